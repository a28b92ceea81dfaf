// People in one depth image: the floor by RANSAC, depth-continuous
// components, and the components of a person's size (person_segmentation.h).
#include "common/tracking/person_segmentation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string_view>
#include <tuple>
#include <utility>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"

namespace reenact::tracking {
namespace {

constexpr int kFloorStride = 4;       // The floor is fitted on every 4th pixel in x and y.
constexpr int kMinFloorSamples = 50;  // Fewer valid samples: no floor.
// RANSAC draws its 2nd and 3rd points within this many grid cells of the 1st.
constexpr int kNeighbourCells = 8;
// Draws that give no floor candidate (walls, people) do not count as RANSAC
// iterations, up to this many draws per iteration.
constexpr int kDrawsPerIteration = 20;
constexpr int kFloorRefinements = 5;        // Least-squares passes after RANSAC (settled after 4 on
                                            // the five-people frame of PCL's test data).
constexpr double kUnderFloorInliers = 3.0;  // Samples this many inlier distances under a
constexpr double kMaxUnderFloorFraction = 0.02;  // plane: at most this share for a floor.
constexpr double kNoiseSigmas = 4.0;             // Connection threshold, in axial noise sigmas.
constexpr double kExtentPercentile = 0.01;       // Extents span the 1st to the 99th percentile.
constexpr int kMaxPeople = 255;                  // Labels are 8-bit.

// Person tests beyond the options (step 3 of the file comment of
// person_segmentation.h). Components cut short by the edge of the view lie
// within kBorderMarginPx of the valid pixels' bounding box; those with
// kMinOccludedOutline of their outline within kOcclusionRadiusPx of a nearer
// surface are occluded. Either way, what is seen is only part of a person.
constexpr int kBorderMarginPx = 4;
constexpr int kOcclusionRadiusPx = 2;
constexpr double kMinOccludedOutline = 0.1;
constexpr double kMinAreaM2 = 0.15;        // Surface seen: a child's torso and head.
constexpr double kMinThicknessM = 0.02;    // Flatter: a wall, a door, a board, a cabinet.
constexpr double kMaxDepthPerWidth = 3.0;  // Deeper: a wall or a door seen edge-on.
constexpr double kMinStandingTopM = 0.9;   // Above a floor: a crouching adult's head.
constexpr double kMaxFootHeightM = 0.3;    // Above a floor: the lowest point of one standing.
constexpr double kMinWholeExtentM = 1.2;   // No floor: a whole person standing or seated.
// Head-based splitting: bins of the height profile, and how far a head
// rises above the shoulders between it and a higher head.
constexpr double kHeadBinM = 0.06;
constexpr double kMinHeadProminenceM = 0.15;
constexpr double kMaxGroupWidthM = 8.0;  // Wider candidates are not split (walls).
// Step 4 (pieces): a piece smaller than this is noise, not a limb.
constexpr int kMinPiecePixels = 30;
// A piece touches a person where one of its pixels has a person pixel within
// this radius (the cut removed one pixel of rim) no farther than
// attach_step_m away in depth; it needs this many such pixels.
constexpr int kAttachRadiusPx = 2;
constexpr int kMinContactPixels = 4;
constexpr int kAttachPasses = 4;  // A hand can attach through its forearm.

// A plane n . p + d = 0 with n unit, metres.
using Plane = Eigen::Vector4d;

// Kinect v1 axial depth noise, metres (Nguyen, Izadi and Lovell, "Modeling
// Kinect Sensor Noise for Improved 3D Reconstruction and Tracking", 3DIMPVT
// 2012): the noisiest of the Kinect-class sensors, so a safe bound for all.
double AxialSigmaM(double z_m) { return 0.0012 + 0.0019 * (z_m - 0.4) * (z_m - 0.4); }

// Neighbours farther apart than this (metres) at depth `z_m` are not connected.
double ConnectStepM(double z_m, const PersonSegmentationOptions& options) {
  return std::max(options.depth_step_m, kNoiseSigmas * AxialSigmaM(z_m));
}

double SignedDistance(const Plane& plane, const Eigen::Vector3d& point) {
  return plane.head<3>().dot(point) + plane.w();
}

// The image's up direction in the camera frame (OpenCV axes: y down).
Eigen::Vector3d ImageUp() { return -Eigen::Vector3d::UnitY(); }

// Per-pixel points in the camera frame, metres; z = 0 where the depth is
// missing, out of range, or cannot be undistorted.
struct Cloud {
  int width = 0;
  int height = 0;
  std::vector<Eigen::Vector3f> points;
  double pixel_area_per_z2 = 0.0;  // 1 / (fx fy): a pixel at depth z covers z^2 times this.

