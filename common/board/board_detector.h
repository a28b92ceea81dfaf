// Finds a board (board_spec.h) in a colour image and measures the pose of the
// camera against it: camera_from_board, the C of thesis Eq. 3.12, both for the
// capture sensors (C_n) and for the AR viewer's camera (C*).
//
// Method: ArUco marker detection (Garrido-Jurado et al., "Automatic generation
// and detection of highly reliable fiducial markers under occlusion", Pattern
// Recognition 47(6), 2014) through OpenCV; each marker's corners are then
// refined to subpixel accuracy as the intersections of lines fitted to its
// four outer edges (edge_refinement.h explains why not cv::cornerSubPix,
// which remains the fallback); the pose comes from IPPE (Collins and Bartoli,
// "Infinitesimal Plane-based Pose Estimation", IJCV 2014) over all corners of
// the board, or from the previous pose when tracking, then Levenberg-Marquardt
// on the reprojection error with the camera's Brown-Conrady distortion
// (common/geometry/camera.h).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/board/board_spec.h"
#include "common/geometry/camera.h"

namespace reenact::board {

// Options of DetectBoard and BoardTracker.
struct DetectorOptions {
  // Fewest board markers (4 corners each) that make a pose.
  int min_markers = 1;
  // When some of the board's markers are not found, search again in the image
  // upsampled 2x: finds markers down to about 2 px per cell (e.g. a Kinect
  // seeing the floor board from 3 m), at up to 4x the detection time on such
  // frames.
  bool upsample_when_incomplete = true;
  // Refine marker corners to subpixel accuracy (from the marker's edges, else
  // cv::cornerSubPix); when false, the detector's pixel-level corners are used.
  bool refine_corners = true;
  // Largest half-width of the cv::cornerSubPix window of the fallback, pixels;
  // the window is otherwise 0.75 of a marker cell, so that it sees only the
  // marker's outer edges.
  int max_refine_half_window_px = 8;
  // Markers whose mean corner reprojection error exceeds this after the first
  // fit are dropped and the pose is fitted again, pixels.
  double outlier_threshold_px = 3.0;
  // A pose whose reprojection RMS exceeds this is rejected (NotFound), pixels.
  double max_reprojection_rms_px = 2.0;

  // InvalidArgument for non-positive values.
  absl::Status Validate() const;
};

// A board found in an image.
struct BoardDetection {
  // Maps board-frame points (metres) to the camera frame (OpenCV axes, metres).
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
  int num_markers = 0;               // Board markers used for the pose.
  double reprojection_rms_px = 0.0;  // RMS distance of the used corners to their projections.
  std::vector<int> marker_ids;       // Ids of the used markers.
  // The refined image corners of the used markers, 4 per marker in
  // BoardMarker order, pixels (origin at the centre of the top-left pixel).
  std::vector<Eigen::Vector2d> corners_px;
};

// Finds `spec` in `image` (sRGB) seen by a camera with `intrinsics` (the same
// size as the image; distortion is taken into account). NotFound when fewer
// than options.min_markers markers of the board are seen or the pose does not
// fit them; InvalidArgument for an empty or inconsistent image, invalid
// intrinsics, spec or options, or a size mismatch.
absl::StatusOr<BoardDetection> DetectBoard(const RgbImage& image,
                                           const CameraIntrinsics& intrinsics,
                                           const BoardSpec& spec,
                                           const DetectorOptions& options = {});

// The same, starting the pose fit from `camera_from_board_guess` (e.g. the
// previous video frame). The guess resolves the two-fold ambiguity of a plane
// seen from far away; when the fit from the guess is worse than a fresh IPPE
// fit, the fresh one wins.
absl::StatusOr<BoardDetection> DetectBoardNear(const RgbImage& image,
                                               const CameraIntrinsics& intrinsics,
                                               const BoardSpec& spec,
                                               const Eigen::Isometry3d& camera_from_board_guess,
                                               const DetectorOptions& options = {});

// Follows a board through a video: each frame starts from the last pose found.
class BoardTracker {
 public:
  // InvalidArgument for an invalid spec, intrinsics or options.
  static absl::StatusOr<BoardTracker> Create(const BoardSpec& spec,
                                             const CameraIntrinsics& intrinsics,
                                             const DetectorOptions& options = {});

  // Finds the board in the next frame; errors as DetectBoard. A frame without
  // the board (NotFound) forgets the last pose.
  absl::StatusOr<BoardDetection> Track(const RgbImage& image);

  // Forgets the last pose (e.g. after a cut).
  void Reset() { last_camera_from_board_.reset(); }

  const std::optional<Eigen::Isometry3d>& last_camera_from_board() const {
    return last_camera_from_board_;
  }

 private:
  BoardTracker(const BoardSpec& spec, const CameraIntrinsics& intrinsics,
               const DetectorOptions& options)
      : spec_(spec), intrinsics_(intrinsics), options_(options) {}

  BoardSpec spec_;
  CameraIntrinsics intrinsics_;
  DetectorOptions options_;
  std::optional<Eigen::Isometry3d> last_camera_from_board_;
};

}  // namespace reenact::board
