// AR mode of reenact-viewer (thesis 3.4.2, "Reenactment stage"): the teacher
// drawn over a live camera image where they stood. The world is the printed
// board (common/board): the capture daemon anchored the take's sensors to it
// (SensorCalibration.world_anchor "board:SPEC", so the reenactment's world is
// the board's frame), and here the viewer camera's pose against the same
// board, C* = camera_from_board, is tracked in every video frame. Eq. 3.12,
// T*_b = C* C_n^-1 T_b,n, then reduces to drawing the reenactment's world
// with camera_from_world = C* (C_n^-1 T_b,n is the part's pose in the board's
// frame, which is what the reenactment stores).
//
// Departure: a reenactment whose sensors were not anchored to a board has no
// known place on it; it is put on the board with the actor's mean floor
// position (mean SpineBase, y = 0) at the board's centre, and the summary
// says so (anchored = false).
//
// The video comes from a file or a webcam (OpenCV's VideoCapture). The
// teacher's instant follows the video's clock: for a file, frame k shows the
// teacher at k / video_fps seconds (times the speed, looping); for a webcam,
// wall-clock time. Frames where the board is not found show the video alone.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "clients/view/reenactment_renderer.h"
#include "common/board/board_spec.h"
#include "common/model/reenactment.h"

namespace reenact::viewer {

struct ArOptions {
  // A video file, or "webcam:N" for camera N.
  std::string video;
  // Intrinsics of the video's camera (common/board/intrinsics_file.h); empty:
  // an ideal camera of `fov_deg` horizontal field of view.
  std::string intrinsics_file;
  double fov_deg = 65.0;
  // The board; empty: the one the reenactment's sensors were anchored to,
  // else the default board.
  std::string board_spec;
  double speed = 1.0;
  // Stop after this many video frames (0: the whole file; a webcam runs
  // until the window closes or run_seconds pass).
  int max_frames = 0;
  double run_seconds = 0.0;
  // Headless: write composited frames (frame_NNNNN.png), video.mp4 and
  // poses.csv into this folder; empty: show them in a window.
  std::string render_to;
  bool mp4 = true;
  bool png = true;
  view::TextureMode mode = view::TextureMode::kVdtm;

  absl::Status Validate() const;
};

struct ArSummary {
  int frames = 0;             // Video frames processed.
  int frames_with_board = 0;  // Of them, where the board was found.
  double mean_rms_px = 0.0;   // Mean reprojection RMS of the found boards.
  bool anchored = false;      // The reenactment's world is the board's frame.
  std::string board_spec;
  std::string poses_csv;  // Headless: per-frame camera_from_board.
  std::string mp4_path;
  std::string mp4_problem;
  double seconds = 0.0;
  double fps = 0.0;  // Frames processed per second (tracking + drawing).
};

// Runs AR mode. InvalidArgument for bad options, a bad board spec or
// intrinsics; NotFound when the video cannot be opened; Unavailable without
// GL (or a display, in window mode).
absl::StatusOr<ArSummary> RunAr(const Reenactment& data, const ArOptions& options);

// The board anchoring of a reenactment: the spec of "board:SPEC" when every
// sensor names the same board, else empty.
std::string AnchoredBoard(const Reenactment& data);

}  // namespace reenact::viewer
