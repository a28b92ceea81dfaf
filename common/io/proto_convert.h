// Conversions between the reenact.v1 protobuf messages and the core types of
// common/geometry. The one place where they meet on the common side.
#pragma once

#include "absl/status/statusor.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "common/methods/method_spec.h"
#include "reenact/v1/geometry.pb.h"
#include "reenact/v1/reenactment.pb.h"

namespace reenact {

// How a method's reenactments are textured, as the wire and the file say it.
v1::TextureMode ToProto(methods::TextureMode mode);

v1::CameraIntrinsics ToProto(const CameraIntrinsics& intrinsics);
// InvalidArgument when the message does not describe a valid camera.
absl::StatusOr<CameraIntrinsics> FromProto(const v1::CameraIntrinsics& message);
// The message's values as they are, not checked (calibrations carried along
// whole, checked where a camera is used).
CameraIntrinsics IntrinsicsAsStored(const v1::CameraIntrinsics& message);

v1::Rigid3 ToProto(const Rigid3d& transform);
// InvalidArgument for a zero or non-finite quaternion; the rotation is
// normalised.
absl::StatusOr<Rigid3d> FromProto(const v1::Rigid3& message);

v1::Vector3 ToProto(const Eigen::Vector3d& v);
Eigen::Vector3d FromProto(const v1::Vector3& message);

v1::Quaternion ToProto(const Eigen::Quaterniond& q);
Eigen::Quaterniond FromProto(const v1::Quaternion& message);

}  // namespace reenact
