#include "common/board/board_detector.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/board/aruco_dictionary.h"
#include "common/board/edge_refinement.h"

namespace reenact::board {
namespace {

// The markers of the board seen in one image, with their image corners in
// BoardMarker order (pixel centres at integer coordinates).
struct Observations {
  std::vector<int> ids;
  std::vector<std::array<cv::Point2f, 4>> corners;
};

// A camera pose against OpenCV's board axes (board_spec.h) and its fit.
struct PoseFit {
  cv::Mat rvec;  // cam_from_cvboard rotation, Rodrigues vector.
  cv::Mat tvec;  // cam_from_cvboard translation, metres.
  double rms_px = 0.0;
  std::vector<double> marker_error_px;  // Mean corner error per marker.
};

// The corners of the used markers in OpenCV's board axes (z = 0) and in the
// image, 4 per marker.
struct Correspondences {
  std::vector<cv::Point3f> object_points;
  std::vector<cv::Point2f> image_points;
};

// The camera model in OpenCV's form.
struct CvCamera {
  cv::Mat camera_matrix;  // 3x3.
  cv::Mat distortion;     // k1 k2 p1 p2 k3.
};

absl::Status ValidateInputs(const RgbImage& image, const CameraIntrinsics& intrinsics,
                            const BoardSpec& spec, const DetectorOptions& options) {
  if (image.width <= 0 || image.height <= 0 || image.data.size() != image.num_pixels() * 3) {
    return absl::InvalidArgumentError(absl::StrCat("DetectBoard: bad image ", image.width, "x",
                                                   image.height, " with ", image.data.size(),
                                                   " values"));
  }
  RETURN_IF_ERROR(intrinsics.Validate());
  if (intrinsics.width != image.width || intrinsics.height != image.height) {
    return absl::InvalidArgumentError(absl::StrCat(
        "DetectBoard: image of ", image.width, "x", image.height, " but intrinsics of ",
        intrinsics.width, "x", intrinsics.height, " (see ScaledIntrinsics)"));
  }
  RETURN_IF_ERROR(spec.Validate());
  return options.Validate();
}

cv::Mat ToGrey(const RgbImage& image) {
  const cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<uint8_t*>(image.data.data()));
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  return grey;
}

CvCamera ToCvCamera(const CameraIntrinsics& intrinsics) {
  CvCamera camera;
  camera.camera_matrix = (cv::Mat_<double>(3, 3) << intrinsics.fx, 0.0, intrinsics.cx, 0.0,
                          intrinsics.fy, intrinsics.cy, 0.0, 0.0, 1.0);
  camera.distortion = (cv::Mat_<double>(1, 5) << intrinsics.k1, intrinsics.k2, intrinsics.p1,
                       intrinsics.p2, intrinsics.k3);
  return camera;
}

// Detects the markers of `spec` in `grey`, corners scaled by 1 / `scale`
// (the image was resampled by `scale`); ids seen twice are dropped (a second
// board with the same ids, or a misread).
Observations FindMarkersAtScale(const cv::Mat& grey, double scale,
                                const cv::Ptr<cv::aruco::Dictionary>& dictionary,
                                const BoardSpec& spec) {
  const cv::Ptr<cv::aruco::DetectorParameters> parameters = cv::aruco::DetectorParameters::create();
  parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;  // Refined below.
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(grey, dictionary, corners, ids, parameters);
  std::map<int, int> count;
  for (int id : ids) ++count[id];
  Observations seen;
  for (size_t i = 0; i < ids.size(); ++i) {
    const int index = ids[i] - spec.first_marker_id;
    if (index < 0 || index >= spec.num_markers() || count[ids[i]] != 1 || corners[i].size() != 4) {
      continue;
    }
    std::array<cv::Point2f, 4> quad;
    for (int k = 0; k < 4; ++k) {
      // Pixel centres sit at integers in both images: p = (p_scaled + 0.5) / s - 0.5.
      quad[k] = (corners[i][k] + cv::Point2f(0.5f, 0.5f)) / scale - cv::Point2f(0.5f, 0.5f);
    }
    seen.ids.push_back(ids[i]);
    seen.corners.push_back(quad);
  }
  return seen;
}

// The markers of `spec` in `grey`; when some are missing and
// options.upsample_when_incomplete, also those found in the image upsampled
// 2x (the detector's contour and bit sampling steps need a few pixels per
// cell, which an oblique board far away does not have).
Observations FindMarkers(const cv::Mat& grey, const cv::Ptr<cv::aruco::Dictionary>& dictionary,
                         const BoardSpec& spec, const DetectorOptions& options) {
  Observations seen = FindMarkersAtScale(grey, 1.0, dictionary, spec);
  if (static_cast<int>(seen.ids.size()) == spec.num_markers() ||
      !options.upsample_when_incomplete) {
    return seen;
  }
  cv::Mat upsampled;
  cv::resize(grey, upsampled, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
  const Observations more = FindMarkersAtScale(upsampled, 2.0, dictionary, spec);
  for (size_t i = 0; i < more.ids.size(); ++i) {
    if (std::find(seen.ids.begin(), seen.ids.end(), more.ids[i]) != seen.ids.end()) continue;
    seen.ids.push_back(more.ids[i]);
    seen.corners.push_back(more.corners[i]);
  }
  return seen;
}

// cv::cornerSubPix with a window of 0.75 cell (at least 2 px, at most
// options.max_refine_half_window_px), so that it sees the marker's outer
// edges and not its inner bits.
void RefineWithCornerSubPix(const cv::Mat& grey, int cells_per_side, const DetectorOptions& options,
                            std::array<cv::Point2f, 4>* quad) {
  const cv::TermCriteria criteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.005);
  double shortest_px = 1e9;
  for (int k = 0; k < 4; ++k) {
    shortest_px = std::min(shortest_px, cv::norm((*quad)[k] - (*quad)[(k + 1) % 4]));
  }
  const int half = std::clamp(static_cast<int>(0.75 * shortest_px / cells_per_side), 2,
                              options.max_refine_half_window_px);
  std::vector<cv::Point2f> points(quad->begin(), quad->end());
  cv::cornerSubPix(grey, points, cv::Size(half, half), cv::Size(-1, -1), criteria);
  std::copy(points.begin(), points.end(), quad->begin());
}

// Refines every marker's corners from its outer edges (edge_refinement.h),
// falling back to cv::cornerSubPix for markers whose edges are not all clear.
void RefineCorners(const cv::Mat& grey, const CameraIntrinsics& intrinsics, int cells_per_side,
                   const DetectorOptions& options, Observations* seen) {
  const cv::Mat linear = internal::LinearGrey(grey);
  for (std::array<cv::Point2f, 4>& quad : seen->corners) {
    if (!internal::RefineCornersFromEdges(linear, intrinsics, cells_per_side, &quad)) {
      RefineWithCornerSubPix(grey, cells_per_side, options, &quad);
    }
  }
}

Correspondences Correspond(const BoardSpec& spec, const Observations& seen) {
  const std::vector<BoardMarker> markers = BoardMarkers(spec);
  const Eigen::Matrix3d cv_from_board = BoardFromOpenCvBoardRotation().transpose();
  Correspondences pairs;
  for (size_t i = 0; i < seen.ids.size(); ++i) {
    const BoardMarker& marker = markers[seen.ids[i] - spec.first_marker_id];
    for (int k = 0; k < 4; ++k) {
      // Board points have y = 0, so in OpenCV's board axes they have z = 0.
      const Eigen::Vector3d p = cv_from_board * marker.corners_in_board[k];
      pairs.object_points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), 0.0f);
      pairs.image_points.push_back(seen.corners[i][k]);
    }
  }
  return pairs;
}

