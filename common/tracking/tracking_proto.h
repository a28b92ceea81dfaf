// The tracker's people as the wire and the takes carry them (v1::Skeleton),
// and the tracker run over a stored take's depth stream, as reenactd runs it
// over a live one. Separate from reenact_tracking, which knows no protobuf.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/io/take.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/tracking_types.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact::tracking {

// Skeleton.source of the skeletons this tracker produces.
inline constexpr char kTrackerSource[] = "reenact-tracker";

// `person` as a Skeleton: the 25 joints by Kinect v2 name in the depth camera
// frame, with confidence and state; body_index the person's mask label (at
// least 1), person_id, source kTrackerSource. A joint that is not finite goes
// out as not tracked at the origin with confidence 0 (the server refuses
// non-finite joints). Stamps, sensor id and frame index are left to the
// caller.
v1::Skeleton TrackedPersonToProto(const TrackedPerson& person);

// The people tracked in sensor `sensor_id`'s depth stream of `take`, frame by
// frame in stream order (person ids carry over), with the take's actor masks
// as labels where it has them and the tracker's own segmentation elsewhere;
// by frame index, each Skeleton stamped as its depth frame. A frame without
// anybody has no entry. NotFound for an unknown sensor, InvalidArgument for
// bad depth intrinsics, DataLoss for a depth frame that does not decode;
// the tracker's errors for a bad forest. `frame_done`, when set, is called
// after each depth frame; returning false stops the run (Cancelled), so a
// long take can be tracked behind a progress bar with a cancel button.
absl::StatusOr<std::map<int64_t, std::vector<v1::Skeleton>>> TrackTakeSensor(
    const TakeReader& take, const std::string& sensor_id, const BodyTrackerOptions& options = {},
    const std::function<bool()>& frame_done = {});

}  // namespace reenact::tracking
