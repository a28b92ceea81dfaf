// Anchors a capture sensor on the printed board (common/board/board_spec.h)
// lying on the floor: the board is found in the sensor's colour frames and
// the board's frame becomes the world of the take (thesis 3.4.2, Eq. 3.12:
// C_n, the capture sensor's pose, is measured against the same board as the
// AR viewer's camera C*, so the teacher appears where they stood).
//
// A SensorAnchor watches one sensor's colour frames at the start of a take:
// the frame path offers each processed frame's JPEG and never waits (a frame
// offered while the worker's queue is full is skipped); a worker thread decodes it
// and runs board::DetectBoard with the sensor's colour intrinsics. Once
// `frames` detections are in (or `max_frames` were tried) it stops. The
// detections are combined: the lowest-RMS one is the reference, those within
// 2 degrees and 30 mm of it are averaged (mean translation, normalised mean
// of sign-aligned quaternions), which drops the rare flipped pose of a plane
// seen from far away.
#pragma once

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact::capture {

struct AnchorOptions {
  // Board spec text ("aruco:DICT_4X4_50:3x2:110:22"); empty: no anchoring.
  std::string board_spec;
  // Detections combined per sensor (1..100).
  int frames = 10;
  // Colour frames tried per sensor before giving up (>= frames).
  int max_frames = 60;
  // How long a take waits for its sensors' anchoring before its calibrations
  // go to the server without it, seconds (> 0).
  double timeout_s = 15.0;
  // Colour frames held for the worker (1..100); a frame offered while they
  // are all taken is skipped. The daemon holds `frames` for playback
  // sources, whose frames may come faster than real time, so that their
  // first frames are all searched.
  int queued_frames = 1;

  bool enabled() const { return !board_spec.empty(); }
  // InvalidArgument for a bad spec or counts.
  absl::Status Validate() const;
};

// What anchoring found for one sensor.
struct AnchorResult {
  // Maps colour-camera points (OpenCV axes, metres) to the board frame.
  Rigid3d board_from_colour;
  // Mean reprojection RMS of the combined detections, pixels.
  double rms_px = 0.0;
  int detections = 0;    // Detections combined.
  int frames_tried = 0;  // Colour frames searched.
};

// "board:" + the canonical spec text (board::FormatBoardSpec): the value of
// SensorCalibration.world_anchor. InvalidArgument for a bad spec.
absl::StatusOr<std::string> WorldAnchorName(const std::string& board_spec);

// `calibration` with world_from_depth = board_from_colour * colour_from_depth
// and the anchor recorded (world_anchor, world_anchor_rms_px).
absl::StatusOr<v1::SensorCalibration> AnchorCalibration(const v1::SensorCalibration& calibration,
                                                        const AnchorResult& anchor,
                                                        const std::string& world_anchor);

// Combines detections (board_from_colour, RMS px) as the file comment says.
// NotFound when `detections` is empty.
absl::StatusOr<AnchorResult> CombineDetections(
    const std::vector<std::pair<Rigid3d, double>>& detections);

// Finds the board in one sensor's colour frames on a worker thread.
class SensorAnchor {
 public:
  // InvalidArgument for bad options or a calibration without valid colour
  // intrinsics.
  static absl::StatusOr<std::unique_ptr<SensorAnchor>> Create(
      const AnchorOptions& options, const v1::SensorCalibration& calibration);
  ~SensorAnchor();

  // Offers one colour frame ("jpeg"); returns at once. Ignored while the
  // worker's queue is full or once anchoring has finished.
  void Offer(const v1::ColorImage& color);
  // True once enough detections are in or max_frames were tried.
  bool finished() const;
  // Stops the search (after the frame in hand) and combines what was found.
  // NotFound, naming the frames tried and the last detector error, when the
  // board was never found.
  absl::StatusOr<AnchorResult> Finish();

 private:
  SensorAnchor(const AnchorOptions& options, const CameraIntrinsics& colour_intrinsics);
  void Work();
  void Detect(const std::string& jpeg);
  bool FinishedLocked() const;

  AnchorOptions options_;
  CameraIntrinsics colour_intrinsics_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::string> queue_;  // JPEGs waiting for the worker.
  bool busy_ = false;              // The worker is searching a frame.
  bool stop_ = false;
  int frames_tried_ = 0;
  std::vector<std::pair<Rigid3d, double>> detections_;
  std::string last_error_;
  std::thread worker_;
};

}  // namespace reenact::capture