void Score(const Correspondences& pairs, const CvCamera& camera, PoseFit* fit) {
  std::vector<cv::Point2f> projected;
  cv::projectPoints(pairs.object_points, fit->rvec, fit->tvec, camera.camera_matrix,
                    camera.distortion, projected);
  double sum_sq = 0.0;
  fit->marker_error_px.assign(projected.size() / 4, 0.0);
  for (size_t i = 0; i < projected.size(); ++i) {
    const double error = cv::norm(projected[i] - pairs.image_points[i]);
    sum_sq += error * error;
    fit->marker_error_px[i / 4] += 0.25 * error;
  }
  fit->rms_px = std::sqrt(sum_sq / std::max<size_t>(1, projected.size()));
}

// IPPE's better solution, refined by Levenberg-Marquardt.
PoseFit FitFresh(const Correspondences& pairs, const CvCamera& camera) {
  std::vector<cv::Mat> rvecs, tvecs;
  cv::solvePnPGeneric(pairs.object_points, pairs.image_points, camera.camera_matrix,
                      camera.distortion, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
  PoseFit best;  // rvec stays empty when IPPE finds no solution.
  best.rms_px = 1e300;
  for (size_t i = 0; i < rvecs.size(); ++i) {
    PoseFit fit;
    fit.rvec = rvecs[i].clone();
    fit.tvec = tvecs[i].clone();
    cv::solvePnPRefineLM(pairs.object_points, pairs.image_points, camera.camera_matrix,
                         camera.distortion, fit.rvec, fit.tvec);
    Score(pairs, camera, &fit);
    if (fit.rms_px < best.rms_px) best = fit;
  }
  return best;
}

PoseFit FitFromGuess(const Correspondences& pairs, const CvCamera& camera,
                     const Eigen::Isometry3d& camera_from_board) {
  Eigen::Matrix3d cam_from_cv = camera_from_board.linear() * BoardFromOpenCvBoardRotation();
  cv::Mat rotation;
  cv::eigen2cv(cam_from_cv, rotation);
  PoseFit fit;
  cv::Rodrigues(rotation, fit.rvec);
  cv::eigen2cv(Eigen::Vector3d(camera_from_board.translation()), fit.tvec);
  cv::solvePnPRefineLM(pairs.object_points, pairs.image_points, camera.camera_matrix,
                       camera.distortion, fit.rvec, fit.tvec);
  Score(pairs, camera, &fit);
  return fit;
}

Eigen::Isometry3d CameraFromBoard(const PoseFit& fit) {
  cv::Mat rotation;
  cv::Rodrigues(fit.rvec, rotation);
  Eigen::Matrix3d cam_from_cv;
  Eigen::Vector3d translation;
  cv::cv2eigen(rotation, cam_from_cv);
  cv::cv2eigen(fit.tvec, translation);
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
  // Our OpenCV board axes share the board origin (see Correspond).
  camera_from_board.linear() = cam_from_cv * BoardFromOpenCvBoardRotation().transpose();
  camera_from_board.translation() = translation;
  return camera_from_board;
}

PoseFit FitPose(const Correspondences& pairs, const CvCamera& camera,
                const Eigen::Isometry3d* guess) {
  PoseFit fresh = FitFresh(pairs, camera);
  if (guess == nullptr) return fresh;
  PoseFit near = FitFromGuess(pairs, camera, *guess);
  // Keep the guess's solution unless it is clearly worse (it then converged
  // to a wrong minimum, e.g. after a fast motion).
  return near.rms_px <= 1.2 * fresh.rms_px + 0.1 ? near : fresh;
}

// Drops the markers whose mean corner error exceeds the threshold, when enough
// remain. True when any were dropped.
bool DropOutliers(const PoseFit& fit, const DetectorOptions& options, Observations* seen) {
  Observations kept;
  for (size_t i = 0; i < seen->ids.size(); ++i) {
    if (fit.marker_error_px[i] > options.outlier_threshold_px) continue;
    kept.ids.push_back(seen->ids[i]);
    kept.corners.push_back(seen->corners[i]);
  }
  if (kept.ids.size() == seen->ids.size() ||
      static_cast<int>(kept.ids.size()) < options.min_markers) {
    return false;
  }
  *seen = std::move(kept);
  return true;
}

BoardDetection MakeDetection(const PoseFit& fit, const Observations& seen) {
  BoardDetection detection;
  detection.camera_from_board = CameraFromBoard(fit);
  detection.num_markers = static_cast<int>(seen.ids.size());
  detection.reprojection_rms_px = fit.rms_px;
  detection.marker_ids = seen.ids;
  for (const auto& quad : seen.corners) {
    for (const cv::Point2f& corner : quad) detection.corners_px.emplace_back(corner.x, corner.y);
  }
  return detection;
}

absl::Status PoseNotFound(const BoardSpec& spec, size_t markers, const PoseFit& fit,
                          const DetectorOptions& options) {
  return absl::NotFoundError(absl::StrCat("board ", FormatBoardSpec(spec), ": ", markers,
                                          " markers seen but the pose fits them with RMS ",
                                          fit.rms_px, " px > ", options.max_reprojection_rms_px));
}

// Detect after validation; may throw cv::Exception.
absl::StatusOr<BoardDetection> DetectValidated(const RgbImage& image,
                                               const CameraIntrinsics& intrinsics,
                                               const BoardSpec& spec,
                                               const DetectorOptions& options,
                                               const Eigen::Isometry3d* guess) {
  ASSIGN_OR_RETURN(cv::Ptr<cv::aruco::Dictionary> dictionary,
                   internal::GetArucoDictionary(spec.dictionary));
  const cv::Mat grey = ToGrey(image);
  Observations seen = FindMarkers(grey, dictionary, spec, options);
  if (static_cast<int>(seen.ids.size()) < options.min_markers) {
    return absl::NotFoundError(absl::StrCat("board ", FormatBoardSpec(spec), ": ", seen.ids.size(),
                                            " of its markers seen, need ", options.min_markers));
  }
  if (options.refine_corners) {
    RefineCorners(grey, intrinsics, dictionary->markerSize + 2, options, &seen);
  }
  const CvCamera camera = ToCvCamera(intrinsics);
  PoseFit fit = FitPose(Correspond(spec, seen), camera, guess);
  if (fit.rvec.empty()) return PoseNotFound(spec, seen.ids.size(), fit, options);
  if (DropOutliers(fit, options, &seen)) fit = FitPose(Correspond(spec, seen), camera, guess);
  if (fit.rvec.empty() || !(fit.rms_px <= options.max_reprojection_rms_px)) {
    return PoseNotFound(spec, seen.ids.size(), fit, options);
  }
  return MakeDetection(fit, seen);
}

absl::StatusOr<BoardDetection> Detect(const RgbImage& image, const CameraIntrinsics& intrinsics,
                                      const BoardSpec& spec, const DetectorOptions& options,
                                      const Eigen::Isometry3d* guess) {
  RETURN_IF_ERROR(ValidateInputs(image, intrinsics, spec, options));
  try {
    return DetectValidated(image, intrinsics, spec, options, guess);
  } catch (const cv::Exception& e) {
    // OpenCV reports what it cannot handle by throwing; an image must never
    // abort the process.
    return absl::InternalError(absl::StrCat("DetectBoard: OpenCV: ", e.what()));
  }
}

}  // namespace