  bool valid(size_t i) const { return points[i].z() > 0.0f; }
  Eigen::Vector3d at(size_t i) const { return points[i].cast<double>(); }
};

absl::Status CheckInputs(const DepthImageMm& depth, const CameraIntrinsics& intrinsics) {
  if (absl::Status status = intrinsics.Validate(); !status.ok()) return status;
  if (depth.empty() || depth.data.size() != depth.num_pixels()) {
    return absl::InvalidArgumentError(
        absl::StrCat("SegmentPeople: empty or malformed depth image (", depth.width, "x",
                     depth.height, ", ", depth.data.size(), " values)"));
  }
  if (depth.width != intrinsics.width || depth.height != intrinsics.height) {
    return absl::InvalidArgumentError(absl::StrCat("SegmentPeople: depth image of ", depth.width,
                                                   "x", depth.height, " px, intrinsics of ",
                                                   intrinsics.width, "x", intrinsics.height));
  }
  return absl::OkStatus();
}

Cloud BackProject(const DepthImageMm& depth, const CameraIntrinsics& intrinsics,
                  const PersonSegmentationOptions& options) {
  Cloud cloud{depth.width, depth.height,
              std::vector<Eigen::Vector3f>(depth.num_pixels(), Eigen::Vector3f::Zero()),
              1.0 / (intrinsics.fx * intrinsics.fy)};
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const double z_m = depth.at(x, y) * 1e-3;
      if (z_m < options.min_range_m || z_m > options.max_range_m) continue;
      const std::optional<Eigen::Vector2d> ray = intrinsics.Undistort(
          {(x - intrinsics.cx) / intrinsics.fx, (y - intrinsics.cy) / intrinsics.fy});
      if (!ray) continue;
      cloud.points[static_cast<size_t>(y) * depth.width + x] =
          Eigen::Vector3d(ray->x() * z_m, ray->y() * z_m, z_m).cast<float>();
    }
  }
  return cloud;
}

// The floor fit's samples: the points of every kFloorStride-th pixel, and
// for each cell of that grid the index of its point (-1: none).
struct FloorSamples {
  int cols = 0;
  int rows = 0;
  std::vector<int> point_of_cell;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2i> cell_of_point;
};

FloorSamples SampleForFloor(const Cloud& cloud) {
  FloorSamples samples;
  samples.cols = (cloud.width + kFloorStride - 1) / kFloorStride;
  samples.rows = (cloud.height + kFloorStride - 1) / kFloorStride;
  samples.point_of_cell.assign(static_cast<size_t>(samples.cols) * samples.rows, -1);
  for (int row = 0; row < samples.rows; ++row) {
    for (int col = 0; col < samples.cols; ++col) {
      const size_t i = static_cast<size_t>(row * kFloorStride) * cloud.width + col * kFloorStride;
      if (!cloud.valid(i)) continue;
      samples.point_of_cell[static_cast<size_t>(row) * samples.cols + col] =
          static_cast<int>(samples.points.size());
      samples.points.push_back(cloud.at(i));
      samples.cell_of_point.emplace_back(col, row);
    }
  }
  return samples;
}

// The plane through `centre` with `normal` turned towards the image's up,
// when it is a floor candidate: within `max_tilt_deg` of up and below the
// camera (the camera, at the origin, on its upper side).
std::optional<Plane> UpFacingPlane(Eigen::Vector3d normal, const Eigen::Vector3d& centre,
                                   double max_tilt_deg) {
  if (!(normal.norm() > 1e-12)) return std::nullopt;
  normal.normalize();
  if (normal.dot(ImageUp()) < 0.0) normal = -normal;
  const double offset = -normal.dot(centre);
  if (normal.dot(ImageUp()) < std::cos(max_tilt_deg * M_PI / 180.0) || offset <= 0.0) {
    return std::nullopt;
  }
  return Plane(normal.x(), normal.y(), normal.z(), offset);
}

// How many samples lie near a plane and how many lie under it, farther than
// kUnderFloorInliers inlier distances (noise aside, nothing is under a floor).
struct PlaneSupport {
  int inliers = 0;
  int under = 0;
};

PlaneSupport Support(const std::vector<Eigen::Vector3d>& samples, const Plane& plane,
                     double inlier_m) {
  PlaneSupport support;
  for (const Eigen::Vector3d& p : samples) {
    const double distance = SignedDistance(plane, p);
    support.inliers += std::abs(distance) < inlier_m;
    support.under += distance < -kUnderFloorInliers * inlier_m;
  }
  return support;
}

// A floor candidate's score: its inliers, or 0 when too much lies under it.
int FloorScore(const std::vector<Eigen::Vector3d>& samples, const Plane& plane, double inlier_m) {
  const PlaneSupport support = Support(samples, plane, inlier_m);
  return support.under > kMaxUnderFloorFraction * samples.size() ? 0 : support.inliers;
}

// The sample within kNeighbourCells grid cells of sample `centre` that a
// random offset lands on, when there is one.
const Eigen::Vector3d* RandomNeighbour(const FloorSamples& samples, int centre,
                                       std::mt19937_64& rng) {
  std::uniform_int_distribution<int> offset(-kNeighbourCells, kNeighbourCells);
  const Eigen::Vector2i cell = samples.cell_of_point[static_cast<size_t>(centre)] +
                               Eigen::Vector2i(offset(rng), offset(rng));
  if (cell.x() < 0 || cell.y() < 0 || cell.x() >= samples.cols || cell.y() >= samples.rows) {
    return nullptr;
  }
  const int index = samples.point_of_cell[static_cast<size_t>(cell.y()) * samples.cols + cell.x()];
  return index < 0 ? nullptr : &samples.points[static_cast<size_t>(index)];
}

