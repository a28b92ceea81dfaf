// Per-sensor processing in reenactd, between the backend and the sync group:
// depth-to-colour registration where the source lacks it, actor segmentation
// where the source gives no mask, and encoding of raw pixels (depth to RVL,
// colour to JPEG). The source's skeleton is passed through.
//
// Policy, frame by frame:
// - Raw frames (CapturedFrame.depth_mm set; the hardware backends):
//   * Registration runs when the mode is kAuto or kOn, the sensor does not
//     register by itself (SensorInfo.provides_registration false), its
//     backend is not "playback", and its calibration has valid depth and
//     colour intrinsics. Depth is then re-expressed in the colour camera
//     (common/geometry/registration.h, triangle fill with a z-buffer) on a
//     grid of the colour camera scaled to registered_width/height_px (by
//     default the colour size divided by the smallest integer that brings its
//     width to max(640, depth width) or less: 640x480 for Kinect v1, 640x360
//     for Kinect v2 colour). calibration() then has depth intrinsics equal to
//     the colour intrinsics at that size, color_from_depth the identity and
//     world_from_depth = world_from_colour. The colour image itself is not
//     resampled. kOn fails at Create when registration is impossible.
//   * Depth is encoded losslessly ("rvl" or "rvl+zstd"), colour as JPEG at
//     jpeg_quality; the raw images are released.
// - Encoded frames (playback: frame.depth already holds RVL bytes): passed
//   through unchanged, registration included (calibration() is the source's).
//   An encoded frame from a sensor whose raw frames are registered is
//   rejected (InvalidArgument), since it would not follow calibration().
// - Segmentation (capture_daemon/processing/actor_segmenter.h) runs when the
//   mode is kOn, or kAuto and the frame carries no mask; encoded depth is
//   decoded for it. The mask is in the pixels of the output depth ("rle",
//   body index 1), empty during the first background_seconds. kOn replaces a
//   source's mask. Segmentation needs valid depth intrinsics; without them
//   kAuto skips it and kOn fails at Create.
// - Tracking (common/tracking/body_tracker.h) runs when the mode is kOn, or
//   kAuto and the frame carries no skeleton: the people in the output depth
//   (the frame's mask marks them when there is one, else the tracker
//   segments by itself) become Skeletons with source kTrackerSource, their
//   body_index the mask's value and person_id stable across frames. kOn
//   replaces a source's skeletons. A frame with nobody gets no skeleton. The
//   tracker's forest is loaded at Create: a missing or corrupt forest fails
//   Create under kOn, and under kAuto for a sensor that gives no skeleton of
//   its own; tracking needs valid depth intrinsics like segmentation.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "capture_daemon/processing/actor_segmenter.h"
#include "capture_daemon/sensors/sensor.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/tracking_proto.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::capture {

// v1::Skeleton.source of the skeletons the daemon's tracker produces.
using tracking::kTrackerSource;

struct ProcessingOptions {
  enum class Mode { kAuto, kOn, kOff };
  // kAuto: register when the source delivers raw depth and colour that are
  // not registered (SensorInfo.provides_registration false).
  Mode registration = Mode::kAuto;
  // kAuto: segment when the source gives no mask.
  Mode segmentation = Mode::kAuto;
  // Length of the start of the stream that builds the background depth model.
  double background_seconds = 1.0;
  // JPEG quality for raw colour, 1..100.
  int jpeg_quality = 90;
  // Encoding of raw depth: "rvl" or "rvl+zstd".
  std::string depth_encoding = "rvl";
  // Size of the registered depth grid (both 0: automatic, see the file
  // comment; else both positive).
  int registered_width_px = 0;
  int registered_height_px = 0;
  // Tuning of the segmentation; its background_seconds is replaced by the
  // field above and its noise_model by the sensor's model.
  SegmenterOptions segmentation_tuning;
  // kAuto: track skeletons when the source gives none.
  Mode tracking = Mode::kAuto;
  // The tracker (its forest_path empty: the shipped forest).
  tracking::BodyTrackerOptions tracker;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Figures of one processor since it was created.
struct ProcessingStats {
  int64_t frames = 0;          // Frames processed successfully.
  int64_t registered = 0;      // Frames whose depth was registered.
  int64_t segmented = 0;       // Frames that got a mask from segmentation.
  int64_t tracked = 0;         // Frames that went through the tracker.
  int64_t tracked_people = 0;  // Skeletons the tracker produced.
  // Frames without a mask that got the tracker's own segmentation of the
  // people it found as their mask (body index k: the skeleton's body_index).
  int64_t tracker_masks = 0;
  double tracking_ms = 0.0;     // Wall time spent in the tracker.
  int64_t tracking_errors = 0;  // Frames the tracker refused (they stream without skeleton).
  std::string last_tracking_error;
  double total_ms = 0.0;  // Wall time spent in Process.
  double max_ms = 0.0;    // Longest Process call.
  bool background_ready = false;
  bool floor_found = false;
};

// One processor per sensor; not thread-safe (call Process from one thread).
class FrameProcessor {
 public:
  // `info` of the sensor whose frames this processor will see.
  static absl::StatusOr<std::unique_ptr<FrameProcessor>> Create(const v1::SensorInfo& info,
                                                                const ProcessingOptions& options);
  virtual ~FrameProcessor() = default;

  // Completes `frame` in place: afterwards frame.frame holds encoded depth,
  // colour when there is any, the mask when segmentation ran or the source
  // gave one, and the source's skeletons; the raw images are released.
  // InvalidArgument for a frame that does not fit the sensor (sizes, ids).
  virtual absl::Status Process(CapturedFrame& frame) = 0;

  // The calibration the processed frames follow (registration makes the
  // depth camera coincide with the colour camera).
  virtual const v1::SensorCalibration& calibration() const = 0;

  // Figures since Create.
  virtual ProcessingStats stats() const { return {}; }
};

}  // namespace reenact::capture
