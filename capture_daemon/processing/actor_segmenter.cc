#include "capture_daemon/processing/actor_segmenter.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace reenact::capture {
namespace {

constexpr double kMaxFloorTiltDeg = 40.0;
constexpr int kFloorStride = 4;             // Every 4th pixel in x and y.
constexpr double kMinFloorFraction = 0.03;  // Of the sampled points.
constexpr double kMinValidFraction = 0.2;   // Of the background frames.

}  // namespace

absl::Status SegmenterOptions::Validate() const {
  if (!(background_seconds >= 0 && background_seconds <= 600)) {
    return absl::InvalidArgumentError("background_seconds must be in [0, 600]");
  }
  if (max_background_frames < 1)
    return absl::InvalidArgumentError("max_background_frames must be >= 1");
  if (!(background_percentile > 0 && background_percentile <= 1)) {
    return absl::InvalidArgumentError("background_percentile must be in (0, 1]");
  }
  if (!(min_margin_mm > 0) || !(noise_sigmas >= 0) || !std::isfinite(noise_sigmas)) {
    return absl::InvalidArgumentError("min_margin_mm must be > 0 and noise_sigmas >= 0");
  }
  if (!(floor_distance_mm >= 0) || !(floor_inlier_mm > 0) || floor_iterations < 1) {
    return absl::InvalidArgumentError(
        "floor_distance_mm must be >= 0, floor_inlier_mm > 0, floor_iterations >= 1");
  }
  if (!(depth_step_mm > 0)) return absl::InvalidArgumentError("depth_step_mm must be > 0");
  if (!(min_body_fraction >= 0 && min_body_fraction < 1)) {
    return absl::InvalidArgumentError("min_body_fraction must be in [0, 1)");
  }
  return absl::OkStatus();
}

double ActorSegmenter::AxialSigmaMm(const std::string& noise_model, double z_m) {
  if (absl::StartsWith(noise_model, "kinect_v2")) {
    return 1.5 - 0.5 * z_m + 0.3 * z_m * z_m;  // Fankhauser et al. 2015, theta = 0.
  }
  return 1.425 * z_m * z_m;  // Khoshelham and Oude Elberink 2012.
}

absl::StatusOr<ActorSegmenter> ActorSegmenter::Create(const CameraIntrinsics& intrinsics,
                                                      const Rigid3d& world_from_depth,
                                                      const SegmenterOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  if (absl::Status s = intrinsics.Validate(); !s.ok()) return s;
  ActorSegmenter segmenter;
  segmenter.intrinsics_ = intrinsics;
  segmenter.options_ = options;
  const bool placed = world_from_depth.translation.norm() > 0 ||
                      std::abs(std::abs(world_from_depth.rotation.w()) - 1.0) > 1e-12;
  if (placed) {
    // World +Y expressed in the depth frame.
    segmenter.up_in_depth_ = world_from_depth.rotation.conjugate() * Eigen::Vector3d::UnitY();
  }
  segmenter.rays_.resize(static_cast<size_t>(intrinsics.width) * intrinsics.height);
  for (int y = 0; y < intrinsics.height; ++y) {
    for (int x = 0; x < intrinsics.width; ++x) {
      const Eigen::Vector2d distorted((x - intrinsics.cx) / intrinsics.fx,
                                      (y - intrinsics.cy) / intrinsics.fy);
      const Eigen::Vector2d ray = intrinsics.HasDistortion()
                                      ? intrinsics.Undistort(distorted).value_or(distorted)
                                      : distorted;
      segmenter.rays_[static_cast<size_t>(y) * intrinsics.width + x] = ray.cast<float>();
    }
  }
  return segmenter;
}

double ActorSegmenter::MarginMm(double z_mm) const {
  return std::max(options_.min_margin_mm,
                  options_.noise_sigmas * AxialSigmaMm(options_.noise_model, z_mm / 1000.0));
}