// A candidate plane from a random sample and two image neighbours of it
// (NAPSAC: Myatt et al., "NAPSAC: High Noise, High Dimensional Robust
// Estimation", BMVC 2002), so that a floor seen in a small part of the image
// is still drawn often; nullopt when the draw gives no floor candidate.
std::optional<Plane> DrawFloorCandidate(const FloorSamples& samples, std::mt19937_64& rng,
                                        double max_tilt_deg) {
  std::uniform_int_distribution<int> pick(0, static_cast<int>(samples.points.size()) - 1);
  const int centre = pick(rng);
  const Eigen::Vector3d& a = samples.points[static_cast<size_t>(centre)];
  const Eigen::Vector3d* b = RandomNeighbour(samples, centre, rng);
  const Eigen::Vector3d* c = RandomNeighbour(samples, centre, rng);
  if (b == nullptr || c == nullptr) return std::nullopt;
  return UpFacingPlane((*b - a).cross(*c - a), a, max_tilt_deg);
}

// RANSAC (Fischler and Bolles, "Random Sample Consensus", CACM 1981): of
// floor_iterations candidate planes through three samples that could be a
// floor, the one with the most samples within floor_inlier_m and almost
// nothing under it.
std::optional<Plane> RansacFloor(const FloorSamples& samples,
                                 const PersonSegmentationOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::optional<Plane> best;
  int best_inliers = 0;
  const int max_draws = kDrawsPerIteration * options.floor_iterations;
  for (int candidates = 0, draws = 0; candidates < options.floor_iterations && draws < max_draws;
       ++draws) {
    const std::optional<Plane> plane = DrawFloorCandidate(samples, rng, options.max_floor_tilt_deg);
    if (!plane) continue;
    ++candidates;
    const int inliers = FloorScore(samples.points, *plane, options.floor_inlier_m);
    if (inliers > best_inliers) {
      best = plane;
      best_inliers = inliers;
    }
  }
  return best;
}

// Total least squares on the inliers of `plane`: the normal is the direction
// of least spread of their scatter matrix, through their centroid.
std::optional<Plane> RefineFloor(const std::vector<Eigen::Vector3d>& samples, const Plane& plane,
                                 const PersonSegmentationOptions& options) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d moments = Eigen::Matrix3d::Zero();
  int count = 0;
  for (const Eigen::Vector3d& p : samples) {
    if (std::abs(SignedDistance(plane, p)) >= options.floor_inlier_m) continue;
    sum += p;
    moments += p * p.transpose();
    ++count;
  }
  if (count < 3) return std::nullopt;
  const Eigen::Vector3d centroid = sum / count;
  const Eigen::Matrix3d scatter = moments / count - centroid * centroid.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  return UpFacingPlane(solver.eigenvectors().col(0), centroid, options.max_floor_tilt_deg);
}

// The floor (step 1 of the file comment of person_segmentation.h), when the
// image shows one.
std::optional<Plane> FindFloor(const Cloud& cloud, const PersonSegmentationOptions& options) {
  const FloorSamples samples = SampleForFloor(cloud);
  if (samples.points.size() < kMinFloorSamples) return std::nullopt;
  std::optional<Plane> floor = RansacFloor(samples, options);
  for (int pass = 0; pass < kFloorRefinements && floor; ++pass) {
    floor = RefineFloor(samples.points, *floor, options);
  }
  if (!floor) return std::nullopt;
  const int inliers = FloorScore(samples.points, *floor, options.floor_inlier_m);
  const double needed =
      std::max<double>(kMinFloorSamples, options.min_floor_fraction * samples.points.size());
  if (inliers < needed) return std::nullopt;
  return floor;
}

// 1 for the valid pixels that are not floor.
cv::Mat AboveFloor(const Cloud& cloud, const std::optional<Plane>& floor,
                   const PersonSegmentationOptions& options) {
  cv::Mat mask(cloud.height, cloud.width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < cloud.height; ++y) {
    uint8_t* row = mask.ptr<uint8_t>(y);
    for (int x = 0; x < cloud.width; ++x) {
      const size_t i = static_cast<size_t>(y) * cloud.width + x;
      if (!cloud.valid(i)) continue;
      row[x] = !floor || SignedDistance(*floor, cloud.at(i)) >= options.floor_distance_m;
    }
  }
  return mask;
}

