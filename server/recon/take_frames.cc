#include "server/recon/take_frames.h"

#include <turbojpeg.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/depth_codec.h"
#include "common/io/mask_codec.h"
#include "common/io/take_convert.h"
#include "common/tracking/skeleton_fusion.h"

namespace reenact::recon {

JointArray MissingJoints() {
  JointArray joints;
  joints.fill(Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  return joints;
}

bool IsJointValid(const Eigen::Vector3d& joint) { return joint.allFinite(); }

absl::Status TakeFramesOptions::Validate() const {
  if (num_threads < 0) return absl::InvalidArgumentError("num_threads must be >= 0");
  if (max_instants < 0) return absl::InvalidArgumentError("max_instants must be >= 0");
  return absl::OkStatus();
}

namespace {

bool Tracked(JointTrackingState state) {
  return state == JointTrackingState::kTracked || state == JointTrackingState::kUnspecified;
}

// Picks the skeleton with the most tracked joints and fills the view's
// skeleton fields (joints not tracked or inferred stay NaN there) and
// `fusion_input`, the sensor's joints for the fusion (inferred ones
// included, with their state and confidence).
void SetSkeleton(const std::vector<Skeleton>& skeletons, const TakeSensor& sensor, SensorView* view,
                 std::optional<tracking::SensorSkeleton>* fusion_input) {
  const Skeleton* best = nullptr;
  int best_count = -1;
  for (const Skeleton& s : skeletons) {
    int count = 0;
    for (const SkeletonJoint& j : s.joints) count += Tracked(j.state) ? 1 : 0;
    if (count > best_count) {
      best = &s;
      best_count = count;
    }
  }
  fusion_input->reset();
  if (best == nullptr) return;
  view->has_skeleton = true;
  view->body_index = best->body_index;
  tracking::SensorSkeleton input;
  input.sensor_id = sensor.sensor_id;
  input.world_from_camera = sensor.world_from_depth;
  for (const SkeletonJoint& j : best->joints) {
    const auto id = body::KinectV2JointFromName(j.name);
    if (!id || j.state == JointTrackingState::kNotTracked) continue;
    const Eigen::Vector3d& p = j.position_in_depth_m;
    if (!p.allFinite()) continue;
    const int index = body::Index(*id);
    tracking::TrackedJoint& joint = input.joints[index];
    joint.position_in_camera_m = p;
    // Device SDKs give no confidence (0): full confidence in their state.
    const float confidence = j.confidence;
    joint.confidence = confidence > 0.0f && confidence <= 1.0f ? confidence : 1.0;
    if (Tracked(j.state)) {
      joint.state = tracking::JointState::kTracked;
      view->joints_in_depth_m[index] = p;
      view->joints_in_world_m[index] = sensor.world_from_depth * p;
      ++view->tracked_joint_count;
    } else {
      joint.state = tracking::JointState::kInferred;
    }
  }
  *fusion_input = std::move(input);
}

// The instant's world skeleton from its sensors' skeletons
// (tracking::FuseSkeletons: confidence-weighted robust mean, left/right swaps
// fixed, lost limbs down-weighted, the previous instant carried by
// `fusion`). Inferred joints count only when `use_inferred`.
void FuseSkeleton(std::vector<tracking::SensorSkeleton> inputs, bool use_inferred,
                  tracking::SequentialSkeletonFusion* fusion, Instant* instant) {
  if (inputs.empty()) return;
  if (!use_inferred) {
    for (tracking::SensorSkeleton& input : inputs) {
      for (tracking::TrackedJoint& joint : input.joints) {
        if (joint.state == tracking::JointState::kInferred) {
          joint.state = tracking::JointState::kNotTracked;
        }
      }
    }
  }
  absl::StatusOr<tracking::SkeletonFusionSummary> fused = fusion->Fuse(inputs, instant->stamp_ns);
  if (!fused.ok()) return;  // More sensors than the fusion takes: no skeleton.
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const tracking::FusedJoint& joint = fused->skeleton.joints[j];
    if (joint.state == tracking::JointState::kNotTracked) continue;
    instant->joints_in_world_m[j] = joint.position_in_world_m;
    instant->valid = true;
  }
}

bool IsRigidFinite(const Rigid3d& t) {
  return t.rotation.coeffs().allFinite() && t.translation.allFinite() &&
         std::abs(t.rotation.norm() - 1.0) < 1e-6;
}

}  // namespace

// Groups a recording's frames into a TakeFrames' instants, or appends a live
// take's FrameSets (friend of TakeFrames).
class TakeFramesBuilder {
 public:
  explicit TakeFramesBuilder(const TakeFramesOptions& options) : options_(options) {}

