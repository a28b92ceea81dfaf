#include "clients/view/texture_selection.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::view {
namespace {

Eigen::Isometry3d ToIsometry(const Rigid3d& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = t.rotation.toRotationMatrix();
  out.translation() = t.translation;
  return out;
}

// Orders `ids` by `score` ascending, ties by id.
std::vector<int> SortByScore(std::vector<int> ids, const std::vector<double>& score_of_id,
                             std::vector<double>* sorted_scores) {
  std::stable_sort(ids.begin(), ids.end(),
                   [&](int a, int b) { return score_of_id[a] < score_of_id[b]; });
  if (sorted_scores != nullptr) {
    sorted_scores->clear();
    for (int id : ids) sorted_scores->push_back(score_of_id[id]);
  }
  return ids;
}

absl::StatusOr<KeyframeCamera> MakeKeyframeCamera(const TextureKeyframe& keyframe,
                                                  const std::map<std::string, int>& sensor_ids,
                                                  const std::vector<KeyframeCamera>& sensors) {
  auto it = sensor_ids.find(keyframe.sensor_id);
  if (it == sensor_ids.end()) {
    return absl::InvalidArgumentError(
        absl::StrCat("keyframe names unknown sensor \"", keyframe.sensor_id, "\""));
  }
  KeyframeCamera camera = sensors[it->second];
  camera.frame = keyframe.frame_index;
  camera.crop_x_px = keyframe.crop_x_px;
  camera.crop_y_px = keyframe.crop_y_px;
  camera.crop_scale = keyframe.crop_scale > 0 ? keyframe.crop_scale : 1.0;
  camera.has_visibility = !keyframe.vertex_visible_bits.empty();
  return camera;
}

}  // namespace

TextureSelection SelectionForReenactment(const ReenactmentInfo& info) {
  if (!info.texture_mode) {
    return info.method == "rigid-cylinders" ? TextureSelection::kPose : TextureSelection::kRotation;
  }
  return *info.texture_mode == methods::TextureMode::kPoseClosest ? TextureSelection::kPose
                                                                  : TextureSelection::kRotation;
}