void ActorSegmenter::BuildBackground() {
  const size_t n = static_cast<size_t>(intrinsics_.width) * intrinsics_.height;
  background_mm_ = DepthImageMm(intrinsics_.width, intrinsics_.height);
  const size_t frames = samples_.size();
  const size_t min_valid =
      std::max<size_t>(1, static_cast<size_t>(std::ceil(kMinValidFraction * frames)));
  std::vector<uint16_t> values;
  values.reserve(frames);
  for (size_t i = 0; i < n && frames > 0; ++i) {
    values.clear();
    for (const DepthImageMm& sample : samples_) {
      if (sample.data[i] != 0) values.push_back(sample.data[i]);
    }
    if (values.size() < min_valid) continue;
    const size_t k =
        static_cast<size_t>(std::lround(options_.background_percentile * (values.size() - 1)));
    std::nth_element(values.begin(), values.begin() + k, values.end());
    background_mm_.data[i] = values[k];
  }
  samples_.clear();
  samples_.shrink_to_fit();
}

void ActorSegmenter::FitFloor(const DepthImageMm& depth_mm) {
  std::vector<Eigen::Vector3d> points;
  for (int y = 0; y < depth_mm.height; y += kFloorStride) {
    for (int x = 0; x < depth_mm.width; x += kFloorStride) {
      const uint16_t d = depth_mm.at(x, y);
      if (d == 0) continue;
      const Eigen::Vector2f& r = rays_[static_cast<size_t>(y) * depth_mm.width + x];
      const double z = d / 1000.0;
      points.emplace_back(r.x() * z, r.y() * z, z);
    }
  }
  if (points.size() < 50) return;
  const double inlier_m = options_.floor_inlier_mm / 1000.0;
  const double min_cos = std::cos(kMaxFloorTiltDeg * M_PI / 180.0);
  std::mt19937_64 rng(options_.seed);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  FloorPlane best;
  best.inliers = 0;
  for (int it = 0; it < options_.floor_iterations; ++it) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() < 1e-9) continue;
    normal.normalize();
    if (normal.dot(up_in_depth_) < 0) normal = -normal;
    if (normal.dot(up_in_depth_) < min_cos) continue;
    const double offset = -normal.dot(a);
    int inliers = 0;
    for (const auto& p : points) inliers += std::abs(normal.dot(p) + offset) < inlier_m;
    if (inliers > best.inliers) best = {normal, offset, inliers};
  }
  if (best.inliers < std::max(50, static_cast<int>(kMinFloorFraction * points.size()))) return;
  // Least-squares refinement on the inliers: the normal is the direction of
  // least spread of their scatter matrix.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  std::vector<const Eigen::Vector3d*> inliers;
  for (const auto& p : points) {
    if (std::abs(best.normal.dot(p) + best.offset_m) < inlier_m) inliers.push_back(&p);
  }
  for (const auto* p : inliers) centroid += *p;
  centroid /= static_cast<double>(inliers.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto* p : inliers) scatter += (*p - centroid) * (*p - centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Eigen::Vector3d normal = solver.eigenvectors().col(0).normalized();
  if (normal.dot(up_in_depth_) < 0) normal = -normal;
  floor_ = FloorPlane{normal, -normal.dot(centroid), static_cast<int>(inliers.size())};
}