  absl::StatusOr<std::unique_ptr<TakeFrames>> FromRecording(RecordedTake take,
                                                            const std::string& path) {
    frames_.reset(new TakeFrames());
    frames_->path_ = path;
    frames_->info_ = std::move(take.info);
    RETURN_IF_ERROR(AddSensors(take.sensors, path));
    for (SensorFrame& frame : take.frames) {
      const int s = frames_->SensorIndex(frame.sensor_id);
      if (s < 0) continue;
      const int64_t index = frame.frame_index;
      raw_[s][index] = std::move(frame);
    }
    take.frames.clear();
    if (!take.frame_sets.empty()) {
      GroupByFrameSets(std::move(take.frame_sets));
      frames_->grouped_by_frame_sets_ = true;
    } else {
      GroupByFrameIndex();
    }
    if (frames_->instants_.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": the take has no depth frames"));
    }
    Finish();
    return std::move(frames_);
  }

  // A live take: calibrations now, FrameSets through Append.
  absl::StatusOr<std::unique_ptr<TakeFrames>> CreateLive(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors) {
    frames_.reset(new TakeFrames());
    frames_->path_ = "(live)";
    frames_->info_ = info;
    RETURN_IF_ERROR(AddSensors(sensors, "live take"));
    frames_->fps_ = info.fps > 0 ? info.fps : 30.0;
    frames_->pool_ = std::make_unique<ThreadPool>(NumThreads());
    frames_->grouped_by_frame_sets_ = true;
    return std::move(frames_);
  }

  // Appends `set` to `frames` as its next instant.
  void Append(FrameSet set, TakeFrames* frames) {
    frames_.reset(frames);  // Borrowed for MakeView; released below.
    Instant instant;
    instant.views.resize(frames->sensors_.size());
    instant.stamp_ns = set.stamp_ns;
    std::vector<tracking::SensorSkeleton> skeletons;
    for (SensorFrame& frame : set.frames) {
      const int s = frames->SensorIndex(frame.sensor_id);
      if (s < 0 || !frame.depth) continue;
      std::optional<tracking::SensorSkeleton> skeleton;
      instant.views[s] = MakeView(s, frame, &skeleton);
      if (skeleton) skeletons.push_back(*std::move(skeleton));
    }
    FuseSkeleton(std::move(skeletons), options_.use_inferred_joints, &fusion_, &instant);
    frames->instants_.push_back(std::move(instant));
    (void)frames_.release();
  }

 private:
  int NumThreads() const {
    if (options_.num_threads > 0) return options_.num_threads;
    return std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 8);
  }

  // Checks the calibrations and makes them TakeSensors (`where` names the
  // source in errors).
  absl::Status AddSensors(const std::vector<SensorCalibration>& calibrations,
                          const std::string& where) {
    for (const SensorCalibration& calibration : calibrations) {
      const std::string what = absl::StrCat(where, ": sensor ", calibration.sensor_id);
      if (frames_->SensorIndex(calibration.sensor_id) >= 0) {
        return absl::InvalidArgumentError(absl::StrCat(what, ": calibrated twice"));
      }
      TakeSensor sensor;
      sensor.sensor_id = calibration.sensor_id;
      sensor.calibration = calibration;
      if (absl::Status status = calibration.depth_intrinsics.Validate(); !status.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(what, ": bad depth intrinsics: ", status.message()));
      }
      sensor.depth_intrinsics = calibration.depth_intrinsics;
      if (!IsRigidFinite(calibration.world_from_depth)) {
        return absl::InvalidArgumentError(
            absl::StrCat(what, ": world_from_depth is not a finite rigid transform"));
      }
      sensor.world_from_depth = calibration.world_from_depth;
      // Colour is optional: a sensor without usable colour calibration keeps
      // its depth, and its colour frames are dropped.
      color_ok_.push_back(calibration.color_intrinsics.Validate().ok() &&
                          IsRigidFinite(calibration.color_from_depth));
      if (color_ok_.back()) {
        sensor.color_intrinsics = calibration.color_intrinsics;
        sensor.color_from_depth = calibration.color_from_depth;
      }
      if (calibration.depth_scale_m_per_unit > 0) {
        sensor.depth_scale_m_per_unit = calibration.depth_scale_m_per_unit;
      }
      frames_->sensors_.push_back(std::move(sensor));
    }
    if (frames_->sensors_.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, ": the take has no sensor calibration"));
    }
    raw_.resize(frames_->sensors_.size());
    return absl::OkStatus();
  }

  // Moves one frame (with depth) into a view.
  SensorView MakeView(int sensor, SensorFrame& f,
                      std::optional<tracking::SensorSkeleton>* skeleton) {
    SensorView view;
    view.present = true;
    view.frame_index = f.frame_index;
    view.host_stamp_ns = f.depth->host_stamp_ns;
    view.depth_encoding = std::move(f.depth->encoding);
    view.depth_data = std::move(f.depth->data);
    if (f.mask) {
      view.mask_encoding = std::move(f.mask->encoding);
      view.mask_data = std::move(f.mask->data);
    }
    if (f.color && options_.load_color && color_ok_[sensor]) {
      view.color_jpeg = std::move(f.color->data);
      view.color_host_stamp_ns = f.color->host_stamp_ns;
      view.has_color = true;
    }
    SetSkeleton(f.skeletons, frames_->sensors_[sensor], &view, skeleton);
    return view;
  }

  // Appends an instant made of `chosen` (frame_index per sensor, or absent).
  void AddInstant(const std::vector<std::optional<int64_t>>& chosen,
                  std::optional<int64_t> stamp_ns) {
    const int num_sensors = static_cast<int>(raw_.size());
    Instant instant;
    instant.views.resize(num_sensors);
    std::vector<tracking::SensorSkeleton> skeletons;
    double stamp_sum = 0;
    int stamp_n = 0;
    for (int s = 0; s < num_sensors; ++s) {
      if (!chosen[s]) continue;
      auto it = raw_[s].find(*chosen[s]);
      if (it == raw_[s].end() || !it->second.depth) continue;
      std::optional<tracking::SensorSkeleton> skeleton;
      instant.views[s] = MakeView(s, it->second, &skeleton);
      if (skeleton) skeletons.push_back(*std::move(skeleton));
      stamp_sum += static_cast<double>(instant.views[s].host_stamp_ns);
      ++stamp_n;
    }
    if (stamp_n == 0) return;
    instant.stamp_ns =
        stamp_ns ? *stamp_ns : static_cast<int64_t>(std::llround(stamp_sum / stamp_n));
    FuseSkeleton(std::move(skeletons), options_.use_inferred_joints, &fusion_, &instant);
    frames_->instants_.push_back(std::move(instant));
  }

  void GroupByFrameIndex() {
    std::vector<int64_t> indices;
    for (const auto& frames : raw_) {
      for (const auto& [index, f] : frames) {
        if (f.depth) indices.push_back(index);
      }
    }
    std::sort(indices.begin(), indices.end());
    indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
    for (int64_t index : indices) {
      std::vector<std::optional<int64_t>> chosen(raw_.size(), index);
      AddInstant(chosen, std::nullopt);
    }
  }

  // Each record is an instant; per listed sensor the frame it names
  // (FrameSetRecord.frame_indices) or, in takes without them, the nearest
  // unused depth frame within skew + half a frame period of the record's
  // stamp.
  void GroupByFrameSets(std::vector<FrameSetRecord> records) {
    std::sort(records.begin(), records.end(),
              [](const auto& a, const auto& b) { return a.sequence < b.sequence; });
    const double fps = frames_->info_.fps > 0 ? frames_->info_.fps : 30.0;
    const int64_t half_period_ns = static_cast<int64_t>(0.5e9 / fps);
    // Per sensor: (host stamp, frame_index) sorted by stamp, and a cursor.
    std::vector<std::vector<std::pair<int64_t, int64_t>>> by_stamp(raw_.size());
    for (size_t s = 0; s < raw_.size(); ++s) {
      for (const auto& [index, f] : raw_[s]) {
        if (f.depth) by_stamp[s].push_back({f.depth->host_stamp_ns, index});
      }
      std::sort(by_stamp[s].begin(), by_stamp[s].end());
    }
    std::vector<size_t> cursor(raw_.size(), 0);
    for (const FrameSetRecord& record : records) {
      std::vector<std::optional<int64_t>> chosen(raw_.size());
      const int64_t tolerance_ns = std::max<int64_t>(record.skew_ns, 0) + half_period_ns;
      const bool indexed = record.frame_indices.size() == record.sensor_ids.size();
      for (size_t k = 0; k < record.sensor_ids.size(); ++k) {
        const int s = frames_->SensorIndex(record.sensor_ids[k]);
        if (s < 0) continue;
        if (indexed) {
          // The clock-corrected set stamp may lie more than half a period
          // from a frame's host stamp (irregular device clocks); the index
          // names the frame itself.
          const auto it = raw_[s].find(record.frame_indices[k]);
          if (it != raw_[s].end() && it->second.depth) chosen[s] = it->first;
          continue;
        }
        const auto& list = by_stamp[s];
        size_t best = list.size();
        int64_t best_dt = std::numeric_limits<int64_t>::max();
        for (size_t i = cursor[s]; i < list.size(); ++i) {
          const int64_t dt = std::llabs(list[i].first - record.stamp_ns);
          if (dt < best_dt) {
            best_dt = dt;
            best = i;
          } else if (list[i].first > record.stamp_ns) {
            break;
          }
        }
        if (best < list.size() && best_dt <= tolerance_ns) {
          chosen[s] = list[best].second;
          cursor[s] = best + 1;
        }
      }
      AddInstant(chosen, record.stamp_ns);
    }
  }

  void Finish() {
    auto& instants = frames_->instants_;
    std::stable_sort(instants.begin(), instants.end(),
                     [](const Instant& a, const Instant& b) { return a.stamp_ns < b.stamp_ns; });
    if (options_.max_instants > 0 && static_cast<int>(instants.size()) > options_.max_instants) {
      instants.resize(options_.max_instants);
    }
    double fps = frames_->info_.fps;
    if (!(fps > 0) && instants.size() >= 2) {
      std::vector<int64_t> steps;
      steps.reserve(instants.size() - 1);
      for (size_t i = 1; i < instants.size(); ++i) {
        steps.push_back(instants[i].stamp_ns - instants[i - 1].stamp_ns);
      }
      std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
      if (steps[steps.size() / 2] > 0) fps = 1e9 / static_cast<double>(steps[steps.size() / 2]);
    }
    frames_->fps_ = fps > 0 && std::isfinite(fps) ? fps : 30.0;
    frames_->pool_ = std::make_unique<ThreadPool>(NumThreads());
    raw_.clear();
  }

  TakeFramesOptions options_;
  tracking::SequentialSkeletonFusion fusion_;
  std::unique_ptr<TakeFrames> frames_;
  std::vector<bool> color_ok_;
  std::vector<std::map<int64_t, SensorFrame>> raw_;  // Per sensor, by frame_index.
};

