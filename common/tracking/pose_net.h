// The body tracker's network: joints of one person from their depth, a small
// convolutional network run on the CPU by OpenCV's dnn module (ONNX).
//
// The person's depth is cut to a square of kPoseNetCropM metres round the
// person's mean pixel at their median depth and sampled to kPoseNetInput^2
// (nearest pixel: no depth is ever interpolated across an edge); each value
// is the depth relative to the median over kPoseNetDepthRangeM, clamped to
// [-1, 1], and 1 off the person. Per joint the network gives a heat map and a
// depth map on a kPoseNetOutput^2 grid; the joint is the expectation under
// the heat map's softmax and its depth the depth map averaged with the same
// weights (integral regression: Sun et al., "Integral Human Pose
// Regression", ECCV 2018). The heat maps carry no measure of how right a
// joint is, so the tracker sets confidences from the depth instead
// (body_tracker.cc).
//
// The network is trained by models/tracker/train_pose_net.py, whose
// pose_net.py implements the same crop; the constants here must equal its.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"

namespace reenact::tracking {

inline constexpr double kPoseNetCropM = 2.4;
inline constexpr double kPoseNetDepthRangeM = 1.2;
inline constexpr double kPoseNetZScaleM = kPoseNetCropM;
inline constexpr int kPoseNetInput = 96;
inline constexpr int kPoseNetOutput = 24;
// Fewer pixels than this are not a person the network is asked about.
inline constexpr int kPoseNetMinPixels = 50;

// Where the network looks: the crop's centre (pixels), the person's median
// depth (metres) and the crop's size (pixels).
struct PoseNetCrop {
  double center_x = 0, center_y = 0;
  double median_depth_m = 0;
  double width_px = 0, height_px = 0;
};

// The crop of the person made of the pixels whose label is `label` in
// `labels` (every measured pixel when `labels` is null). nullopt when the
// person has fewer than kPoseNetMinPixels measured pixels.
std::optional<PoseNetCrop> ChoosePoseNetCrop(const DepthImageMm& depth, const MaskImage* labels,
                                             int label, const CameraIntrinsics& intrinsics);

// The network's input for `crop`: kPoseNetInput^2 values, row-major.
std::vector<float> PoseNetInput(const DepthImageMm& depth, const MaskImage* labels, int label,
                                const PoseNetCrop& crop);

struct PoseNetJoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // In the depth image.
  double depth_m = 0;
};

class PoseNet {
 public:
  // The ONNX file: NotFound when missing, DataLoss when OpenCV cannot read it
  // as a network, InvalidArgument when its output is not 2 x 25 maps of
  // kPoseNetOutput^2 for a kPoseNetInput^2 input.
  static absl::StatusOr<std::unique_ptr<PoseNet>> Load(const std::string& path);
  ~PoseNet();
  PoseNet(const PoseNet&) = delete;
  PoseNet& operator=(const PoseNet&) = delete;

  // The joints of the person seen through `crop` (input from PoseNetInput).
  // Not thread-safe: one PoseNet per thread.
  absl::StatusOr<std::array<PoseNetJoint, body::kNumKinectV2Joints>> Run(
      const std::vector<float>& input, const PoseNetCrop& crop);

 private:
  struct Impl;
  explicit PoseNet(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The network: $REENACT_TRACKER_MODEL when set, else the installed one
// (PREFIX/share/reenact/models/tracker/pose_net.onnx beside PREFIX/bin of
// the running program, as `cmake --install` lays it out), else the source
// tree's (models/tracker/pose_net.onnx).
std::string DefaultPoseNetPath();

// PREFIX/share/reenact/models/tracker/`file` for the running program in
// PREFIX/bin when that file exists; "" otherwise.
std::string InstalledTrackerFile(const std::string& file);

}  // namespace reenact::tracking