// Step 2 before labelling: of two 8-neighbours of `mask` farther apart than
// ConnectStepM, the farther one is removed, so that no two remaining
// neighbours straddle a depth discontinuity. Departure from a graph
// labelling with a depth predicate on its edges: one pixel of the farther
// surface's rim is lost, which lets OpenCV label the components.
cv::Mat CutAtDepthSteps(const Cloud& cloud, const cv::Mat& mask,
                        const PersonSegmentationOptions& options) {
  cv::Mat kept = mask.clone();
  constexpr int kForward[4][2] = {{1, 0}, {-1, 1}, {0, 1}, {1, 1}};
  for (int y = 0; y < cloud.height; ++y) {
    for (int x = 0; x < cloud.width; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const float z = cloud.points[static_cast<size_t>(y) * cloud.width + x].z();
      for (const auto& [dx, dy] : kForward) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || nx >= cloud.width || ny >= cloud.height || !mask.at<uint8_t>(ny, nx))
          continue;
        const float nz = cloud.points[static_cast<size_t>(ny) * cloud.width + nx].z();
        if (std::abs(nz - z) <= ConnectStepM(std::min(z, nz), options)) continue;
        if (nz > z) {
          kept.at<uint8_t>(ny, nx) = 0;
        } else {
          kept.at<uint8_t>(y, x) = 0;
        }
      }
    }
  }
  return kept;
}

// Axes in which a component's size is measured: up (the floor's normal, or
// the image's up), right (the camera's x on the ground), forward (away from
// the camera along the ground).
struct GroundAxes {
  Eigen::Vector3d up, right, forward;
  double up_offset_m = 0.0;  // Added to up . p: the height above the floor.
};

GroundAxes AxesFor(const std::optional<Plane>& floor) {
  GroundAxes axes;
  axes.up = floor ? Eigen::Vector3d(floor->head<3>()) : ImageUp();
  axes.up_offset_m = floor ? floor->w() : 0.0;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
  axes.right = (x - x.dot(axes.up) * axes.up).normalized();
  axes.forward = axes.up.cross(axes.right);
  return axes;
}

// What the person tests look at, shared by every candidate of one image.
struct Scene {
  const Cloud& cloud;
  const PersonSegmentationOptions& options;
  GroundAxes axes;
  bool has_floor = false;
  cv::Rect valid_bounds;  // Bounding box of the valid pixels: the sensor's view.
};

// Indices (y * width + x) of the pixels of one candidate.
using Pixels = std::vector<size_t>;

cv::Rect BoundsOf(const Pixels& pixels, int width) {
  int min_x = width, min_y = std::numeric_limits<int>::max(), max_x = -1, max_y = -1;
  for (const size_t i : pixels) {
    const int x = static_cast<int>(i % width), y = static_cast<int>(i / width);
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
  }
  return pixels.empty() ? cv::Rect() : cv::Rect(min_x, min_y, max_x - min_x + 1, max_y - min_y + 1);
}

// The values at the kExtentPercentile and 1 - kExtentPercentile quantiles.
std::pair<double, double> RobustRange(std::vector<double> values) {
  const size_t last = values.size() - 1;
  const auto lo = values.begin() + static_cast<long>(std::floor(kExtentPercentile * last));
  const auto hi = values.begin() + static_cast<long>(std::ceil((1.0 - kExtentPercentile) * last));
  std::nth_element(values.begin(), lo, values.end());
  const double low = *lo;
  std::nth_element(values.begin(), hi, values.end());
  return {low, *hi};
}

// A candidate's metric figures.
struct Shape {
  double bottom_m = 0.0;     // Robust range along up: above the floor when there is one,
  double top_m = 0.0;        // else relative to the camera.
  double width_m = 0.0;      // Robust extent along right.
  double depth_m = 0.0;      // Robust extent along forward.
  double thickness_m = 0.0;  // RMS distance to the best-fitting plane, axial noise removed.
  double area_m2 = 0.0;      // Surface seen: a pixel at depth z covers z^2 / (fx fy).
};

// RMS distance of the points to their total-least-squares plane, less the
// axial noise at their mean depth (0 for a plane seen through noise).
double Thickness(const Cloud& cloud, const Pixels& pixels) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d moments = Eigen::Matrix3d::Zero();
  for (const size_t i : pixels) {
    const Eigen::Vector3d p = cloud.at(i);
    sum += p;
    moments += p * p.transpose();
  }
  const Eigen::Vector3d mean = sum / static_cast<double>(pixels.size());
  const Eigen::Matrix3d scatter =
      moments / static_cast<double>(pixels.size()) - mean * mean.transpose();
  const double least = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues()(0);
  const double noise = AxialSigmaM(mean.z());
  return std::sqrt(std::max(0.0, least - noise * noise));
}

Shape Measure(const Scene& scene, const Pixels& pixels) {
  std::vector<double> up, right, forward;
  Shape shape;
  for (const size_t i : pixels) {
    const Eigen::Vector3d p = scene.cloud.at(i);
    up.push_back(scene.axes.up.dot(p) + scene.axes.up_offset_m);
    right.push_back(scene.axes.right.dot(p));
    forward.push_back(scene.axes.forward.dot(p));
    shape.area_m2 += p.z() * p.z() * scene.cloud.pixel_area_per_z2;
  }
  std::tie(shape.bottom_m, shape.top_m) = RobustRange(std::move(up));
  const auto [left, right_edge] = RobustRange(std::move(right));
  const auto [near, far] = RobustRange(std::move(forward));
  shape.width_m = right_edge - left;
  shape.depth_m = far - near;
  shape.thickness_m = Thickness(scene.cloud, pixels);
  return shape;
}

