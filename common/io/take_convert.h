// Conversions between a take's plain values (common/model/take.h) and the
// reenact.v1 messages of its file and of the ingest stream, and the reader
// that loads a whole take file as a RecordedTake. The one adapter on the
// take side: reconstruction and the live followers see only the plain
// values.
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/model/ground_truth.h"
#include "common/model/sensor_calibration.h"
#include "common/model/take.h"
#include "reenact/v1/frame.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"

namespace reenact {

TakeInfo TakeInfoFromProto(const v1::TakeInfo& message);
v1::TakeInfo TakeInfoToProto(const TakeInfo& info);

Skeleton SkeletonFromProto(const v1::Skeleton& message);

// A frame of the ingest stream. Its frame_index is the depth image's (the
// frame's own when it has no depth). The image bytes are moved out of
// `message`.
SensorFrame SensorFrameFromProto(v1::Frame&& message);
// Copies the image bytes.
FrameSet FrameSetFromProto(const v1::FrameSet& message);

FrameSetRecord FrameSetRecordFromProto(const v1::FrameSetRecord& message);

struct RecordedTakeOptions {
  // Keep the colour JPEG bytes (texturing needs them; most passes do not).
  bool load_color = true;
};

// Reads the take file at `path`: its info, calibrations, every sensor's
// frames (depth, mask, colour, skeletons; no ground truth) and its
// /ingest/frame_set records. NotFound when the file does not exist;
// InvalidArgument when it is not a take, a sensor's calibration holds a zero
// or non-finite transform, or a channel's schema is not the one its topic
// needs; DataLoss when a message does not parse. `progress` gets stage
// "load" (items: messages read); returning false cancels (Cancelled).
absl::StatusOr<RecordedTake> ReadRecordedTake(const std::string& path,
                                              const RecordedTakeOptions& options = {},
                                              const ProgressCallback& progress = {});

class TakeReader;

// The calibrations of `take`'s sensors as plain values, in sensor-id order.
// InvalidArgument for a sensor transform that is zero or not finite.
absl::StatusOr<std::vector<SensorCalibration>> TakeSensorCalibrations(const TakeReader& take);

// The ground truth of the synthetic take `take`: its topology, the true
// meshes of the frames in `mesh_frames` (none when empty; a take holds one
// per frame, so a reader asks for those it needs), every frame's joints and
// the sensors' calibrations. FailedPrecondition when the take has no
// ground truth (/ground_truth/topology); DataLoss when a message does not
// parse or a mesh or triangle does not fit the topology; InvalidArgument
// for a sensor transform that is zero or not finite.
absl::StatusOr<GroundTruth> ReadGroundTruth(const TakeReader& take,
                                            const std::set<int64_t>& mesh_frames);

}  // namespace reenact