double RotationAngle(const Eigen::Matrix3d& r) {
  // atan2 of sin and cos of the angle stays accurate near 0 and pi.
  const Eigen::Vector3d axis_sin(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
  return std::atan2(0.5 * axis_sin.norm(), 0.5 * (r.trace() - 1.0));
}

absl::StatusOr<VdtmModel> VdtmModel::Create(const Reenactment& data) {
  RETURN_IF_ERROR(ValidateReenactment(data));
  VdtmModel model;
  model.data_ = &data;
  model.num_parts_ = static_cast<int>(data.parts.size());
  const int num_parts = model.num_parts();
  for (const ReenactmentFrame& frame : data.frames) {
    std::array<Eigen::Vector3d, kNumSkeletonJoints> joints;
    std::array<bool, kNumSkeletonJoints> valid{};
    for (int j = 0; j < kNumSkeletonJoints; ++j) {
      joints[j] = Eigen::Vector3d::Zero();
      if (frame.joints_in_world_m.size() != kNumSkeletonJoints) continue;
      joints[j] = frame.joints_in_world_m[j];
      valid[j] = joints[j].allFinite();
    }
    model.joints_.push_back(joints);
    model.joints_valid_.push_back(valid);
  }
  std::map<std::string, int> sensor_ids;
  std::vector<KeyframeCamera> sensors;
  for (int s = 0; s < static_cast<int>(data.info.sensors.size()); ++s) {
    const SensorCalibration& calibration = data.info.sensors[s];
    KeyframeCamera camera;
    camera.sensor = s;
    // A depth-only sensor (no colour camera: intrinsics of size 0) textures
    // nothing; a keyframe naming it is refused below as an unknown sensor.
    if (calibration.color_intrinsics.width == 0 && calibration.color_intrinsics.height == 0) {
      sensors.push_back(camera);
      continue;
    }
    RETURN_IF_ERROR(calibration.color_intrinsics.Validate());
    camera.color_intrinsics = calibration.color_intrinsics;
    camera.color_from_world =
        ToIsometry(calibration.color_from_depth * calibration.world_from_depth.Inverse());
    sensor_ids[calibration.sensor_id] = s;
    sensors.push_back(camera);
  }
  for (const TextureKeyframe& keyframe : data.keyframes) {
    ASSIGN_OR_RETURN(KeyframeCamera camera, MakeKeyframeCamera(keyframe, sensor_ids, sensors));
    if (camera.frame < 0 || camera.frame >= model.num_frames()) {
      return absl::InvalidArgumentError(
          absl::StrCat("keyframe names frame ", camera.frame, " of ", model.num_frames()));
    }
    model.keyframes_.push_back(camera);
  }
  // Frame-independent halves of Eq. 3.13 (R_{b,n}) and Eq. 3.6 (S_n).
  model.keyframe_rotation_.assign(num_parts, {});
  for (int b = 0; b < num_parts; ++b) {
    for (const KeyframeCamera& k : model.keyframes_) {
      model.keyframe_rotation_[b].push_back(k.color_from_world.linear() *
                                            model.pose(k.frame, b).world_from_part.linear());
    }
  }
  for (const KeyframeCamera& k : model.keyframes_) {
    std::array<Eigen::Vector3d, kNumSkeletonJoints> joints;
    std::array<bool, kNumSkeletonJoints> valid;
    model.NeckRelativeJoints(k.frame, k.color_from_world, &joints, &valid);
    model.keyframe_joints_.push_back(joints);
    model.keyframe_joints_valid_.push_back(valid);
  }
  return model;
}

void VdtmModel::NeckRelativeJoints(int frame, const Eigen::Isometry3d& camera_from_world,
                                   std::array<Eigen::Vector3d, kNumSkeletonJoints>* joints,
                                   std::array<bool, kNumSkeletonJoints>* valid) const {
  const auto& world = joints_[frame];
  const auto& known = joints_valid_[frame];
  const Eigen::Vector3d neck = camera_from_world * world[kNeckJoint];
  for (int j = 0; j < kNumSkeletonJoints; ++j) {
    (*valid)[j] = known[j] && known[kNeckJoint];
    (*joints)[j] = (*valid)[j] ? Eigen::Vector3d(camera_from_world * world[j] - neck)
                               : Eigen::Vector3d::Zero();
  }
}

std::vector<int> VdtmModel::RankByRotation(int frame, int part,
                                           const Eigen::Isometry3d& camera_from_world,
                                           std::vector<double>* angles_rad) const {
  // R_b* of Eq. 3.12-3.13: the part's rotation in the viewer camera.
  const Eigen::Matrix3d r_star =
      camera_from_world.linear() * pose(frame, part).world_from_part.linear();
  std::vector<double> angle(keyframes_.size(), std::numeric_limits<double>::infinity());
  std::vector<int> candidates;
  for (int k = 0; k < num_keyframes(); ++k) {
    if (!pose(keyframes_[k].frame, part).valid) continue;
    angle[k] = RotationAngle(r_star * keyframe_rotation_[part][k].transpose());  // Eq. 3.13.
    candidates.push_back(k);
  }
  return SortByScore(std::move(candidates), angle, angles_rad);
}

std::vector<int> VdtmModel::RankByPose(int frame, const Eigen::Isometry3d& camera_from_world,
                                       std::vector<double>* distances_m) const {
  std::array<Eigen::Vector3d, kNumSkeletonJoints> viewer;  // S* - s*_neck.
  std::array<bool, kNumSkeletonJoints> viewer_valid;
  NeckRelativeJoints(frame, camera_from_world, &viewer, &viewer_valid);
  std::vector<double> distance(keyframes_.size(), std::numeric_limits<double>::infinity());
  std::vector<int> all(keyframes_.size());
  std::iota(all.begin(), all.end(), 0);
  for (int k = 0; k < num_keyframes(); ++k) {
    double sum = 0.0;
    int count = 0;
    for (int j = 0; j < kNumSkeletonJoints; ++j) {
      if (j == kNeckJoint || !viewer_valid[j] || !keyframe_joints_valid_[k][j]) continue;
      sum += (viewer[j] - keyframe_joints_[k][j]).norm();  // Eq. 3.6.
      ++count;
    }
    if (count > 0) distance[k] = sum / count;
  }
  return SortByScore(std::move(all), distance, distances_m);
}

bool VdtmModel::VertexVisible(int keyframe, int part, int vertex) const {
  if (!keyframes_[keyframe].has_visibility) return true;
  const TextureKeyframe& k = data_->keyframes[keyframe];
  if (part < 0 || part >= static_cast<int>(k.vertex_visible_bits.size())) return false;
  const std::string& bits = k.vertex_visible_bits[part];
  const size_t byte = static_cast<size_t>(vertex) / 8;
  if (vertex < 0 || byte >= bits.size()) return false;
  return (static_cast<uint8_t>(bits[byte]) >> (vertex % 8)) & 1u;
}

std::vector<int> VdtmModel::AssignTriangles(int part, const std::vector<int>& ranking,
                                            int* not_best, std::vector<int>* second) const {
  std::vector<int> usable;
  for (int k : ranking) {
    if (pose(keyframes_[k].frame, part).valid) usable.push_back(k);
  }
  const std::vector<Eigen::Vector3i>& triangles = data_->parts[part].triangles;
  std::vector<int> chosen(triangles.size(), -1);
  if (second != nullptr) second->assign(triangles.size(), -1);
  int fallbacks = 0;
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (size_t r = 0; r < usable.size(); ++r) {
      const int k = usable[r];
      if (!VertexVisible(k, part, triangles[t][0]) || !VertexVisible(k, part, triangles[t][1]) ||
          !VertexVisible(k, part, triangles[t][2])) {
        continue;
      }
      if (chosen[t] >= 0) {
        (*second)[t] = k;
        break;
      }
      chosen[t] = k;
      if (r > 0) ++fallbacks;  // Occluded in the better ones: next-best frame.
      if (second == nullptr) break;
    }
  }
  if (not_best != nullptr) *not_best = fallbacks;
  return chosen;
}

Eigen::Vector2f VdtmModel::KeyframeUv(int keyframe, int part,
                                      const Eigen::Vector3f& point_in_part_m, int image_width,
                                      int image_height) const {
  const KeyframeCamera& k = keyframes_[keyframe];
  // Eq. 3.14: x_n = T_{b,n} x (the part's pose at the keyframe's instant).
  const Eigen::Vector3d point_in_world =
      pose(k.frame, part).WorldFromPartScaled() * point_in_part_m.cast<double>();
  // Eq. 3.15: rho, into the keyframe's colour image, then into its crop.
  const auto pixel = k.color_intrinsics.Project(k.color_from_world * point_in_world);
  if (!pixel) return Eigen::Vector2f(-1.0f, -1.0f);
  const double u = (pixel->x() - k.crop_x_px + 0.5) * k.crop_scale / image_width;
  const double v = (pixel->y() - k.crop_y_px + 0.5) * k.crop_scale / image_height;
  return Eigen::Vector2f(static_cast<float>(u), static_cast<float>(1.0 - v));
}

}  // namespace reenact::view