// Where a candidate's view is cut short: by the edges of the sensor's view,
// or by nearer surfaces in front of it, above or below.
struct Cuts {
  bool top = false;
  bool bottom = false;
  bool side = false;
  bool occluded_above = false;
  bool occluded_below = false;

  bool any() const { return top || bottom || side || occluded_above || occluded_below; }
};

// Where `window` holds a valid point nearer than `z_m` by more than the
// connection step: {above row y, below row y}.
std::pair<bool, bool> NearerNeighbours(const Cloud& cloud, const cv::Rect& window, int y, float z_m,
                                       const PersonSegmentationOptions& options) {
  const float limit = z_m - static_cast<float>(ConnectStepM(z_m, options));
  std::pair<bool, bool> found(false, false);
  for (int v = window.y; v < window.y + window.height; ++v) {
    for (int u = window.x; u < window.x + window.width; ++u) {
      const size_t j = static_cast<size_t>(v) * cloud.width + u;
      if (!cloud.valid(j) || cloud.points[j].z() >= limit) continue;
      found.first |= v < y;
      found.second |= v > y;
    }
  }
  return found;
}

// Sets the occlusion flags of `cuts`: a share kMinOccludedOutline of the
// candidate's outline lies within kOcclusionRadiusPx (above, or below) of a
// valid point nearer than it by more than the connection step. `box`: the
// candidate's bounding box.
void FindOcclusion(const Scene& scene, const Pixels& pixels, const cv::Rect& box, Cuts& cuts) {
  const Cloud& cloud = scene.cloud;
  const int r = kOcclusionRadiusPx;
  const cv::Rect image(0, 0, cloud.width, cloud.height);
  const cv::Rect padded(box.x - r, box.y - r, box.width + 2 * r, box.height + 2 * r);
  cv::Mat member(padded.size(), CV_8U, cv::Scalar(0));
  for (const size_t i : pixels) {
    member.at<uint8_t>(static_cast<int>(i / cloud.width) - padded.y,
                       static_cast<int>(i % cloud.width) - padded.x) = 1;
  }
  int outline = 0, above = 0, below = 0;
  for (const size_t i : pixels) {
    const int x = static_cast<int>(i % cloud.width), y = static_cast<int>(i / cloud.width);
    const cv::Rect window = cv::Rect(x - r, y - r, 2 * r + 1, 2 * r + 1) & image;
    if (cv::countNonZero(member(window - padded.tl())) == window.area()) continue;  // Inside.
    ++outline;
    const auto [nearer_above, nearer_below] =
        NearerNeighbours(cloud, window, y, cloud.points[i].z(), scene.options);
    above += nearer_above;
    below += nearer_below;
  }
  cuts.occluded_above = outline > 0 && above >= kMinOccludedOutline * outline;
  cuts.occluded_below = outline > 0 && below >= kMinOccludedOutline * outline;
}

Cuts FindCuts(const Scene& scene, const cv::Rect& box) {
  const cv::Rect& view = scene.valid_bounds;
  Cuts cuts;
  cuts.top = box.y <= view.y + kBorderMarginPx;
  cuts.bottom = box.br().y >= view.br().y - kBorderMarginPx;
  cuts.side = box.x <= view.x + kBorderMarginPx || box.br().x >= view.br().x - kBorderMarginPx;
  return cuts;
}

// Step 3 of the file comment of person_segmentation.h, on the metric
// figures alone: a person's size, neither flat nor seen edge-on.
bool HasPersonSize(const Shape& shape, const PersonSegmentationOptions& options) {
  return shape.area_m2 >= kMinAreaM2 && shape.top_m - shape.bottom_m >= options.min_height_m &&
         shape.width_m <= options.max_width_m && shape.depth_m <= options.max_depth_extent_m &&
         shape.depth_m <= kMaxDepthPerWidth * shape.width_m && shape.thickness_m >= kMinThicknessM;
}

// Step 3, heights: above a floor, a person's top is a person's height and
// the person stands on the floor; without one, a person seen whole is tall.
// What the view cuts short (`cuts`) is exempt.
bool StandsLikePerson(const Shape& shape, const Cuts& cuts, bool has_floor,
                      const PersonSegmentationOptions& options) {
  if (!has_floor) {
    const double extent = shape.top_m - shape.bottom_m;
    return extent <= options.max_height_m && (cuts.any() || extent >= kMinWholeExtentM);
  }
  return shape.top_m >= options.min_height_m && shape.top_m <= options.max_height_m &&
         (cuts.top || cuts.occluded_above || shape.top_m >= kMinStandingTopM) &&
         (cuts.bottom || cuts.occluded_below || shape.bottom_m <= kMaxFootHeightM);
}

bool IsPerson(const Scene& scene, const Pixels& pixels) {
  if (static_cast<int>(pixels.size()) < scene.options.min_points) return false;
  const Shape shape = Measure(scene, pixels);
  if (!HasPersonSize(shape, scene.options)) return false;
  const cv::Rect box = BoundsOf(pixels, scene.cloud.width);
  Cuts cuts = FindCuts(scene, box);
  if (StandsLikePerson(shape, cuts, scene.has_floor, scene.options)) return true;
  FindOcclusion(scene, pixels, box, cuts);
  return StandsLikePerson(shape, cuts, scene.has_floor, scene.options);
}