absl::StatusOr<std::unique_ptr<TakeFrames>> TakeFrames::Load(const std::string& path,
                                                             const TakeFramesOptions& options,
                                                             const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  RecordedTakeOptions read;
  read.load_color = options.load_color;
  ASSIGN_OR_RETURN(RecordedTake take, ReadRecordedTake(path, read, progress));
  return FromRecording(std::move(take), options, path);
}

absl::StatusOr<std::unique_ptr<TakeFrames>> TakeFrames::FromRecording(
    RecordedTake take, const TakeFramesOptions& options, const std::string& path) {
  RETURN_IF_ERROR(options.Validate());
  TakeFramesBuilder builder(options);
  return builder.FromRecording(std::move(take), path);
}

TakeFrames::~TakeFrames() = default;

absl::StatusOr<std::unique_ptr<TakeFrames>> TakeFrames::CreateLive(
    const TakeInfo& info, const std::vector<SensorCalibration>& sensors,
    const TakeFramesOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  auto builder = std::make_unique<TakeFramesBuilder>(options);
  ASSIGN_OR_RETURN(std::unique_ptr<TakeFrames> frames, builder->CreateLive(info, sensors));
  frames->live_ = std::move(builder);
  return frames;
}

absl::Status TakeFrames::AppendFrameSet(FrameSet set) {
  if (live_ == nullptr) {
    return absl::FailedPreconditionError("AppendFrameSet on a take loaded from a file");
  }
  live_->Append(std::move(set), this);
  return absl::OkStatus();
}

