// Conversions between a reenactment's plain values (common/model/
// reenactment.h) and the reenact.v1 messages of its file and the wire
// (ReenactmentData, reenactment_file.h). The one adapter on the common side:
// readers convert on the way in and writers on the way out, so no algorithm
// or viewer handles the messages.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/io/reenactment_file.h"
#include "common/model/reenactment.h"
#include "common/model/sensor_calibration.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact {

// Validates `data` (ValidateReenactment) and converts it. InvalidArgument
// naming the first problem, including sensor calibrations whose transforms
// hold a zero or non-finite rotation. Poses marked valid whose rotation is
// zero read as not valid, and a pose scale <= 0 reads as 1, as viewers have
// always drawn them.
absl::StatusOr<Reenactment> ReenactmentFromProto(const ReenactmentData& data);

// The messages of `reenactment` (not validated; WriteReenactmentFile does).
ReenactmentData ReenactmentToProto(const Reenactment& reenactment);

// ReadReenactmentFile, then ReenactmentFromProto.
absl::StatusOr<Reenactment> ReadReenactment(const std::string& path, bool skip_keyframes = false);

// ReenactmentToProto, then WriteReenactmentFile (validated; a failed write
// leaves nothing at `path`).
absl::Status WriteReenactment(const Reenactment& reenactment, const std::string& path);

// One sensor's calibration. The message is not checked beyond its
// transforms: InvalidArgument for a zero or non-finite rotation.
absl::StatusOr<SensorCalibration> SensorCalibrationFromProto(const v1::SensorCalibration& message);
v1::SensorCalibration SensorCalibrationToProto(const SensorCalibration& calibration);

// Body meshes and poses on their own (live body fits send them on the wire).
// BodyMeshFromProto checks as DecodeBodyMesh; BodyFramePoseFromProto as
// ValidateBodyPose against `num_vertices`.
absl::StatusOr<BodyMesh> BodyMeshFromProto(const v1::BodyMesh& message);
v1::BodyMesh BodyMeshToProto(const BodyMesh& mesh);
absl::StatusOr<BodyFramePose> BodyFramePoseFromProto(const v1::BodyPose& message, int num_vertices);
v1::BodyPose BodyFramePoseToProto(const BodyFramePose& pose);

// One frame on its own (live previews and a split job's parts carry them).
// FrameFromProto checks a body pose as BodyFramePoseFromProto against
// `num_vertices`; part poses read as in ReenactmentFromProto.
absl::StatusOr<ReenactmentFrame> FrameFromProto(const v1::PartFrame& message, int num_vertices);
v1::PartFrame FrameToProto(const ReenactmentFrame& frame);

// One part's mesh and one texture keyframe on their own (a split job's
// parts carry them). Neither is validated here: the reenactment they end up
// in is (ValidateReenactment). PartMeshFromProto: InvalidArgument for float
// arrays whose byte length is not a whole number of floats.
absl::StatusOr<PartMesh> PartMeshFromProto(const v1::PartMesh& message);
v1::PartMesh PartMeshToProto(const PartMesh& mesh);
TextureKeyframe KeyframeFromProto(const v1::TextureKeyframe& message);
v1::TextureKeyframe KeyframeToProto(const TextureKeyframe& keyframe);

}  // namespace reenact