absl::Status DetectorOptions::Validate() const {
  if (min_markers < 1 || max_refine_half_window_px < 2 || !(outlier_threshold_px > 0.0) ||
      !(max_reprojection_rms_px > 0.0)) {
    return absl::InvalidArgumentError(
        "DetectorOptions: min_markers >= 1, max_refine_half_window_px >= 2 and positive "
        "thresholds required");
  }
  return absl::OkStatus();
}

absl::StatusOr<BoardDetection> DetectBoard(const RgbImage& image,
                                           const CameraIntrinsics& intrinsics,
                                           const BoardSpec& spec, const DetectorOptions& options) {
  return Detect(image, intrinsics, spec, options, nullptr);
}

absl::StatusOr<BoardDetection> DetectBoardNear(const RgbImage& image,
                                               const CameraIntrinsics& intrinsics,
                                               const BoardSpec& spec,
                                               const Eigen::Isometry3d& camera_from_board_guess,
                                               const DetectorOptions& options) {
  return Detect(image, intrinsics, spec, options, &camera_from_board_guess);
}

absl::StatusOr<BoardTracker> BoardTracker::Create(const BoardSpec& spec,
                                                  const CameraIntrinsics& intrinsics,
                                                  const DetectorOptions& options) {
  RETURN_IF_ERROR(spec.Validate());
  RETURN_IF_ERROR(intrinsics.Validate());
  RETURN_IF_ERROR(options.Validate());
  return BoardTracker(spec, intrinsics, options);
}

absl::StatusOr<BoardDetection> BoardTracker::Track(const RgbImage& image) {
  absl::StatusOr<BoardDetection> detection =
      last_camera_from_board_
          ? DetectBoardNear(image, intrinsics_, spec_, *last_camera_from_board_, options_)
          : DetectBoard(image, intrinsics_, spec_, options_);
  if (detection.ok()) {
    last_camera_from_board_ = detection->camera_from_board;
  } else if (absl::IsNotFound(detection.status())) {
    last_camera_from_board_.reset();
  }
  return detection;
}

}  // namespace reenact::board
