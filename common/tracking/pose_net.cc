#include "common/tracking/pose_net.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>

#include "absl/strings/str_cat.h"

namespace reenact::tracking {
namespace {

bool OnPerson(const DepthImageMm& depth, const MaskImage* labels, int label, size_t i) {
  return depth.data[i] != 0 && (labels == nullptr || labels->data[i] == label);
}

}  // namespace

std::optional<PoseNetCrop> ChoosePoseNetCrop(const DepthImageMm& depth, const MaskImage* labels,
                                             int label, const CameraIntrinsics& intrinsics) {
  std::vector<uint16_t> values;
  int64_t sum_x = 0, sum_y = 0;
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const size_t i = static_cast<size_t>(y) * depth.width + x;
      if (!OnPerson(depth, labels, label, i)) continue;
      values.push_back(depth.data[i]);
      sum_x += x, sum_y += y;
    }
  }
  if (static_cast<int>(values.size()) < kPoseNetMinPixels) return std::nullopt;
  const size_t n = values.size();
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(n / 2),
                   values.end());
  PoseNetCrop crop;
  crop.median_depth_m = values[n / 2] * 0.001;
  crop.center_x = static_cast<double>(sum_x) / static_cast<double>(n);
  crop.center_y = static_cast<double>(sum_y) / static_cast<double>(n);
  crop.width_px = kPoseNetCropM * intrinsics.fx / crop.median_depth_m;
  crop.height_px = kPoseNetCropM * intrinsics.fy / crop.median_depth_m;
  return crop;
}

std::vector<float> PoseNetInput(const DepthImageMm& depth, const MaskImage* labels, int label,
                                const PoseNetCrop& crop) {
  constexpr int kN = kPoseNetInput;
  std::array<int, kN> xs{}, ys{};
  for (int k = 0; k < kN; ++k) {
    const double g = (k + 0.5) / kN - 0.5;
    xs[k] = static_cast<int>(std::floor(crop.center_x + g * crop.width_px + 0.5));
    ys[k] = static_cast<int>(std::floor(crop.center_y + g * crop.height_px + 0.5));
  }
  std::vector<float> input(static_cast<size_t>(kN) * kN, 1.0f);
  for (int r = 0; r < kN; ++r) {
    const int y = ys[r];
    if (y < 0 || y >= depth.height) continue;
    for (int c = 0; c < kN; ++c) {
      const int x = xs[c];
      if (x < 0 || x >= depth.width) continue;
      const size_t i = static_cast<size_t>(y) * depth.width + x;
      if (!OnPerson(depth, labels, label, i)) continue;
      const double v = (depth.data[i] * 0.001 - crop.median_depth_m) / kPoseNetDepthRangeM;
      input[static_cast<size_t>(r) * kN + c] = static_cast<float>(std::clamp(v, -1.0, 1.0));
    }
  }
  return input;
}

struct PoseNet::Impl {
  cv::dnn::Net net;
};

PoseNet::PoseNet(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PoseNet::~PoseNet() = default;

absl::StatusOr<std::unique_ptr<PoseNet>> PoseNet::Load(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return absl::NotFoundError(absl::StrCat("tracker: no network at ", path));
  }
  auto impl = std::make_unique<Impl>();
  try {
    impl->net = cv::dnn::readNetFromONNX(path);
  } catch (const cv::Exception& e) {
    return absl::DataLossError(
        absl::StrCat("tracker: ", path, " is not a network OpenCV can read (", e.msg, ")"));
  }
  if (impl->net.empty()) {
    return absl::DataLossError(absl::StrCat("tracker: ", path, " holds no network"));
  }
  impl->net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  impl->net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  auto pose_net = std::unique_ptr<PoseNet>(new PoseNet(std::move(impl)));
  // One run on a blank input checks the output's shape.
  const std::vector<float> blank(static_cast<size_t>(kPoseNetInput) * kPoseNetInput, 1.0f);
  const PoseNetCrop crop{0, 0, 1, 1, 1};
  if (absl::StatusOr<std::array<PoseNetJoint, body::kNumKinectV2Joints>> r =
          pose_net->Run(blank, crop);
      !r.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("tracker: ", path, ": ", r.status().message()));
  }
  return pose_net;
}

absl::StatusOr<std::array<PoseNetJoint, body::kNumKinectV2Joints>> PoseNet::Run(
    const std::vector<float>& input, const PoseNetCrop& crop) {
  constexpr int kN = kPoseNetInput, kM = kPoseNetOutput, kJ = body::kNumKinectV2Joints;
  if (input.size() != static_cast<size_t>(kN) * kN) {
    return absl::InvalidArgumentError("tracker: network input of the wrong size");
  }
  cv::Mat maps;
  try {
    const int dims[4] = {1, 1, kN, kN};
    const cv::Mat blob(4, dims, CV_32F, const_cast<float*>(input.data()));
    impl_->net.setInput(blob);
    maps = impl_->net.forward();
  } catch (const cv::Exception& e) {
    return absl::InvalidArgumentError(absl::StrCat("the network does not run (", e.msg, ")"));
  }
  if (maps.dims != 4 || maps.size[0] != 1 || maps.size[1] != 2 * kJ || maps.size[2] != kM ||
      maps.size[3] != kM || maps.type() != CV_32F) {
    return absl::InvalidArgumentError(
        absl::StrCat("the network's output is not 1 x ", 2 * kJ, " x ", kM, " x ", kM, " maps"));
  }
  const float* out = maps.ptr<float>();
  std::array<PoseNetJoint, kJ> joints;
  std::array<double, kM * kM> p{};
  for (int j = 0; j < kJ; ++j) {
    const float* logits = out + static_cast<size_t>(j) * kM * kM;
    const float* depth = out + static_cast<size_t>(kJ + j) * kM * kM;
    const float top = *std::max_element(logits, logits + kM * kM);
    double total = 0;
    for (int i = 0; i < kM * kM; ++i)
      total += p[i] = std::exp(static_cast<double>(logits[i] - top));
    double u = 0, v = 0, z = 0;
    // Cell i lies in column i % kM and row i / kM (whole cells); its
    // centre is half a cell further.
    for (int i = 0; i < kM * kM; ++i) {
      const int column = i % kM, row = i / kM;
      p[i] /= total;
      u += p[i] * (column + 0.5);
      v += p[i] * (row + 0.5);
      z += p[i] * depth[i];
    }
    PoseNetJoint& joint = joints[j];
    joint.pixel = {crop.center_x + (u / kM - 0.5) * crop.width_px,
                   crop.center_y + (v / kM - 0.5) * crop.height_px};
    joint.depth_m = crop.median_depth_m + z * kPoseNetZScaleM;
    if (!std::isfinite(joint.pixel.x()) || !std::isfinite(joint.pixel.y()) ||
        !std::isfinite(joint.depth_m)) {
      joint = PoseNetJoint{};
    }
  }
  return joints;
}

std::string InstalledTrackerFile(const std::string& file) {
  std::error_code error;
  const std::filesystem::path program = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return "";
  const std::filesystem::path installed =
      program.parent_path().parent_path() / "share" / "reenact" / "models" / "tracker" / file;
  return std::filesystem::is_regular_file(installed, error) ? installed.string() : "";
}

std::string DefaultPoseNetPath() {
  if (const char* env = std::getenv("REENACT_TRACKER_MODEL"); env && *env) return env;
  if (std::string installed = InstalledTrackerFile("pose_net.onnx"); !installed.empty()) {
    return installed;
  }
  return REENACT_DEFAULT_TRACKER_MODEL;
}

}  // namespace reenact::tracking
