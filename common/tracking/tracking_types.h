// Plain result types of the body tracker (common/tracking): people found in
// one depth image, each with the 25 Kinect v2 joints in the depth camera's
// frame. No protobuf, no gRPC: the capture daemon and the CLI convert at
// their edges.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "common/body/joint_set.h"

namespace reenact::tracking {

// How a joint's position was obtained (the Kinect SDK's three states).
enum class JointState : uint8_t {
  kNotTracked = 0,  // No estimate (the position is meaningless).
  kInferred = 1,  // Estimated, but not on a surface the camera sees (hidden, or outside the view).
  kTracked = 2,   // Estimated on (just behind) a surface the camera sees.
};

std::string_view JointStateName(JointState state);  // "not_tracked", "inferred", "tracked".

struct TrackedJoint {
  // Position in the depth camera's frame (OpenCV axes: x right, y down, z
  // forward), metres.
  Eigen::Vector3d position_in_camera_m = Eigen::Vector3d::Zero();
  // Where the position projects in the depth image, pixels (may lie outside).
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  // In [0, 1]: the share of the tracker's evidence that agrees on the position.
  double confidence = 0.0;
  JointState state = JointState::kNotTracked;
};

struct TrackedPerson {
  // Stable across the frames of one tracker (BodyTracker::Track), from 1.
  int person_id = 0;
  // The person's value in the label image the tracker used (the actor mask's
  // body index, or the tracker's own segmentation).
  int mask_label = 0;
  // Pixels of the person that were looked at (after subsampling).
  int num_pixels = 0;
  // Mean of the person's points in the camera frame, metres.
  Eigen::Vector3d centroid_in_camera_m = Eigen::Vector3d::Zero();
  // Indexed by body::KinectV2Joint.
  std::array<TrackedJoint, body::kNumKinectV2Joints> joints;
};

}  // namespace reenact::tracking
