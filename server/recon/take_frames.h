// A take loaded for reconstruction: the sensors' calibrations, the take's
// instants (one frame per sensor, grouped), and per instant and sensor the
// encoded depth, actor mask, colour JPEG and skeleton, decoded on demand.
//
// Loading reads the MCAP file once and keeps the encoded streams in memory
// (depth RVL, mask RLE, colour JPEG: a few hundred kB per sensor frame; no
// ground truth), so later passes decode only what they need, in parallel
// through pool() if they like. Skeletons are decoded at load time: each
// sensor's skeleton is converted to the world frame (world_from_depth), and
// the instant's fused skeleton is the mean of the sensors' joints (thesis
// 3.3.1 stores S'_n, the skeleton in world coordinates; with several sensors
// we average them).
//
// Instants: when the take holds /ingest/frame_set records (takes the server
// ingested), each record is one instant, and for every sensor it lists the
// frame of that sensor nearest to the record's stamp is taken (each frame at
// most once). Otherwise frames are grouped by their frame_index across
// sensors (synthetic takes and recordings whose sensors start together).
// Instants are sorted by stamp.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/base/progress.h"
#include "common/base/thread_pool.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "common/model/sensor_calibration.h"
#include "common/model/take.h"

namespace reenact::recon {

// 25 Kinect v2 joints (body::KinectV2Joint order), metres; NaN where the
// joint is missing.
using JointArray = std::array<Eigen::Vector3d, body::kNumKinectV2Joints>;

// A JointArray of NaNs.
JointArray MissingJoints();
// True when every coordinate of `joint` is finite.
bool IsJointValid(const Eigen::Vector3d& joint);

// One sensor of the take: its calibration as stored, and the parts of it
// that the methods use, checked.
struct TakeSensor {
  std::string sensor_id;
  SensorCalibration calibration;      // As stored in the take.
  CameraIntrinsics depth_intrinsics;  // Pixels of the depth image.
  // Pixels of the full-size colour image. A sensor whose colour intrinsics
  // do not validate has none (zero size), and its colour frames are dropped.
  CameraIntrinsics color_intrinsics;
  Rigid3d world_from_depth;               // Depth camera -> world (metres).
  Rigid3d color_from_depth;               // Depth camera -> colour camera (metres).
  double depth_scale_m_per_unit = 0.001;  // The calibration's, when > 0.
};

// One sensor's frame at one instant, still encoded (decode through
// TakeFrames::Load*).
struct SensorView {
  bool present = false;        // False: the sensor has no frame at this instant.
  int64_t frame_index = -1;    // The sensor's own frame index.
  int64_t host_stamp_ns = 0;   // Of the depth frame (take timeline).
  std::string depth_encoding;  // DepthImage.encoding / .data.
  std::string depth_data;
  std::string mask_encoding;  // ActorMask.encoding / .data; empty data: no mask.
  std::string mask_data;
  std::string color_jpeg;  // ColorImage.data; empty: no colour frame (or no bytes).
  // The take has a colour frame here, even where its bytes were left out
  // (a take read with a selection, common/io/take_selection.h).
  bool has_color = false;
  int64_t color_host_stamp_ns = 0;
  // The skeleton of the actor (of several bodies, the one with the most
  // tracked joints), in the depth camera frame and in the world frame.
  // Joints that were not tracked (or inferred, see TakeFramesOptions) are NaN.
  bool has_skeleton = false;
  int body_index = 0;  // Skeleton.body_index (the mask value of this body).
  JointArray joints_in_depth_m = MissingJoints();
  JointArray joints_in_world_m = MissingJoints();
  int tracked_joint_count = 0;
};

// One instant of the take: the frames of every sensor there.
struct Instant {
  int64_t stamp_ns = 0;           // Take timeline (host clock).
  std::vector<SensorView> views;  // One per sensor, in TakeFrames::sensors() order.
  // The sensors' skeletons fused in the world frame (tracking::FuseSkeletons:
  // confidence-weighted robust mean with left/right swaps fixed); NaN where
  // no sensor has the joint.
  JointArray joints_in_world_m = MissingJoints();
  // False when no sensor has a skeleton at this instant (methods skip it or
  // mark its parts invalid).
  bool valid = false;
};

struct TakeFramesOptions {
  // Keep the colour JPEG bytes (texturing needs them).
  bool load_color = true;
  // Use INFERRED joints of a sensor when no sensor TRACKED the joint at that
  // instant (joints with an unspecified state count as tracked).
  bool use_inferred_joints = true;
  // Threads of pool(); 0: one per hardware thread (at most 8).
  int num_threads = 0;
  // Keep only the first `max_instants` instants (0: all).
  int max_instants = 0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

class TakeFramesBuilder;

class TakeFrames {
 public:
  // Reads the take at `path` (ReadRecordedTake, common/io/take_convert.h)
  // and groups it (FromRecording). NotFound when it does not exist;
  // InvalidArgument when it is not a take or has no sensor with depth;
  // DataLoss when a message is corrupt. `progress` gets stage "load" (items:
  // messages read); returning false cancels (Cancelled).
  static absl::StatusOr<std::unique_ptr<TakeFrames>> Load(const std::string& path,
                                                          const TakeFramesOptions& options = {},
                                                          const ProgressCallback& progress = {});

