#include "common/board/edge_refinement.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>

namespace reenact::board::internal {
namespace {

constexpr double kStepPx = 0.25;       // Sample spacing across an edge.
constexpr double kMinContrast = 0.08;  // Linear-light rise that counts as an edge.
constexpr int kMaxPointsPerSide = 40;
constexpr double kMaxCornerMovePx = 3.0;

// A line n . x = offset with unit normal n, in ideal (undistorted) pixels.
struct Line {
  Eigen::Vector2d normal;
  double offset = 0.0;
};

// Bilinear sample of a CV_32FC1 image at continuous pixel (x, y); nullopt
// outside the image.
std::optional<double> Sample(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x));
  const int y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= image.cols || y0 + 1 >= image.rows) return std::nullopt;
  const double ax = x - x0;
  const double ay = y - y0;
  const float* row0 = image.ptr<float>(y0);
  const float* row1 = image.ptr<float>(y0 + 1);
  return (1.0 - ay) * ((1.0 - ax) * row0[x0] + ax * row0[x0 + 1]) +
         ay * ((1.0 - ax) * row1[x0] + ax * row1[x0 + 1]);
}

// Offset along `normal` from `point` (pixels) where the profile rises through
// the mid level between its darkest and brightest samples; the crossing
// nearest to `point`. nullopt without a clear rising edge.
std::optional<double> EdgeCrossing(const cv::Mat& linear, const Eigen::Vector2d& point,
                                   const Eigen::Vector2d& normal, double reach_px) {
  const int half = static_cast<int>(std::ceil(reach_px / kStepPx));
  std::vector<double> values;
  values.reserve(2 * half + 1);
  for (int i = -half; i <= half; ++i) {
    const Eigen::Vector2d p = point + i * kStepPx * normal;
    const std::optional<double> value = Sample(linear, p.x(), p.y());
    if (!value) return std::nullopt;
    values.push_back(*value);
  }
  const auto [low, high] = std::minmax_element(values.begin(), values.end());
  if (*high - *low < kMinContrast) return std::nullopt;
  const double mid = 0.5 * (*low + *high);
  std::optional<double> best;
  for (size_t i = 0; i + 1 < values.size(); ++i) {
    if (!(values[i] < mid && values[i + 1] >= mid)) continue;
    const double s =
        (static_cast<double>(i) - half + (mid - values[i]) / (values[i + 1] - values[i])) * kStepPx;
    if (!best || std::abs(s) < std::abs(*best)) best = s;
  }
  return best;
}

std::optional<Eigen::Vector2d> ToIdeal(const CameraIntrinsics& k, const Eigen::Vector2d& pixel) {
  if (!k.HasDistortion()) return pixel;
  const std::optional<Eigen::Vector2d> normalized =
      k.Undistort(Eigen::Vector2d((pixel.x() - k.cx) / k.fx, (pixel.y() - k.cy) / k.fy));
  if (!normalized) return std::nullopt;
  return Eigen::Vector2d(k.fx * normalized->x() + k.cx, k.fy * normalized->y() + k.cy);
}

Eigen::Vector2d FromIdeal(const CameraIntrinsics& k, const Eigen::Vector2d& ideal) {
  if (!k.HasDistortion()) return ideal;
  const Eigen::Vector2d distorted =
      k.Distort(Eigen::Vector2d((ideal.x() - k.cx) / k.fx, (ideal.y() - k.cy) / k.fy));
  return Eigen::Vector2d(k.fx * distorted.x() + k.cx, k.fy * distorted.y() + k.cy);
}

// Total-least-squares line through `points`.
Line FitLineOnce(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) centroid += p / static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& p : points) scatter += (p - centroid) * (p - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  Line line;
  line.normal = solver.eigenvectors().col(0);  // Smallest eigenvalue first.
  line.offset = line.normal.dot(centroid);
  return line;
}

// Fits a line, drops the points over 0.5 px off it, and fits again.
std::optional<Line> FitLine(std::vector<Eigen::Vector2d> points) {
  if (points.size() < 4) return std::nullopt;
  const Line first = FitLineOnce(points);
  std::erase_if(points, [&](const Eigen::Vector2d& p) {
    return std::abs(first.normal.dot(p) - first.offset) > 0.5;
  });
  if (points.size() < 4) return std::nullopt;
  return FitLineOnce(points);
}