void TakeFrames::ReleaseInstant(int instant) {
  if (instant < 0 || instant >= num_instants()) return;
  for (SensorView& view : instants_[instant].views) {
    view.present = false;
    std::string().swap(view.depth_data);
    std::string().swap(view.mask_data);
    std::string().swap(view.color_jpeg);
  }
}

int TakeFrames::SensorIndex(const std::string& sensor_id) const {
  for (size_t i = 0; i < sensors_.size(); ++i) {
    if (sensors_[i].sensor_id == sensor_id) return static_cast<int>(i);
  }
  return -1;
}

int TakeFrames::num_valid_instants() const {
  return static_cast<int>(
      std::count_if(instants_.begin(), instants_.end(), [](const Instant& i) { return i.valid; }));
}

double TakeFrames::duration_s() const {
  if (instants_.size() < 2) return 0.0;
  return static_cast<double>(instants_.back().stamp_ns - instants_.front().stamp_ns) * 1e-9;
}

namespace {

absl::Status CheckView(const TakeFrames& take, int instant, int sensor) {
  if (instant < 0 || instant >= take.num_instants() || sensor < 0 || sensor >= take.num_sensors()) {
    return absl::InvalidArgumentError(
        absl::StrCat("no view (instant ", instant, ", sensor ", sensor, ") in the take"));
  }
  if (!take.instant(instant).views[sensor].present) {
    return absl::InvalidArgumentError(absl::StrCat("sensor ", take.sensors()[sensor].sensor_id,
                                                   " has no frame at instant ", instant));
  }
  return absl::OkStatus();
}

std::string ViewName(const TakeFrames& take, int instant, int sensor) {
  return absl::StrCat(take.path(), ": sensor ", take.sensors()[sensor].sensor_id, " frame ",
                      take.instant(instant).views[sensor].frame_index);
}

}  // namespace

