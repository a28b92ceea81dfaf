#include "common/io/proto_convert.h"

#include <cmath>

namespace reenact {

v1::TextureMode ToProto(methods::TextureMode mode) {
  switch (mode) {
    case methods::TextureMode::kPoseClosest:
      return v1::TEXTURE_MODE_POSE_CLOSEST;
    case methods::TextureMode::kRotationClosest:
      return v1::TEXTURE_MODE_ROTATION_CLOSEST;
    case methods::TextureMode::kBodyAtlas:
      return v1::TEXTURE_MODE_BODY_ATLAS;
  }
  return v1::TEXTURE_MODE_UNSPECIFIED;
}

v1::CameraIntrinsics ToProto(const CameraIntrinsics& k) {
  v1::CameraIntrinsics m;
  m.set_width_px(k.width);
  m.set_height_px(k.height);
  m.set_fx_px(k.fx);
  m.set_fy_px(k.fy);
  m.set_cx_px(k.cx);
  m.set_cy_px(k.cy);
  m.set_k1(k.k1);
  m.set_k2(k.k2);
  m.set_k3(k.k3);
  m.set_p1(k.p1);
  m.set_p2(k.p2);
  return m;
}

CameraIntrinsics IntrinsicsAsStored(const v1::CameraIntrinsics& m) {
  CameraIntrinsics k;
  k.width = m.width_px();
  k.height = m.height_px();
  k.fx = m.fx_px();
  k.fy = m.fy_px();
  k.cx = m.cx_px();
  k.cy = m.cy_px();
  k.k1 = m.k1();
  k.k2 = m.k2();
  k.k3 = m.k3();
  k.p1 = m.p1();
  k.p2 = m.p2();
  return k;
}

absl::StatusOr<CameraIntrinsics> FromProto(const v1::CameraIntrinsics& m) {
  CameraIntrinsics k = IntrinsicsAsStored(m);
  if (auto status = k.Validate(); !status.ok()) return status;
  return k;
}

v1::Vector3 ToProto(const Eigen::Vector3d& v) {
  v1::Vector3 m;
  m.set_x(v.x());
  m.set_y(v.y());
  m.set_z(v.z());
  return m;
}

Eigen::Vector3d FromProto(const v1::Vector3& m) { return {m.x(), m.y(), m.z()}; }

v1::Quaternion ToProto(const Eigen::Quaterniond& q) {
  v1::Quaternion m;
  m.set_w(q.w());
  m.set_x(q.x());
  m.set_y(q.y());
  m.set_z(q.z());
  return m;
}

Eigen::Quaterniond FromProto(const v1::Quaternion& m) {
  return Eigen::Quaterniond(m.w(), m.x(), m.y(), m.z());
}

v1::Rigid3 ToProto(const Rigid3d& t) {
  v1::Rigid3 m;
  *m.mutable_rotation() = ToProto(t.rotation);
  *m.mutable_translation_m() = ToProto(t.translation);
  return m;
}

absl::StatusOr<Rigid3d> FromProto(const v1::Rigid3& m) {
  Eigen::Quaterniond q = FromProto(m.rotation());
  const Eigen::Vector3d t = FromProto(m.translation_m());
  const double norm = q.norm();
  if (!std::isfinite(norm) || norm < 1e-9 || !t.allFinite()) {
    return absl::InvalidArgumentError("Rigid3: zero or non-finite rotation or translation");
  }
  q.normalize();
  return Rigid3d(q, t);
}

}  // namespace reenact