std::optional<Eigen::Vector2d> Intersect(const Line& a, const Line& b) {
  Eigen::Matrix2d normals;
  normals << a.normal.transpose(), b.normal.transpose();
  if (std::abs(normals.determinant()) < 0.05) return std::nullopt;  // Nearly parallel.
  return normals.inverse() * Eigen::Vector2d(a.offset, b.offset);
}

// The outer edge of side a -> b of a marker whose corners average to
// `centre`, as a line in ideal pixels; nullopt when too few crossings.
std::optional<Line> FitSide(const cv::Mat& linear, const CameraIntrinsics& intrinsics,
                            const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                            const Eigen::Vector2d& centre, double reach_px) {
  const double length = (b - a).norm();
  const double end_margin = reach_px + 2.0;  // Keep clear of the neighbouring sides.
  if (length < 2.0 * end_margin + 4.0) return std::nullopt;
  const Eigen::Vector2d along = (b - a) / length;
  Eigen::Vector2d normal(-along.y(), along.x());
  if (normal.dot(0.5 * (a + b) - centre) < 0.0) normal = -normal;  // Outward: dark to bright.
  const int count =
      std::clamp(static_cast<int>((length - 2.0 * end_margin) / 1.5), 4, kMaxPointsPerSide);
  std::vector<Eigen::Vector2d> edge_points;
  for (int j = 0; j < count; ++j) {
    const double t = end_margin + (length - 2.0 * end_margin) * j / (count - 1);
    const Eigen::Vector2d p = a + t * along;
    const std::optional<double> crossing = EdgeCrossing(linear, p, normal, reach_px);
    if (!crossing) continue;
    if (auto ideal = ToIdeal(intrinsics, p + *crossing * normal)) edge_points.push_back(*ideal);
  }
  if (static_cast<int>(edge_points.size()) < std::max(4, count / 2)) return std::nullopt;
  return FitLine(std::move(edge_points));
}

// One refinement pass over the four corners; false when a side fails.
bool RefineOnce(const cv::Mat& linear, const CameraIntrinsics& intrinsics, int cells_per_side,
                std::array<Eigen::Vector2d, 4>* corners) {
  const std::array<Eigen::Vector2d, 4>& c = *corners;
  double shortest_px = 1e9;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (int k = 0; k < 4; ++k) {
    shortest_px = std::min(shortest_px, (c[(k + 1) % 4] - c[k]).norm());
    centre += 0.25 * c[k];
  }
  // Reach across the black border (one cell) but not into the marker's bits.
  const double reach_px = std::clamp(0.8 * shortest_px / cells_per_side, 1.5, 6.0);
  std::array<Line, 4> sides;
  for (int k = 0; k < 4; ++k) {
    const std::optional<Line> side =
        FitSide(linear, intrinsics, c[k], c[(k + 1) % 4], centre, reach_px);
    if (!side) return false;
    sides[k] = *side;
  }
  std::array<Eigen::Vector2d, 4> refined;
  for (int k = 0; k < 4; ++k) {
    // Corner k joins side k - 1 (ending at it) and side k (starting at it).
    const std::optional<Eigen::Vector2d> ideal = Intersect(sides[(k + 3) % 4], sides[k]);
    if (!ideal) return false;
    refined[k] = FromIdeal(intrinsics, *ideal);
    if ((refined[k] - c[k]).norm() > kMaxCornerMovePx) return false;
  }
  *corners = refined;
  return true;
}

}  // namespace

cv::Mat LinearGrey(const cv::Mat& grey_srgb) {
  cv::Mat table(1, 256, CV_32FC1);
  for (int i = 0; i < 256; ++i) {
    const double v = i / 255.0;
    table.at<float>(0, i) =
        static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
  }
  cv::Mat linear;
  cv::LUT(grey_srgb, table, linear);
  return linear;
}

bool RefineCornersFromEdges(const cv::Mat& linear_grey, const CameraIntrinsics& intrinsics,
                            int cells_per_side, std::array<cv::Point2f, 4>* corners) {
  std::array<Eigen::Vector2d, 4> estimate;
  for (int k = 0; k < 4; ++k) estimate[k] = Eigen::Vector2d((*corners)[k].x, (*corners)[k].y);
  // The second pass samples along the sides found by the first.
  for (int pass = 0; pass < 2; ++pass) {
    if (!RefineOnce(linear_grey, intrinsics, cells_per_side, &estimate)) return false;
  }
  for (int k = 0; k < 4; ++k) {
    (*corners)[k] =
        cv::Point2f(static_cast<float>(estimate[k].x()), static_cast<float>(estimate[k].y()));
  }
  return true;
}

}  // namespace reenact::board::internal