absl::StatusOr<DepthImageMm> TakeFrames::LoadDepth(int instant, int sensor) const {
  RETURN_IF_ERROR(CheckView(*this, instant, sensor));
  const SensorView& view = instants_[instant].views[sensor];
  auto depth = DecodeDepth(view.depth_data);
  if (!depth.ok()) {
    return absl::DataLossError(
        absl::StrCat(ViewName(*this, instant, sensor), ": depth: ", depth.status().message()));
  }
  const CameraIntrinsics& k = sensors_[sensor].depth_intrinsics;
  if (depth->width != k.width || depth->height != k.height) {
    return absl::DataLossError(absl::StrCat(ViewName(*this, instant, sensor), ": depth is ",
                                            depth->width, "x", depth->height,
                                            ", the calibration says ", k.width, "x", k.height));
  }
  return depth;
}

absl::StatusOr<MaskImage> TakeFrames::LoadActorMask(int instant, int sensor) const {
  ASSIGN_OR_RETURN(DepthImageMm depth, LoadDepth(instant, sensor));
  const SensorView& view = instants_[instant].views[sensor];
  MaskImage actor(depth.width, depth.height, 0);
  if (view.mask_data.empty()) {
    for (size_t i = 0; i < depth.data.size(); ++i) actor.data[i] = depth.data[i] > 0 ? 1 : 0;
    return actor;
  }
  auto decoded_mask = DecodeMask(view.mask_encoding == "rvl" ? "rvl" : "rle", view.mask_data);
  if (!decoded_mask.ok()) {
    return absl::DataLossError(absl::StrCat(ViewName(*this, instant, sensor),
                                            ": mask: ", decoded_mask.status().message()));
  }
  MaskImage mask = *std::move(decoded_mask);
  if (mask.width != depth.width || mask.height != depth.height) {
    return absl::DataLossError(absl::StrCat(ViewName(*this, instant, sensor), ": mask is ",
                                            mask.width, "x", mask.height, ", depth is ",
                                            depth.width, "x", depth.height));
  }
  bool body_in_mask = false;
  if (view.body_index > 0 && view.body_index < 256) {
    body_in_mask = std::find(mask.data.begin(), mask.data.end(),
                             static_cast<uint8_t>(view.body_index)) != mask.data.end();
  }
  for (size_t i = 0; i < mask.data.size(); ++i) {
    const bool is_actor = body_in_mask ? mask.data[i] == view.body_index : mask.data[i] > 0;
    actor.data[i] = is_actor && depth.data[i] > 0 ? 1 : 0;
  }
  return actor;
}