  // Groups a recording's frames into instants (see the top of this file);
  // the encoded bytes move into the views. `path` names the take in errors.
  // InvalidArgument for bad options, a sensor calibrated twice, depth
  // intrinsics that do not validate, a world_from_depth that is not a
  // finite rigid transform, or a take with no calibration or no depth
  // frame.
  static absl::StatusOr<std::unique_ptr<TakeFrames>> FromRecording(
      RecordedTake take, const TakeFramesOptions& options = {},
      const std::string& path = "(recording)");

  // A take that grows while it is recorded (live following): the
  // calibrations now, each FrameSet through AppendFrameSet as the next
  // instant (frames of unknown sensors skipped; the skeleton fused as in
  // Load). InvalidArgument for bad calibrations (as FromRecording) or
  // options.
  static absl::StatusOr<std::unique_ptr<TakeFrames>> CreateLive(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors,
      const TakeFramesOptions& options = {});
  // Appends an instant to a live take (FailedPrecondition for a loaded
  // one); its encoded bytes move into the views. Not thread-safe against
  // readers of instants().
  absl::Status AppendFrameSet(FrameSet set);
  // Drops the encoded frames of `instant` (its views become not present),
  // so a long live take keeps only what is still to be processed.
  void ReleaseInstant(int instant);
  ~TakeFrames();

  const std::string& path() const { return path_; }
  const TakeInfo& info() const { return info_; }
  // Frames per second: TakeInfo::fps, else from the instants' stamps, else 30.
  double fps() const { return fps_; }
  const std::vector<TakeSensor>& sensors() const { return sensors_; }
  int num_sensors() const { return static_cast<int>(sensors_.size()); }
  // Index of `sensor_id` in sensors(), or -1.
  int SensorIndex(const std::string& sensor_id) const;

  const std::vector<Instant>& instants() const { return instants_; }
  int num_instants() const { return static_cast<int>(instants_.size()); }
  const Instant& instant(int i) const { return instants_[i]; }
  int num_valid_instants() const;
  // Seconds from the first to the last instant.
  double duration_s() const;
  // True when instants came from /ingest/frame_set records.
  bool grouped_by_frame_sets() const { return grouped_by_frame_sets_; }

  // Decoders; thread-safe. InvalidArgument for indices out of range or a
  // view that is not present, NotFound when the stream is absent (no colour),
  // DataLoss for bytes that do not decode or sizes that disagree with the
  // calibration.
  //
  // Depth in millimetres, depth_intrinsics size.
  absl::StatusOr<DepthImageMm> LoadDepth(int instant, int sensor) const;
  // The actor in depth pixels: 1 actor, 0 not. When the view's skeleton has
  // a body index found in the mask, only that body; else any mask value > 0.
  // Pixels without depth are 0. Without a mask: every pixel with depth is 1.
  absl::StatusOr<MaskImage> LoadActorMask(int instant, int sensor) const;
  // Depth with every non-actor pixel set to 0.
  absl::StatusOr<DepthImageMm> LoadActorDepth(int instant, int sensor) const;
  // Colour (sRGB) decoded at 1/scale_denominator of the full size
  // (scale_denominator 1, 2, 4 or 8; libjpeg-turbo's DCT scaling, fast).
  // The intrinsics of the result: ColorIntrinsicsForImage.
  absl::StatusOr<RgbImage> LoadColor(int instant, int sensor, int scale_denominator = 1) const;
  // The sensor's colour intrinsics scaled to `image`'s size.
  absl::StatusOr<CameraIntrinsics> ColorIntrinsicsForImage(int sensor, const RgbImage& image) const;

  // A pool for parallel decoding and per-frame work (options.num_threads).
  ThreadPool& pool() const { return *pool_; }
  // Calls fn(instant, sensor) for every present view, in parallel on pool();
  // returns the first error (all calls finish first).
  absl::Status ParallelForViews(
      const std::function<absl::Status(int instant, int sensor)>& fn) const;

 private:
  TakeFrames() = default;
  friend class TakeFramesBuilder;

  std::string path_;
  TakeInfo info_;
  double fps_ = 30.0;
  std::vector<TakeSensor> sensors_;
  std::vector<Instant> instants_;
  bool grouped_by_frame_sets_ = false;
  std::unique_ptr<ThreadPool> pool_;
  std::unique_ptr<TakeFramesBuilder> live_;  // Live takes only.
};

}  // namespace reenact::recon