// The 8-connected components of `kept` with at least `min_pixels` pixels.
std::vector<Pixels> LabelComponents(const cv::Mat& kept, int min_pixels) {
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(kept, labels, stats, centroids, 8, CV_32S);
  std::vector<int> slot(static_cast<size_t>(count), -1);
  std::vector<Pixels> components;
  for (int label = 1; label < count; ++label) {
    if (stats.at<int>(label, cv::CC_STAT_AREA) < min_pixels) continue;
    slot[static_cast<size_t>(label)] = static_cast<int>(components.size());
    components.emplace_back();
  }
  for (int y = 0; y < labels.rows; ++y) {
    const int* row = labels.ptr<int>(y);
    for (int x = 0; x < labels.cols; ++x) {
      const int s = slot[static_cast<size_t>(row[x])];
      if (s >= 0)
        components[static_cast<size_t>(s)].push_back(static_cast<size_t>(y) * labels.cols + x);
    }
  }
  return components;
}

// The highest point of a candidate (metres along up) in each kHeadBinM slice
// along right, -infinity where a slice is empty; no slices for a candidate
// wider than kMaxGroupWidthM.
struct HeightProfile {
  double first_bin_m = 0.0;  // Where bin 0 starts along right.
  std::vector<double> heights;
};

HeightProfile ProfileOf(const Scene& scene, const Pixels& pixels) {
  std::vector<double> right;
  for (const size_t i : pixels) right.push_back(scene.axes.right.dot(scene.cloud.at(i)));
  HeightProfile profile;
  profile.first_bin_m = *std::min_element(right.begin(), right.end());
  const double last_m = *std::max_element(right.begin(), right.end());
  if (last_m - profile.first_bin_m > kMaxGroupWidthM) return profile;  // No heads.
  profile.heights.assign(static_cast<size_t>((last_m - profile.first_bin_m) / kHeadBinM) + 1,
                         -std::numeric_limits<double>::infinity());
  for (size_t k = 0; k < pixels.size(); ++k) {
    const double up = scene.axes.up.dot(scene.cloud.at(pixels[k])) + scene.axes.up_offset_m;
    double& bin =
        profile.heights[static_cast<size_t>((right[k] - profile.first_bin_m) / kHeadBinM)];
    bin = std::max(bin, up);
  }
  return profile;
}

// How far bin `b` of `profile` rises above the lowest bin on its way to
// higher ground (topographic prominence); infinite for the highest bin. Of
// equal bins, the leftmost counts as the higher.
double Prominence(const std::vector<double>& profile, long b) {
  const long bins = static_cast<long>(profile.size());
  const double height = profile[static_cast<size_t>(b)];
  double col = -std::numeric_limits<double>::infinity();
  bool higher_exists = false;
  for (const long direction : {-1L, 1L}) {
    double lowest = height;
    for (long o = b + direction; o >= 0 && o < bins; o += direction) {
      const double other = profile[static_cast<size_t>(o)];
      if (other > height || (other == height && o < b)) {
        col = std::max(col, lowest);
        higher_exists = true;
        break;
      }
      lowest = std::min(lowest, other);
    }
  }
  return higher_exists ? height - col : std::numeric_limits<double>::infinity();
}

// Positions along right (metres) of the profile's heads: bins at least a
// crouching person's height that rise kMinHeadProminenceM above the col to
// any higher bin.
std::vector<double> FindHeads(const HeightProfile& profile) {
  std::vector<double> heads;
  for (long b = 0; b < static_cast<long>(profile.heights.size()); ++b) {
    if (profile.heights[static_cast<size_t>(b)] < kMinStandingTopM) continue;
    if (Prominence(profile.heights, b) < kMinHeadProminenceM) continue;
    heads.push_back(profile.first_bin_m + (static_cast<double>(b) + 0.5) * kHeadBinM);
  }
  return heads;
}

// Each pixel goes to the head nearest to it along right.
std::vector<Pixels> ShareAmongHeads(const Scene& scene, const Pixels& pixels,
                                    const std::vector<double>& heads) {
  std::vector<Pixels> shares(heads.size());
  for (const size_t i : pixels) {
    const double right = scene.axes.right.dot(scene.cloud.at(i));
    size_t nearest = 0;
    for (size_t h = 1; h < heads.size(); ++h) {
      if (std::abs(heads[h] - right) < std::abs(heads[nearest] - right)) nearest = h;
    }
    shares[nearest].push_back(i);
  }
  return shares;
}

