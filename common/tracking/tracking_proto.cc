#include "common/tracking/tracking_proto.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/depth_codec.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"

namespace reenact::tracking {

v1::Skeleton TrackedPersonToProto(const TrackedPerson& person) {
  v1::Skeleton skeleton;
  skeleton.set_body_index(std::max(1, person.mask_label));
  skeleton.set_person_id(person.person_id);
  skeleton.set_source(kTrackerSource);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const TrackedJoint& tj = person.joints[j];
    const bool finite = tj.position_in_camera_m.allFinite() && std::isfinite(tj.confidence);
    v1::Joint* joint = skeleton.add_joints();
    joint->set_name(std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j))));
    *joint->mutable_position_in_depth_m() =
        ToProto(finite ? tj.position_in_camera_m : Eigen::Vector3d::Zero());
    joint->set_confidence(finite ? static_cast<float>(std::clamp(tj.confidence, 0.0, 1.0)) : 0.f);
    joint->set_tracking_state(!finite                             ? v1::TRACKING_STATE_NOT_TRACKED
                              : tj.state == JointState::kTracked  ? v1::TRACKING_STATE_TRACKED
                              : tj.state == JointState::kInferred ? v1::TRACKING_STATE_INFERRED
                                                                  : v1::TRACKING_STATE_NOT_TRACKED);
  }
  return skeleton;
}

absl::StatusOr<std::map<int64_t, std::vector<v1::Skeleton>>> TrackTakeSensor(
    const TakeReader& take, const std::string& sensor_id, const BodyTrackerOptions& options,
    const std::function<bool()>& frame_done) {
  const auto calibration = take.sensors().find(sensor_id);
  if (calibration == take.sensors().end()) {
    return absl::NotFoundError(absl::StrCat("the take has no sensor '", sensor_id, "'"));
  }
  absl::StatusOr<CameraIntrinsics> k = FromProto(calibration->second.depth_intrinsics());
  if (k.ok()) {
    if (absl::Status valid = k->Validate(); !valid.ok()) k = valid;
  }
  if (!k.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor ", sensor_id, ": depth intrinsics: ", k.status().message()));
  }
  std::map<int64_t, v1::ActorMask> masks;
  RETURN_IF_ERROR(
      take.ForEach<v1::ActorMask>(SensorTopic(sensor_id, "mask"), [&](const v1::ActorMask& m) {
        masks[m.frame_index()] = m;
        return absl::OkStatus();
      }));
  ASSIGN_OR_RETURN(std::unique_ptr<BodyTracker> tracker, BodyTracker::Create(options));
  std::map<int64_t, std::vector<v1::Skeleton>> tracked;
  RETURN_IF_ERROR(take.ForEach<v1::DepthImage>(
      SensorTopic(sensor_id, "depth"), [&](const v1::DepthImage& m) -> absl::Status {
        absl::StatusOr<DepthImageMm> depth = DecodeDepth(m.data());
        if (!depth.ok()) {
          return absl::DataLossError(absl::StrCat("sensor ", sensor_id, " frame ", m.frame_index(),
                                                  ": ", depth.status().message()));
        }
        std::optional<MaskImage> mask;
        if (auto found = masks.find(m.frame_index()); found != masks.end()) {
          auto decoded = DecodeMask(found->second.encoding(), found->second.data());
          if (decoded.ok() && decoded->width == depth->width && decoded->height == depth->height) {
            mask = *std::move(decoded);
          }
        }
        auto people = tracker->Track(*depth, *k, mask ? &*mask : nullptr);
        if (frame_done && !frame_done()) {
          return absl::CancelledError(
              absl::StrCat("tracking sensor ", sensor_id, " stopped at frame ", m.frame_index()));
        }
        if (!people.ok()) return absl::OkStatus();  // A frame without skeleton, as in reenactd.
        for (const TrackedPerson& person : *people) {
          v1::Skeleton skeleton = TrackedPersonToProto(person);
          skeleton.set_sensor_id(sensor_id);
          skeleton.set_device_stamp_ns(m.device_stamp_ns());
          skeleton.set_host_stamp_ns(m.host_stamp_ns());
          skeleton.set_frame_index(m.frame_index());
          tracked[m.frame_index()].push_back(std::move(skeleton));
        }
        return absl::OkStatus();
      }));
  return tracked;
}

}  // namespace reenact::tracking
