// The randomised decision forest of the body tracker (body_tracker.h): each
// split node compares a depth-difference feature with a threshold, each leaf
// holds a body-part distribution and a few joint votes.
//
// Feature (Shotton et al., CVPR 2011, Eq. 1):
//   f(x) = d(x + u / d(x)) - d(x + v / d(x))
// with d the depth in metres at a pixel (a constant `kBackgroundDepthM` off
// the person, outside the image or where there is no measurement). Departure
// from the paper: u and v are stored in metres on the image plane at the
// pixel's depth and turned into pixels by the camera's focal lengths, so one
// forest serves sensors of any resolution and field of view.
//
// Leaves (Girshick et al., ICCV 2011, sec. 3.1): besides P(part), up to
// kMaxLeafVotes joints with the mode of their offsets from the pixel's 3D
// point (camera frame, metres) and a weight, the share of the leaf's training
// pixels that agree on that mode.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact::tracking {

inline constexpr float kBackgroundDepthM = 8.0f;
inline constexpr int kMaxLeafVotes = 6;
inline constexpr uint8_t kNoJoint = 255;

struct SplitFeature {
  float u_x_m = 0, u_y_m = 0;  // First probe offset, metres at the pixel's depth.
  float v_x_m = 0, v_y_m = 0;  // Second probe offset (0, 0: the pixel itself).
  float threshold_m = 0;       // Go left when f(x) < threshold.
};

struct ForestNode {
  // Split: children indices (> this node's index). Leaf: left == -1 and
  // `leaf` indexes the tree's leaves.
  int32_t left = -1;
  int32_t right = -1;
  int32_t leaf = -1;
  SplitFeature feature;
};

struct JointVote {
  uint8_t joint = kNoJoint;  // body::KinectV2Joint, kNoJoint: unused slot.
  float weight = 0;          // In (0, 1].
  Eigen::Vector3f offset_m = Eigen::Vector3f::Zero();  // Joint minus pixel point, camera frame.
};

struct ForestLeaf {
  std::vector<float> part_probability;  // num_parts values summing to 1.
  std::array<JointVote, kMaxLeafVotes> votes;
};

struct DecisionTree {
  std::vector<ForestNode> nodes;  // nodes[0] is the root.
  std::vector<ForestLeaf> leaves;
};

class BodyPartForest {
 public:
  BodyPartForest() = default;
  BodyPartForest(int num_parts, std::vector<DecisionTree> trees, std::string description);

  int num_parts() const { return num_parts_; }
  const std::vector<DecisionTree>& trees() const { return trees_; }
  // Free text written by the trainer: data, seed, sizes, training time.
  const std::string& description() const { return description_; }

  // Checks the structure: child indices ahead of their parent and in range,
  // leaf indices in range, finite values, part distributions of the right
  // size. InvalidArgument naming the first problem.
  absl::Status Validate() const;

  // Writes the forest (".rtf": a small versioned little-endian binary).
  absl::Status Save(const std::string& path) const;
  // Reads and validates a forest; every count is checked against the bytes
  // left in the file before anything is allocated. NotFound for a missing
  // file, DataLoss for a truncated or corrupt one.
  static absl::StatusOr<BodyPartForest> Load(const std::string& path);
  static absl::StatusOr<BodyPartForest> Parse(const std::string& bytes);

  // Sum of the trees' node and leaf counts, and the deepest leaf.
  int64_t num_nodes() const;
  int max_depth() const;

 private:
  int num_parts_ = 0;
  std::vector<DecisionTree> trees_;
  std::string description_;
};

// Depth access for features: the person's depth in metres at integer pixels,
// kBackgroundDepthM elsewhere. Row-major, width x height.
struct DepthProbe {
  const float* depth_m = nullptr;
  int width = 0;
  int height = 0;
  float fx = 0, fy = 0;  // Focal lengths, pixels.

  float At(int x, int y) const {
    if (x < 0 || y < 0 || x >= width || y >= height) return kBackgroundDepthM;
    return depth_m[static_cast<size_t>(y) * width + x];
  }
  // f(x) of Eq. 1 at pixel (x, y) whose depth is z_m.
  float Feature(const SplitFeature& f, int x, int y, float z_m) const {
    const float sx = fx / z_m, sy = fy / z_m;
    const float a = At(x + static_cast<int>(f.u_x_m * sx + (f.u_x_m >= 0 ? 0.5f : -0.5f)),
                       y + static_cast<int>(f.u_y_m * sy + (f.u_y_m >= 0 ? 0.5f : -0.5f)));
    const float b = At(x + static_cast<int>(f.v_x_m * sx + (f.v_x_m >= 0 ? 0.5f : -0.5f)),
                       y + static_cast<int>(f.v_y_m * sy + (f.v_y_m >= 0 ? 0.5f : -0.5f)));
    return a - b;
  }
};

// The leaf a pixel reaches in `tree`.
inline const ForestLeaf& DescendTree(const DecisionTree& tree, const DepthProbe& probe, int x,
                                     int y, float z_m) {
  int32_t index = 0;
  while (tree.nodes[static_cast<size_t>(index)].left >= 0) {
    const ForestNode& node = tree.nodes[static_cast<size_t>(index)];
    index =
        probe.Feature(node.feature, x, y, z_m) < node.feature.threshold_m ? node.left : node.right;
  }
  return tree.leaves[static_cast<size_t>(tree.nodes[static_cast<size_t>(index)].leaf)];
}

}  // namespace reenact::tracking