// Head-based sub-clustering (Munaro, Basso and Menegatti, "Tracking people
// within groups with RGB-D data", IROS 2012): people who touch form one
// component; the maxima of its height profile along the ground (heads; here
// the prominent ones rather than those a fixed distance apart) seed one
// person each and every pixel goes to the nearest head. Departure: a head whose share is not a
// person on its own (a raised hand) is dropped and the pixels are shared again; with fewer than two
// heads the component stays whole. Only above a floor, where a share's footing can be checked.
std::vector<Pixels> SplitByHeads(const Scene& scene, Pixels pixels) {
  if (!scene.has_floor) return {std::move(pixels)};
  std::vector<double> heads = FindHeads(ProfileOf(scene, pixels));
  while (heads.size() >= 2) {
    std::vector<Pixels> shares = ShareAmongHeads(scene, pixels, heads);
    size_t worst = shares.size();
    for (size_t h = 0; h < shares.size(); ++h) {
      if (IsPerson(scene, shares[h])) continue;
      if (worst == shares.size() || shares[h].size() < shares[worst].size()) worst = h;
    }
    if (worst == shares.size()) return shares;
    heads.erase(heads.begin() + static_cast<long>(worst));
  }
  return {std::move(pixels)};
}

// The figures of one person.
PersonSegment Summarise(const Scene& scene, const Pixels& pixels) {
  PersonSegment segment;
  segment.num_pixels = static_cast<int>(pixels.size());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const size_t i : pixels) sum += scene.cloud.at(i);
  segment.centroid_in_camera_m = sum / std::max(1, segment.num_pixels);
  const cv::Rect box = BoundsOf(pixels, scene.cloud.width);
  segment.min_x = box.x;
  segment.min_y = box.y;
  segment.max_x = box.br().x - 1;
  segment.max_y = box.br().y - 1;
  const Cuts cuts = FindCuts(scene, box);
  segment.touches_border = cuts.top || cuts.bottom || cuts.side;
  return segment;
}

// The bounding box of the valid pixels (the whole image when none is).
cv::Rect ValidBounds(const Cloud& cloud) {
  cv::Mat valid(cloud.height, cloud.width, CV_8U, cv::Scalar(0));
  for (size_t i = 0; i < cloud.points.size(); ++i) valid.data[i] = cloud.valid(i);
  const cv::Rect bounds = cv::boundingRect(valid);
  return bounds.area() > 0 ? bounds : cv::Rect(0, 0, cloud.width, cloud.height);
}

// Pixels of `piece` with a pixel of person k within kAttachRadiusPx that is
// at most attach_step_m nearer or farther, per person (`owner`: the person
// of each pixel, -1 for none).
std::vector<int> CountContacts(const Scene& scene, const std::vector<int>& owner,
                               const Pixels& piece, size_t num_people) {
  const Cloud& cloud = scene.cloud;
  const float step = static_cast<float>(scene.options.attach_step_m);
  std::vector<int> contacts(num_people, 0);
  for (const size_t i : piece) {
    const int x = static_cast<int>(i % cloud.width), y = static_cast<int>(i / cloud.width);
    const float z = cloud.points[i].z();
    int found = -1;
    for (int v = std::max(0, y - kAttachRadiusPx);
         v <= std::min(cloud.height - 1, y + kAttachRadiusPx) && found < 0; ++v) {
      for (int u = std::max(0, x - kAttachRadiusPx);
           u <= std::min(cloud.width - 1, x + kAttachRadiusPx); ++u) {
        const size_t j = static_cast<size_t>(v) * cloud.width + u;
        if (owner[j] >= 0 && std::abs(cloud.points[j].z() - z) <= step) {
          found = owner[j];
          break;
        }
      }
    }
    if (found >= 0) ++contacts[static_cast<size_t>(found)];
  }
  return contacts;
}

// Step 4 (our addition to the file comment of person_segmentation.h): a
// person's own parts occlude each other, and the depth step between a
// raised arm and the face behind it, or a forearm across the chest, is
// larger than the connection step, so the head or an arm can come out as a
// component of its own that is no person by itself. Such a piece joins the
// person it touches across a step of at most attach_step_m (the room behind
// a person lies farther), when the two together still have a person's size.
void AttachPieces(const Scene& scene, std::vector<Pixels>& people, std::vector<Pixels>& pieces) {
  if (people.empty() || pieces.empty() || !(scene.options.attach_step_m > 0.0)) return;
  const Cloud& cloud = scene.cloud;
  std::vector<int> owner(cloud.points.size(), -1);
  std::vector<cv::Rect> reach;  // Each person's box grown by the attach radius.
  for (size_t k = 0; k < people.size(); ++k) {
    for (const size_t i : people[k]) owner[i] = static_cast<int>(k);
    const cv::Rect box = BoundsOf(people[k], cloud.width);
    reach.emplace_back(box.x - kAttachRadiusPx, box.y - kAttachRadiusPx,
                       box.width + 2 * kAttachRadiusPx, box.height + 2 * kAttachRadiusPx);
  }
  bool changed = true;
  for (int pass = 0; pass < kAttachPasses && changed; ++pass) {
    changed = false;
    for (size_t p = 0; p < pieces.size();) {
      const cv::Rect box = BoundsOf(pieces[p], cloud.width);
      bool near_anyone = false;
      for (const cv::Rect& r : reach) near_anyone |= (box & r).area() > 0;
      int best = -1;
      if (near_anyone) {
        const std::vector<int> contacts = CountContacts(scene, owner, pieces[p], people.size());
        for (size_t k = 0; k < contacts.size(); ++k) {
          if (contacts[k] >= kMinContactPixels && (best < 0 || contacts[k] > contacts[best])) {
            best = static_cast<int>(k);
          }
        }
      }
      if (best >= 0) {
        Pixels joined = people[static_cast<size_t>(best)];
        joined.insert(joined.end(), pieces[p].begin(), pieces[p].end());
        const Shape shape = Measure(scene, joined);
        if (HasPersonSize(shape, scene.options) &&
            shape.top_m - shape.bottom_m <= scene.options.max_height_m) {
          for (const size_t i : pieces[p]) owner[i] = best;
          people[static_cast<size_t>(best)] = std::move(joined);
          reach[static_cast<size_t>(best)] |=
              cv::Rect(box.x - kAttachRadiusPx, box.y - kAttachRadiusPx,
                       box.width + 2 * kAttachRadiusPx, box.height + 2 * kAttachRadiusPx);
          pieces.erase(pieces.begin() + static_cast<long>(p));
          changed = true;
          continue;
        }
      }
      ++p;
    }
  }
}