absl::StatusOr<MaskImage> ActorSegmenter::Segment(const DepthImageMm& depth_mm, int64_t stamp_ns) {
  if (depth_mm.width != intrinsics_.width || depth_mm.height != intrinsics_.height ||
      depth_mm.data.size() != depth_mm.num_pixels()) {
    return absl::InvalidArgumentError(absl::StrCat("depth image of ", depth_mm.width, "x",
                                                   depth_mm.height, " px; the segmenter expects ",
                                                   intrinsics_.width, "x", intrinsics_.height));
  }
  MaskImage mask(depth_mm.width, depth_mm.height);
  if (!started_) {
    started_ = true;
    first_stamp_ns_ = stamp_ns;
  }
  if (!ready_) {
    const double elapsed_s = (stamp_ns - first_stamp_ns_) * 1e-9;
    if (options_.background_seconds > 0 && elapsed_s < options_.background_seconds) {
      if (static_cast<int>(samples_.size()) < options_.max_background_frames)
        samples_.push_back(depth_mm);
      return mask;
    }
    if (!samples_.empty()) BuildBackground();
    ready_ = true;
  }
  if (!floor_tried_) {
    floor_tried_ = true;
    FitFloor(background_mm_.empty() ? depth_mm : background_mm_);
  }

  const int w = depth_mm.width, h = depth_mm.height;
  const bool have_background = !background_mm_.empty();
  const double floor_m = options_.floor_distance_mm / 1000.0;
  cv::Mat candidate(h, w, CV_8U, cv::Scalar(0));
  for (int y = 0; y < h; ++y) {
    uint8_t* row = candidate.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const uint16_t d = depth_mm.data[i];
      if (d == 0) continue;
      if (have_background) {
        const uint16_t bg = background_mm_.data[i];
        if (bg != 0 && bg - static_cast<double>(d) <= MarginMm(bg)) continue;
      }
      if (floor_) {
        const double z = d / 1000.0;
        const Eigen::Vector3d p(rays_[i].x() * z, rays_[i].y() * z, z);
        if (floor_->normal.dot(p) + floor_->offset_m < floor_m) continue;
      }
      row[x] = 1;
    }
  }
  // Cut at depth discontinuities: of two 4-neighbours more than a step apart,
  // the farther one leaves the labelling (restored below when it touches the
  // body).
  cv::Mat labelled = candidate.clone();
  auto step_mm = [&](uint16_t d) {
    return std::max(options_.depth_step_mm,
                    options_.noise_sigmas * AxialSigmaMm(options_.noise_model, d / 1000.0));
  };
  auto cut_pair = [&](int x0, int y0, int x1, int y1) {
    const uint16_t a = depth_mm.at(x0, y0), b = depth_mm.at(x1, y1);
    const uint16_t near = std::min(a, b);
    if (std::abs(static_cast<int>(a) - static_cast<int>(b)) <= step_mm(near)) return;
    if (a > b) {
      labelled.at<uint8_t>(y0, x0) = 0;
    } else {
      labelled.at<uint8_t>(y1, x1) = 0;
    }
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!candidate.at<uint8_t>(y, x)) continue;
      if (x + 1 < w && candidate.at<uint8_t>(y, x + 1)) cut_pair(x, y, x + 1, y);
      if (y + 1 < h && candidate.at<uint8_t>(y + 1, x)) cut_pair(x, y, x, y + 1);
    }
  }
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(labelled, labels, stats, centroids, 8, CV_32S);
  int best = 0, best_area = 0;
  for (int label = 1; label < count; ++label) {
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    if (area > best_area) {
      best = label;
      best_area = area;
    }
  }
  if (best == 0 || best_area < options_.min_body_fraction * w * h) return mask;
  for (int y = 0; y < h; ++y) {
    const int* label_row = labels.ptr<int>(y);
    for (int x = 0; x < w; ++x) {
      if (label_row[x] == best) mask.at(x, y) = 1;
    }
  }
  // Restore cut pixels that touch the body.
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!candidate.at<uint8_t>(y, x) || labelled.at<uint8_t>(y, x)) continue;
      bool touches = false;
      for (int dy = -1; dy <= 1 && !touches; ++dy) {
        for (int dx = -1; dx <= 1 && !touches; ++dx) {
          const int nx = x + dx, ny = y + dy;
          touches = nx >= 0 && ny >= 0 && nx < w && ny < h && labels.at<int>(ny, nx) == best;
        }
      }
      if (touches) mask.at(x, y) = 1;
    }
  }
  return mask;
}

}  // namespace reenact::capture