absl::StatusOr<DepthImageMm> TakeFrames::LoadActorDepth(int instant, int sensor) const {
  ASSIGN_OR_RETURN(DepthImageMm depth, LoadDepth(instant, sensor));
  ASSIGN_OR_RETURN(MaskImage actor, LoadActorMask(instant, sensor));
  for (size_t i = 0; i < depth.data.size(); ++i) {
    if (actor.data[i] == 0) depth.data[i] = 0;
  }
  return depth;
}

absl::StatusOr<RgbImage> TakeFrames::LoadColor(int instant, int sensor,
                                               int scale_denominator) const {
  RETURN_IF_ERROR(CheckView(*this, instant, sensor));
  if (scale_denominator != 1 && scale_denominator != 2 && scale_denominator != 4 &&
      scale_denominator != 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("colour scale denominator must be 1, 2, 4 or 8, not ", scale_denominator));
  }
  const SensorView& view = instants_[instant].views[sensor];
  if (view.color_jpeg.empty()) {
    return absl::NotFoundError(absl::StrCat(ViewName(*this, instant, sensor), ": no colour frame"));
  }
  const std::string what = absl::StrCat(ViewName(*this, instant, sensor), ": colour: ");
  tjhandle handle = tjInitDecompress();
  if (handle == nullptr) return absl::InternalError("tjInitDecompress failed");
  struct Closer {
    tjhandle h;
    ~Closer() { tjDestroy(h); }
  } closer{handle};
  int width = 0, height = 0, subsampling = 0, colorspace = 0;
  auto* bytes = reinterpret_cast<const unsigned char*>(view.color_jpeg.data());
  const auto size = static_cast<unsigned long>(view.color_jpeg.size());
  if (tjDecompressHeader3(handle, bytes, size, &width, &height, &subsampling, &colorspace) != 0) {
    return absl::DataLossError(absl::StrCat(what, tjGetErrorStr2(handle)));
  }
  const CameraIntrinsics& k = sensors_[sensor].color_intrinsics;
  if (width != k.width || height != k.height) {
    return absl::DataLossError(absl::StrCat(what, "image is ", width, "x", height,
                                            ", the calibration says ", k.width, "x", k.height));
  }
  const tjscalingfactor factor{1, scale_denominator};
  RgbImage image(TJSCALED(width, factor), TJSCALED(height, factor));
  if (tjDecompress2(handle, bytes, size, image.data.data(), image.width, 0, image.height, TJPF_RGB,
                    TJFLAG_FASTDCT) != 0) {
    return absl::DataLossError(absl::StrCat(what, tjGetErrorStr2(handle)));
  }
  return image;
}

absl::StatusOr<CameraIntrinsics> TakeFrames::ColorIntrinsicsForImage(int sensor,
                                                                     const RgbImage& image) const {
  if (sensor < 0 || sensor >= num_sensors()) {
    return absl::InvalidArgumentError(absl::StrCat("no sensor ", sensor));
  }
  return ScaledIntrinsics(sensors_[sensor].color_intrinsics, image.width, image.height);
}

absl::Status TakeFrames::ParallelForViews(
    const std::function<absl::Status(int instant, int sensor)>& fn) const {
  std::vector<std::pair<int, int>> views;
  for (int i = 0; i < num_instants(); ++i) {
    for (int s = 0; s < num_sensors(); ++s) {
      if (instants_[i].views[s].present) views.push_back({i, s});
    }
  }
  std::mutex mu;
  absl::Status first = absl::OkStatus();
  pool_->ParallelFor(0, static_cast<int>(views.size()), [&](int k) {
    absl::Status status = fn(views[k].first, views[k].second);
    if (!status.ok()) {
      std::lock_guard<std::mutex> lock(mu);
      if (first.ok()) first = status;
    }
  });
  return first;
}

}  // namespace reenact::recon