// The people among the components of `kept`, largest first, labelled from 1
// in `result`.
void CollectPeople(const Cloud& cloud, const cv::Mat& kept,
                   const PersonSegmentationOptions& options, PersonSegmentation& result) {
  const Scene scene{cloud, options, AxesFor(result.floor_plane), result.floor_plane.has_value(),
                    ValidBounds(cloud)};
  std::vector<Pixels> people, pieces;
  for (Pixels& component : LabelComponents(kept, std::min(kMinPiecePixels, options.min_points))) {
    if (static_cast<int>(component.size()) < options.min_points) {
      pieces.push_back(std::move(component));
      continue;
    }
    for (Pixels& part : SplitByHeads(scene, std::move(component))) {
      if (IsPerson(scene, part)) {
        people.push_back(std::move(part));
      } else {
        pieces.push_back(std::move(part));
      }
    }
  }
  AttachPieces(scene, people, pieces);
  std::stable_sort(people.begin(), people.end(),
                   [](const Pixels& a, const Pixels& b) { return a.size() > b.size(); });
  if (people.size() > kMaxPeople) people.resize(kMaxPeople);
  result.labels = MaskImage(cloud.width, cloud.height);
  for (size_t k = 0; k < people.size(); ++k) {
    for (const size_t i : people[k]) result.labels.data[i] = static_cast<uint8_t>(k + 1);
    result.people.push_back(Summarise(scene, people[k]));
    result.people.back().label = static_cast<int>(k) + 1;
  }
}

}  // namespace

absl::Status PersonSegmentationOptions::Validate() const {
  auto bad = [](const char* field) {
    return absl::InvalidArgumentError(absl::StrCat("person segmentation: bad ", field));
  };
  if (!(min_range_m >= 0.0 && max_range_m > min_range_m && max_range_m <= 20.0)) {
    return bad("min_range_m / max_range_m (0 <= min < max <= 20)");
  }
  if (!(max_floor_tilt_deg >= 0.0 && max_floor_tilt_deg <= 90.0)) return bad("max_floor_tilt_deg");
  if (!(floor_inlier_m > 0.0 && floor_inlier_m <= 1.0)) return bad("floor_inlier_m");
  if (!(floor_distance_m >= 0.0 && floor_distance_m <= 1.0)) return bad("floor_distance_m");
  if (!(min_floor_fraction >= 0.0 && min_floor_fraction <= 1.0)) return bad("min_floor_fraction");
  if (floor_iterations < 0 || floor_iterations > 100000) return bad("floor_iterations");
  if (!(depth_step_m > 0.0 && depth_step_m <= 2.0)) return bad("depth_step_m");
  if (!(min_height_m >= 0.0 && max_height_m > min_height_m && max_height_m <= 10.0)) {
    return bad("min_height_m / max_height_m");
  }
  if (!(max_width_m > 0.0 && max_width_m <= 10.0)) return bad("max_width_m");
  if (!(max_depth_extent_m > 0.0 && max_depth_extent_m <= 10.0)) return bad("max_depth_extent_m");
  if (min_points < 1) return bad("min_points (>= 1)");
  if (!(attach_step_m >= 0.0 && attach_step_m <= 2.0)) return bad("attach_step_m");
  return absl::OkStatus();
}

absl::StatusOr<PersonSegmentation> SegmentPeople(const DepthImageMm& depth,
                                                 const CameraIntrinsics& intrinsics,
                                                 const PersonSegmentationOptions& options) {
  if (absl::Status status = options.Validate(); !status.ok()) return status;
  if (absl::Status status = CheckInputs(depth, intrinsics); !status.ok()) return status;
  const Cloud cloud = BackProject(depth, intrinsics, options);
  PersonSegmentation result;
  result.floor_plane = FindFloor(cloud, options);
  const cv::Mat kept =
      CutAtDepthSteps(cloud, AboveFloor(cloud, result.floor_plane, options), options);
  CollectPeople(cloud, kept, options, result);
  return result;
}

}  // namespace reenact::tracking
