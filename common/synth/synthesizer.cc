#include "common/synth/synthesizer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <filesystem>
#include <future>
#include <memory>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/thread_pool.h"
#include "common/base/time.h"
#include "common/board/board_image.h"
#include "common/board/board_spec.h"
#include "common/body/body_model.h"
#include "common/body/model_spec.h"
#include "common/body/retarget.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/render/intrinsics_camera.h"
#include "common/render/mesh_data.h"
#include "common/render/offscreen_renderer.h"
#include "common/synth/builtin_motions.h"
#include "common/synth/clothing.h"
#include "common/synth/scene.h"
#include "common/synth/sensor_rig.h"

namespace reenact::synth {
namespace {

constexpr int kActorLabel = 1;
constexpr char kSkeletonSource[] =
    "synthetic-sensor-skeleton (true joints seen by this sensor plus Kinect-like jitter; a "
    "stand-in for a vendor SDK tracker)";

// ---------------------------------------------------------------- the actor

absl::StatusOr<body::BodyModel> LoadBody(const std::string& spec) {
  if (!body::IsBodyModelSpec(spec)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--body: expected 'procedural' or 'makehuman:DIR', got '", spec, "'"));
  }
  return body::LoadBodyModelSpec(spec);
}

absl::StatusOr<body::Motion> LoadMotion(const SynthOptions& options) {
  if (absl::StartsWith(options.motion, "builtin:")) {
    // One frame more than the take needs, so its last instant is covered.
    return MakeBuiltinMotion(options.motion.substr(8), options.seconds + 1.0 / options.fps,
                             options.fps);
  }
  body::MotionReadOptions read_options;
  read_options.asf_path = options.asf_path;
  read_options.metres_per_unit = options.metres_per_unit;
  if (!options.joint_map_path.empty()) {
    ASSIGN_OR_RETURN(read_options.joint_map, body::ReadJointMap(options.joint_map_path));
  }
  return body::ReadMotion(options.motion, read_options);
}

absl::StatusOr<Eigen::VectorXd> MakeShape(const std::string& spec, const body::BodyModel& model,
                                          uint64_t seed) {
  Eigen::VectorXd shape = Eigen::VectorXd::Zero(model.num_shape_components());
  if (spec == "mean") return shape;
  if (spec == "random" || absl::StartsWith(spec, "random:")) {
    uint64_t shape_seed = seed;
    if (spec.size() > 7 && !absl::SimpleAtoi(spec.substr(7), &shape_seed)) {
      return absl::InvalidArgumentError(absl::StrCat("--shape: bad seed in '", spec, "'"));
    }
    std::mt19937_64 rng(shape_seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int k = 0; k < shape.size(); ++k) shape[k] = std::clamp(normal(rng), -2.0, 2.0);
    // MakeHuman's directions are whole macro targets: keep them gentle.
    if (model.name != "procedural") shape *= 0.3;
    return shape;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("--shape: expected 'mean', 'random' or 'random:SEED', got '", spec, "'"));
}

// The pose at time t_s (seconds from the first motion frame): slerp of the
// neighbouring frames' rotations, linear root translation.
body::BodyPose SamplePose(const body::RetargetedMotion& motion, double t_s) {
  const int n = static_cast<int>(motion.poses.size());
  const double position = std::clamp(t_s * motion.fps, 0.0, static_cast<double>(n - 1));
  const int i0 = static_cast<int>(std::floor(position));
  const int i1 = std::min(i0 + 1, n - 1);
  const double u = position - i0;
  body::BodyPose pose;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    pose.local_rotation[j] =
        motion.poses[i0].local_rotation[j].slerp(u, motion.poses[i1].local_rotation[j]);
  }
  pose.root_translation_m =
      (1 - u) * motion.poses[i0].root_translation_m + u * motion.poses[i1].root_translation_m;
  return pose;
}

// Moves the motion so that its mean floor position is the origin.
void CenterMotion(body::RetargetedMotion* motion, int used_frames) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  const int n = std::min<int>(used_frames, static_cast<int>(motion->poses.size()));
  for (int i = 0; i < n; ++i) mean += motion->poses[i].root_translation_m;
  mean /= std::max(n, 1);
  mean.y() = 0;
  for (auto& pose : motion->poses) pose.root_translation_m -= mean;
}

// Turns every pose by `yaw_deg` about the vertical through the world origin.
// The root's world transform G_root = [R_root | J_root + t] becomes
// Y * G_root, i.e. R_root' = Y R_root and t' = Y (J_root + t) - J_root, where
// J_root is the shaped model's rest root joint; the children follow.
absl::Status TurnMotion(const body::BodyModel& model, const Eigen::VectorXd& shape, double yaw_deg,
                        body::RetargetedMotion* motion) {
  if (yaw_deg == 0.0) return absl::OkStatus();
  ASSIGN_OR_RETURN(const auto rest_joints_m, body::RestJointPositions(model, shape));
  const Eigen::Vector3d& root_m = rest_joints_m[body::Index(body::KinectV2Joint::kSpineBase)];
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()));
  const int root = body::Index(body::KinectV2Joint::kSpineBase);
  for (body::BodyPose& pose : motion->poses) {
    pose.local_rotation[root] = (yaw * pose.local_rotation[root]).normalized();
    pose.root_translation_m = yaw * (root_m + pose.root_translation_m) - root_m;
  }
  return absl::OkStatus();
}

// --------------------------------------------------------- virtual sensors

// The depth camera's lens distortion, applied to a pinhole render of a larger
// canvas by a nearest-pixel lookup table (no depth mixing across edges).
struct DistortionMap {
  CameraIntrinsics canvas;        // Pinhole, covers every undistorted ray.
  std::vector<int> canvas_index;  // Per output pixel, its canvas pixel (-1: none).
};

DistortionMap MakeDistortionMap(const CameraIntrinsics& k) {
  DistortionMap map;
  std::vector<Eigen::Vector2d> rays(static_cast<size_t>(k.width) * k.height);
  double min_u = 0, max_u = k.width - 1, min_v = 0, max_v = k.height - 1;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector2d distorted((x - k.cx) / k.fx, (y - k.cy) / k.fy);
      const auto n = k.Undistort(distorted).value_or(distorted);
      rays[static_cast<size_t>(y) * k.width + x] = n;
      min_u = std::min(min_u, k.fx * n.x() + k.cx);
      max_u = std::max(max_u, k.fx * n.x() + k.cx);
      min_v = std::min(min_v, k.fy * n.y() + k.cy);
      max_v = std::max(max_v, k.fy * n.y() + k.cy);
    }
  }
  const int left = static_cast<int>(std::ceil(-min_u)) + 1,
            top = static_cast<int>(std::ceil(-min_v)) + 1;
  map.canvas = k;
  map.canvas.k1 = map.canvas.k2 = map.canvas.k3 = map.canvas.p1 = map.canvas.p2 = 0;
  map.canvas.cx = k.cx + left;
  map.canvas.cy = k.cy + top;
  map.canvas.width = static_cast<int>(std::ceil(max_u)) + left + 2;
  map.canvas.height = static_cast<int>(std::ceil(max_v)) + top + 2;
  map.canvas_index.resize(rays.size(), -1);
  for (size_t i = 0; i < rays.size(); ++i) {
    const int u = static_cast<int>(std::lround(map.canvas.fx * rays[i].x() + map.canvas.cx));
    const int v = static_cast<int>(std::lround(map.canvas.fy * rays[i].y() + map.canvas.cy));
    if (u >= 0 && v >= 0 && u < map.canvas.width && v < map.canvas.height) {
      map.canvas_index[i] = v * map.canvas.width + u;
    }
  }
  return map;
}

render::RenderCamera ToRenderCamera(const CameraIntrinsics& k, const Rigid3d& world_from_camera) {
  return render::RenderCameraFromIntrinsics(k, Eigen::Isometry3d(world_from_camera.ToMatrix4()),
                                            /*near_m=*/0.2, /*far_m=*/12.0);
}

// What one sensor saw at one instant, before noise and encoding.
struct SensorShot {
  const VirtualSensor* sensor = nullptr;
  int64_t frame_index = 0;
  int64_t host_stamp_ns = 0;
  int64_t device_stamp_ns = 0;
  FloatImage ideal_depth_m;
  MaskImage label;
  RgbImage color;
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> joints_in_world;
  int64_t num_frames = 0;  // Of the take.
};

// The encoded messages of one sensor at one instant.
struct SensorMessages {
  v1::DepthImage depth, ground_truth_depth;
  v1::ColorImage color;
  v1::ActorMask mask;
  v1::Skeleton skeleton;
};

template <typename Message>
void SetStamps(const SensorShot& shot, Message* m) {
  m->set_sensor_id(shot.sensor->sensor_id);
  m->set_device_stamp_ns(shot.device_stamp_ns);
  m->set_host_stamp_ns(shot.host_stamp_ns);
  m->set_frame_index(shot.frame_index);
}

// Adds Gaussian sensor noise of `sigma` levels to every channel.
void AddColorNoise(RgbImage* image, double sigma, uint64_t seed) {
  if (sigma <= 0) return;
  // A table of noise values read at a random offset per row keeps this cheap.
  static const std::vector<int8_t> table = [] {
    std::vector<int8_t> t(1 << 16);
    std::mt19937 rng(12345);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    for (auto& v : t)
      v = static_cast<int8_t>(std::clamp(std::lround(normal(rng) * 16.0f), -127L, 127L));
    return t;
  }();
  std::mt19937_64 rng(seed);
  const int row = image->width * 3;
  const double scale = sigma / 16.0;
  for (int y = 0; y < image->height; ++y) {
    const size_t offset = rng() & 0xffff;
    uint8_t* p = &image->data[static_cast<size_t>(y) * row];
    for (int i = 0; i < row; ++i) {
      const double v = p[i] + table[(offset + i) & 0xffff] * scale;
      p[i] = static_cast<uint8_t>(std::clamp(v + 0.5, 0.0, 255.0));
    }
  }
}

// The joints a tracker would report at frame `frame` of `frames` with the
// errors of `errors` (the same for every sensor: seeded by the frame).
std::array<Eigen::Vector3d, body::kNumKinectV2Joints> WithSkeletonErrors(
    const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& joints_in_world,
    const SynthOptions::SkeletonErrors& errors, int64_t frame, int64_t frames, double fps,
    uint64_t seed, std::array<bool, body::kNumKinectV2Joints>* dropped) {
  using body::KinectV2Joint;
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> out = joints_in_world;
  dropped->fill(false);
  std::mt19937_64 rng(seed * 0x9e3779b97f4a7c15ull + static_cast<uint64_t>(frame) * 7919u + 17u);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const bool swap_arms = uniform(rng) < errors.arm_swap_fraction;
  if (swap_arms) {
    const std::pair<KinectV2Joint, KinectV2Joint> arms[] = {
        {KinectV2Joint::kShoulderLeft, KinectV2Joint::kShoulderRight},
        {KinectV2Joint::kElbowLeft, KinectV2Joint::kElbowRight},
        {KinectV2Joint::kWristLeft, KinectV2Joint::kWristRight},
        {KinectV2Joint::kHandLeft, KinectV2Joint::kHandRight},
        {KinectV2Joint::kHandTipLeft, KinectV2Joint::kHandTipRight},
        {KinectV2Joint::kThumbLeft, KinectV2Joint::kThumbRight}};
    for (const auto& [left, right] : arms)
      std::swap(out[body::Index(left)], out[body::Index(right)]);
  }
  for (const KinectV2Joint j :
       {KinectV2Joint::kElbowLeft, KinectV2Joint::kWristLeft, KinectV2Joint::kHandLeft,
        KinectV2Joint::kElbowRight, KinectV2Joint::kWristRight, KinectV2Joint::kHandRight,
        KinectV2Joint::kKneeLeft, KinectV2Joint::kAnkleLeft, KinectV2Joint::kFootLeft,
        KinectV2Joint::kKneeRight, KinectV2Joint::kAnkleRight, KinectV2Joint::kFootRight}) {
    const Eigen::Vector3d noise(normal(rng), normal(rng), normal(rng));
    out[body::Index(j)] += errors.limb_noise_m * noise;
  }
  const double half = 0.5 * errors.leg_drop_s * fps;
  const double middle = 0.5 * static_cast<double>(frames);
  if (static_cast<double>(frame) < errors.lock_on_s * fps) dropped->fill(true);
  if (half > 0 && std::abs(static_cast<double>(frame) - middle) < half) {
    for (const KinectV2Joint j :
         {KinectV2Joint::kKneeLeft, KinectV2Joint::kAnkleLeft, KinectV2Joint::kFootLeft}) {
      (*dropped)[body::Index(j)] = true;
    }
  }
  return out;
}

v1::Skeleton MakeSensorSkeleton(const SensorShot& shot, double jitter_m, uint64_t seed,
                                const SynthOptions& options) {
  v1::Skeleton skeleton;
  SetStamps(shot, &skeleton);
  skeleton.set_body_index(kActorLabel);
  skeleton.set_source(kSkeletonSource);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Rigid3d depth_from_world = shot.sensor->world_from_depth.Inverse();
  const CameraIntrinsics& k = shot.sensor->depth_intrinsics;
  std::array<bool, body::kNumKinectV2Joints> dropped{};
  const std::array<Eigen::Vector3d, body::kNumKinectV2Joints> reported =
      options.skeleton_errors.any()
          ? WithSkeletonErrors(shot.joints_in_world, options.skeleton_errors, shot.frame_index,
                               shot.num_frames, options.fps, options.seed, &dropped)
          : shot.joints_in_world;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    // Visibility from where the joint truly is; the position as reported.
    const Eigen::Vector3d truth = depth_from_world * shot.joints_in_world[j];
    const Eigen::Vector3d p = depth_from_world * reported[j];
    // Tracked where the joint is seen on the actor's surface; inferred (and
    // noisier) where it is hidden; not tracked outside the view.
    v1::TrackingState state = v1::TRACKING_STATE_NOT_TRACKED;
    if (auto pixel = k.Project(truth); pixel && k.IsInside(*pixel)) {
      const int x = static_cast<int>(std::lround(pixel->x())),
                y = static_cast<int>(std::lround(pixel->y()));
      const double z = shot.ideal_depth_m.at(x, y);
      const bool visible = shot.label.at(x, y) == kActorLabel && z > 0 && truth.z() - z < 0.15;
      state = visible ? v1::TRACKING_STATE_TRACKED : v1::TRACKING_STATE_INFERRED;
    }
    if (dropped[j]) state = v1::TRACKING_STATE_NOT_TRACKED;
    const double sigma = jitter_m * (state == v1::TRACKING_STATE_TRACKED ? 1.0 : 3.0);
    const Eigen::Vector3d noisy =
        p + sigma * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    auto* joint = skeleton.add_joints();
    joint->set_name(std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j))));
    *joint->mutable_position_in_depth_m() = ToProto(noisy);
    joint->set_tracking_state(state);
  }
  return skeleton;
}

absl::StatusOr<v1::DepthImage> MakeDepthMessage(const SensorShot& shot, const DepthImageMm& depth) {
  v1::DepthImage m;
  SetStamps(shot, &m);
  m.set_width_px(depth.width);
  m.set_height_px(depth.height);
  m.set_encoding("rvl+zstd");
  ASSIGN_OR_RETURN(std::string data, EncodeDepth(depth, DepthCodecOptions{}));
  m.set_data(std::move(data));
  return m;
}

// Noise and encoding of one shot; runs on a worker thread.
absl::StatusOr<SensorMessages> EncodeShot(SensorShot shot, const SynthOptions& options) {
  SensorMessages out;
  const uint64_t seed = options.seed * 1000003u + static_cast<uint64_t>(shot.frame_index) * 131u +
                        std::hash<std::string>{}(shot.sensor->sensor_id);
  const DepthImageMm noisy = ApplyKinectV2DepthNoise(
      shot.ideal_depth_m, shot.sensor->depth_intrinsics, options.depth_noise, seed);
  ASSIGN_OR_RETURN(out.depth, MakeDepthMessage(shot, noisy));
  ASSIGN_OR_RETURN(out.ground_truth_depth,
                   MakeDepthMessage(shot, QuantizeDepth(shot.ideal_depth_m, options.depth_noise)));
  // The actor mask marks valid depth pixels on the actor, like Kinect's body index.
  MaskImage mask(shot.label.width, shot.label.height);
  for (size_t i = 0; i < mask.data.size(); ++i) {
    mask.data[i] = (shot.label.data[i] == kActorLabel && noisy.data[i] != 0) ? kActorLabel : 0;
  }
  SetStamps(shot, &out.mask);
  out.mask.set_width_px(mask.width);
  out.mask.set_height_px(mask.height);
  out.mask.set_encoding("rle");
  out.mask.set_data(EncodeMaskRle(mask));
  AddColorNoise(&shot.color, options.color_noise_sigma, seed ^ 0x9e3779b97f4a7c15ull);
  SetStamps(shot, &out.color);
  out.color.set_width_px(shot.color.width);
  out.color.set_height_px(shot.color.height);
  out.color.set_encoding("jpeg");
  out.color.set_quality(options.jpeg_quality);
  ASSIGN_OR_RETURN(std::string jpeg, EncodeJpeg(shot.color, options.jpeg_quality));
  out.color.set_data(std::move(jpeg));
  out.skeleton = MakeSensorSkeleton(shot, options.skeleton_jitter_m, seed + 7, options);
  return out;
}

}  // namespace

absl::Status SynthOptions::Validate() const {
  if (motion.empty()) return absl::InvalidArgumentError("--motion is required");
  if (!(metres_per_unit >= 0.0 && metres_per_unit <= body::kMaxMetresPerUnit)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--metres-per-unit must be within (0, ", body::kMaxMetresPerUnit, "] metres"));
  }
  if (absl::StartsWith(motion, "builtin:") && (!joint_map_path.empty() || metres_per_unit > 0)) {
    return absl::InvalidArgumentError(
        "--joint-map and --metres-per-unit apply to a motion file, not to a builtin motion");
  }
  if (!(seconds > 0 && seconds <= 3600)) {
    return absl::InvalidArgumentError("--seconds must be in (0, 3600]");
  }
  if (!(fps > 0 && fps <= 120)) return absl::InvalidArgumentError("fps must be in (0, 120]");
  if (absl::StatusOr<Wardrobe> parsed = ParseWardrobe(wardrobe); !parsed.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("--wardrobe: ", parsed.status().message()));
  }
  if (num_sensors < 1 || num_sensors > 8) {
    return absl::InvalidArgumentError("--sensors must be 1..8");
  }
  if (jpeg_quality < 1 || jpeg_quality > 100) {
    return absl::InvalidArgumentError("jpeg quality must be 1..100");
  }
  if (color_width < 16 || color_height < 16 || color_width > 4096 || color_height > 4096) {
    return absl::InvalidArgumentError("colour size must be within 16..4096 px");
  }
  if (!(std::abs(yaw_deg) <= 360.0)) {
    return absl::InvalidArgumentError("--yaw-deg must be a finite angle within [-360, 360]");
  }
  if (!(lead_in_s >= 0.0 && lead_in_s < 3600.0)) {
    return absl::InvalidArgumentError("--lead-in-s must be within [0, 3600) seconds");
  }
  if (color_noise_sigma < 0 || skeleton_jitter_m < 0) {
    return absl::InvalidArgumentError("noise levels must be >= 0");
  }
  if (!(skeleton_errors.limb_noise_m >= 0 && skeleton_errors.limb_noise_m <= 1) ||
      !(skeleton_errors.arm_swap_fraction >= 0 && skeleton_errors.arm_swap_fraction <= 1) ||
      !(skeleton_errors.leg_drop_s >= 0 && skeleton_errors.leg_drop_s <= 3600) ||
      !(skeleton_errors.lock_on_s >= 0 && skeleton_errors.lock_on_s <= 3600)) {
    return absl::InvalidArgumentError(
        "skeleton errors: limb noise within [0, 1] m, arm swaps a fraction within [0, 1], a leg "
        "drop and a lock-on time within [0, 3600] s");
  }
  if (!(calibration_error_m >= 0 && calibration_error_m <= 2)) {
    return absl::InvalidArgumentError("the calibration error must be within [0, 2] m");
  }
  if (skeleton_errors.any() && sensor_skeleton != SensorSkeleton::kTruth) {
    return absl::InvalidArgumentError(
        "skeleton errors perturb the sensors' skeletons: they need --sensor-skeleton truth");
  }
  RETURN_IF_ERROR(ValidateBoard());
  return depth_noise.Validate();
}

absl::Status SynthOptions::ValidateBoard() const {
  if (board.empty()) return absl::OkStatus();
  if (absl::StatusOr<board::BoardSpec> spec = board::ParseBoardSpec(board); !spec.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("--board: ", spec.status().message()));
  }
  if (!(std::hypot(board_x_m, board_z_m) <= 4.0)) {
    return absl::InvalidArgumentError("the board must lie within 4 m of the origin");
  }
  if (!(std::abs(board_yaw_deg) <= 360.0)) {
    return absl::InvalidArgumentError("--board-yaw-deg must be a finite angle within [-360, 360]");
  }
  return absl::OkStatus();
}

Rigid3d WorldFromBoard(const SynthOptions& options) {
  const double yaw_rad = options.board_yaw_deg * M_PI / 180.0;
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY())),
                 Eigen::Vector3d(options.board_x_m, 0.0, options.board_z_m));
}

namespace {

// ------------------------------------------------------------- the set-up

struct Actor {
  body::BodyModel model;
  Eigen::VectorXd shape;
  body::RetargetedMotion motion;
  int num_frames = 0;  // Take frames to synthesise.
  double lead_in_s = 0.0;

  // The motion's pose at take time t_s: its first pose during the lead-in.
  body::BodyPose PoseAt(double t_s) const {
    return SamplePose(motion, std::max(0.0, t_s - lead_in_s));
  }
};

absl::StatusOr<Actor> PrepareActor(const SynthOptions& options) {
  Actor actor;
  ASSIGN_OR_RETURN(actor.model, LoadBody(options.body));
  ASSIGN_OR_RETURN(actor.shape, MakeShape(options.shape, actor.model, options.seed));
  ASSIGN_OR_RETURN(body::Motion motion, LoadMotion(options));
  if (motion.num_frames() < 1 || !(motion.fps() > 0)) {
    return absl::InvalidArgumentError(absl::StrCat(options.motion, ": motion has no frames"));
  }
  ASSIGN_OR_RETURN(actor.motion, body::RetargetMotion(motion, actor.model, actor.shape));
  const double motion_seconds = (motion.num_frames() - 1) / motion.fps();
  actor.lead_in_s = options.lead_in_s;
  const double seconds =
      std::min(options.seconds, options.lead_in_s + motion_seconds + 0.5 / options.fps);
  actor.num_frames = std::max(1, static_cast<int>(std::floor(seconds * options.fps)));
  if (options.center_motion) {
    const double moving_s = std::max(0.0, seconds - options.lead_in_s);
    CenterMotion(&actor.motion, static_cast<int>(std::ceil(moving_s * motion.fps())) + 1);
  }
  RETURN_IF_ERROR(TurnMotion(actor.model, actor.shape, options.yaw_deg, &actor.motion));
  return actor;
}

struct Scene {
  std::unique_ptr<render::OffscreenRenderer> renderer;
  render::MeshId body_mesh;
  std::vector<render::DrawItem> items;  // The room, then the body.
  RgbImage body_texture;                // The clothing (albedo) of the actor.
};

// The room light every sensor's colour image is rendered under; written to
// the ground truth (WriteTopology) so that a novel view of the truth can be
// rendered under the same light.
render::ShadingOptions SceneShading() {
  render::ShadingOptions shading;
  shading.headlight = false;  // One room light, the same for every sensor.
  shading.direction_to_light_in_world = {0.3, 1.0, 0.6};
  shading.ambient = 0.45f;
  shading.diffuse = 0.55f;
  return shading;
}

// Lays the printed board of `options` on the floor: a textured sheet at
// y = 0 that wins over the floor (drawn as an underlay), part of the
// background (label 0).
absl::Status AddBoard(const SynthOptions& options, Scene* scene) {
  if (options.board.empty()) return absl::OkStatus();
  ASSIGN_OR_RETURN(const board::BoardSpec spec, board::ParseBoardSpec(options.board));
  ASSIGN_OR_RETURN(const board::BoardTexture texture, board::RenderBoardTexture(spec));
  render::DrawItem sheet;
  ASSIGN_OR_RETURN(sheet.mesh, scene->renderer->UploadMesh(
                                   render::MakeFloorQuad(texture.width_m, texture.depth_m)));
  ASSIGN_OR_RETURN(sheet.texture, scene->renderer->UploadTexture(texture.image_srgb));
  sheet.world_from_model = Eigen::Isometry3d(WorldFromBoard(options).ToMatrix4());
  sheet.label = 0;
  scene->items.front().underlay = true;  // The floor (MakeRoom's first part).
  scene->items.insert(scene->items.begin() + 1, sheet);
  return absl::OkStatus();
}

absl::StatusOr<Scene> BuildScene(const body::BodyModel& model, const SynthOptions& options,
                                 int max_width, int max_height) {
  Scene scene;
  render::RendererOptions renderer_options;
  renderer_options.max_width = max_width;
  renderer_options.max_height = max_height;
  ASSIGN_OR_RETURN(scene.renderer, render::OffscreenRenderer::Create(renderer_options));
  RETURN_IF_ERROR(scene.renderer->SetShading(SceneShading()));
  for (RoomPart& part : MakeRoom()) {
    render::DrawItem item;
    ASSIGN_OR_RETURN(item.mesh, scene.renderer->UploadMesh(part.mesh));
    ASSIGN_OR_RETURN(item.texture, scene.renderer->UploadTexture(part.texture));
    item.label = 0;
    scene.items.push_back(item);
  }
  RETURN_IF_ERROR(AddBoard(options, &scene));
  ASSIGN_OR_RETURN(render::MeshData body_mesh,
                   render::MeshFromCornerUvs(model.template_vertices_m.cast<float>(),
                                             model.triangles, model.uvs, model.uv_triangles));
  render::DrawItem actor;
  ASSIGN_OR_RETURN(actor.mesh, scene.renderer->UploadMesh(body_mesh));
  ASSIGN_OR_RETURN(const Wardrobe wardrobe, ParseWardrobe(options.wardrobe));
  scene.body_texture = PaintClothingTexture(model, 1024, wardrobe);
  ASSIGN_OR_RETURN(actor.texture, scene.renderer->UploadTexture(scene.body_texture));
  actor.label = kActorLabel;
  scene.body_mesh = actor.mesh;
  scene.items.push_back(actor);
  return scene;
}

// Renders what `sensor` sees of the posed body: depth and label through the
// lens distortion of the depth camera, colour through the colour camera.
absl::Status RenderShot(Scene& scene, const VirtualSensor& sensor, const DistortionMap& map,
                        SensorShot* shot) {
  render::RenderOutputs canvas;
  canvas.requested = render::kRenderDepth | render::kRenderLabel;
  RETURN_IF_ERROR(scene.renderer->Render(ToRenderCamera(map.canvas, sensor.world_from_depth),
                                         scene.items, &canvas));
  const CameraIntrinsics& k = sensor.depth_intrinsics;
  shot->ideal_depth_m = FloatImage(k.width, k.height);
  shot->label = MaskImage(k.width, k.height);
  for (size_t i = 0; i < map.canvas_index.size(); ++i) {
    if (map.canvas_index[i] < 0) continue;
    shot->ideal_depth_m.data[i] = canvas.depth_m.data[map.canvas_index[i]];
    shot->label.data[i] = canvas.label.data[map.canvas_index[i]];
  }
  render::RenderOutputs color;
  color.requested = render::kRenderColour;
  RETURN_IF_ERROR(scene.renderer->Render(
      ToRenderCamera(sensor.color_intrinsics, sensor.world_from_color()), scene.items, &color));
  shot->color = std::move(color.colour);
  return absl::OkStatus();
}

v1::SensorCalibration MakeCalibration(const VirtualSensor& sensor, double fps) {
  v1::SensorCalibration c;
  c.set_sensor_id(sensor.sensor_id);
  c.set_model("kinect_v2_synthetic");
  c.set_serial(absl::StrCat("synthetic-", sensor.sensor_id));
  *c.mutable_depth_intrinsics() = ToProto(sensor.depth_intrinsics);
  *c.mutable_color_intrinsics() = ToProto(sensor.color_intrinsics);
  *c.mutable_color_from_depth() = ToProto(sensor.color_from_depth);
  *c.mutable_world_from_depth() = ToProto(sensor.world_from_depth);
  c.set_clock_offset_ns(sensor.clock_offset_ns);
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(fps);
  return c;
}

v1::TakeInfo MakeTakeInfo(const SynthOptions& options, const std::string& out_path,
                          int64_t start_stamp_ns) {
  v1::TakeInfo info;
  info.set_name(std::filesystem::path(out_path).stem().string());
  info.set_created_unix_ns(WallNowNs());
  info.set_generator("reenact synth");
  info.set_motion_source(options.motion);
  info.set_body_model(absl::StrCat(options.body, " shape=", options.shape));
  info.set_sensor_count(options.num_sensors);
  info.set_fps(options.fps);
  info.set_start_stamp_ns(start_stamp_ns);
  info.set_synthetic(true);
  info.set_notes(
      "Synthetic take: virtual Kinect v2 sensors; depth noise after Fankhauser et al. 2015 "
      "(axial, lateral, flying pixels, range and incidence limits); colour with Gaussian sensor "
      "noise; the skeleton channel is the true joints plus jitter, standing in for a vendor "
      "tracker. Ground truth on /ground_truth/*.");
  if (options.yaw_deg != 0.0) {
    info.set_notes(absl::StrCat(info.notes(), " The performance is turned by ", options.yaw_deg,
                                " degrees about the vertical through the origin."));
  }
  if (!options.board.empty()) {
    info.set_notes(absl::StrCat(info.notes(), " The board ", options.board,
                                " lies on the floor (GroundTruthTopology.world_from_board)."));
  }
  return info;
}

absl::Status WriteGroundTruth(TakeWriter* writer, const Actor& actor, int64_t frame,
                              int64_t stamp_ns, const body::BodyPose& pose,
                              const body::PosedBody& posed, bool with_mesh) {
  v1::GroundTruthJoints joints;
  joints.set_frame_index(frame);
  joints.set_stamp_ns(stamp_ns);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    joints.add_joint_names(
        std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j))));
    *joints.add_positions_in_world_m() = ToProto(posed.joints_m[j]);
  }
  RETURN_IF_ERROR(writer->WriteGroundTruthJoints(joints));
  v1::GroundTruthBody body;
  body.set_frame_index(frame);
  body.set_stamp_ns(stamp_ns);
  body.set_model_name(actor.model.name);
  for (const auto& q : pose.local_rotation) *body.add_local_rotations() = ToProto(q);
  *body.mutable_root_translation_in_world_m() = ToProto(pose.root_translation_m);
  for (int k = 0; k < actor.shape.size(); ++k)
    body.add_shape_coefficients(static_cast<float>(actor.shape[k]));
  RETURN_IF_ERROR(writer->WriteGroundTruthBody(body));
  if (!with_mesh) return absl::OkStatus();
  v1::GroundTruthMesh mesh;
  mesh.set_frame_index(frame);
  mesh.set_stamp_ns(stamp_ns);
  mesh.set_vertex_count(static_cast<int>(posed.vertices_m.cols()));
  const Eigen::Matrix3Xf vertices = posed.vertices_m.cast<float>();
  mesh.set_positions_in_world_m_f32(
      std::string(reinterpret_cast<const char*>(vertices.data()), vertices.size() * sizeof(float)));
  return writer->WriteGroundTruthMesh(mesh);
}

// PNG bytes of an sRGB image (lossless, so the truth's albedo is exact).
absl::StatusOr<std::string> EncodePng(const RgbImage& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<uint8_t*>(image.data.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", bgr, png)) {
    return absl::InternalError("ground truth: the albedo texture could not be encoded as PNG");
  }
  return std::string(png.begin(), png.end());
}

// The truth's triangles and its appearance: uvs per triangle corner, the
// clothing texture (albedo) and the room light of SceneShading, so that a
// novel view of the truth renders as the sensors saw it.
absl::Status WriteTopology(TakeWriter* writer, const body::BodyModel& model, const RgbImage& albedo,
                           const SynthOptions& options) {
  v1::GroundTruthTopology topology;
  topology.set_model_name(model.name);
  topology.set_vertex_count(model.num_vertices());
  for (const auto& t : model.triangles) {
    for (int k = 0; k < 3; ++k) topology.add_triangle_indices(static_cast<uint32_t>(t[k]));
  }
  std::string uvs;
  uvs.resize(model.uvs.size() * 2 * sizeof(float));
  for (size_t i = 0; i < model.uvs.size(); ++i) {
    std::memcpy(&uvs[i * 2 * sizeof(float)], model.uvs[i].data(), 2 * sizeof(float));
  }
  topology.set_uvs_f32(std::move(uvs));
  for (const auto& t : model.uv_triangles) {
    for (int k = 0; k < 3; ++k) topology.add_uv_triangle_indices(static_cast<uint32_t>(t[k]));
  }
  ASSIGN_OR_RETURN(std::string png, EncodePng(albedo));
  topology.set_albedo_png(std::move(png));
  const render::ShadingOptions shading = SceneShading();
  *topology.mutable_direction_to_light_in_world() =
      ToProto(Eigen::Vector3d(shading.direction_to_light_in_world.normalized()));
  topology.set_ambient(shading.ambient);
  topology.set_diffuse(shading.diffuse);
  if (!options.board.empty()) {
    ASSIGN_OR_RETURN(const board::BoardSpec spec, board::ParseBoardSpec(options.board));
    topology.set_board_spec(board::FormatBoardSpec(spec));
    *topology.mutable_world_from_board() = ToProto(WorldFromBoard(options));
  }
  return writer->WriteGroundTruthTopology(topology);
}

absl::Status WriteSensorMessages(TakeWriter* writer, const SensorMessages& m, bool with_skeleton) {
  RETURN_IF_ERROR(writer->WriteDepth(m.depth));
  RETURN_IF_ERROR(writer->WriteColor(m.color));
  RETURN_IF_ERROR(writer->WriteMask(m.mask));
  if (with_skeleton) RETURN_IF_ERROR(writer->WriteSkeleton(m.skeleton));
  return writer->WriteGroundTruthDepth(m.ground_truth_depth);
}

using PendingShot = std::future<absl::StatusOr<SensorMessages>>;

// Runs EncodeShot on the pool; the future holds its result.
PendingShot ScheduleEncode(ThreadPool* pool, SensorShot shot, const SynthOptions& options) {
  auto task = std::make_shared<std::packaged_task<absl::StatusOr<SensorMessages>()>>(
      [shot = std::move(shot), &options]() mutable {
        return EncodeShot(std::move(shot), options);
      });
  PendingShot future = task->get_future();
  pool->Schedule([task] { (*task)(); });
  return future;
}

absl::Status SynthesizeInto(const SynthOptions& options, const std::string& path,
                            const ProgressCallback& progress, SynthSummary* summary) {
  ASSIGN_OR_RETURN(Actor actor, PrepareActor(options));
  SensorRigOptions rig_options;
  rig_options.num_sensors = options.num_sensors;
  rig_options.distance_m = options.sensor_distance_m;
  rig_options.color_width = options.color_width;
  rig_options.color_height = options.color_height;
  rig_options.fps = options.fps;
  rig_options.seed = options.seed;
  ASSIGN_OR_RETURN(std::vector<VirtualSensor> sensors, MakeSensorRig(rig_options));
  const DistortionMap distortion = MakeDistortionMap(sensors[0].depth_intrinsics);
  ASSIGN_OR_RETURN(
      Scene scene,
      BuildScene(actor.model, options, std::max(options.color_width, distortion.canvas.width),
                 std::max(options.color_height, distortion.canvas.height)));
  summary->renderer = scene.renderer->Description();

  const int64_t start_ns = (WallNowNs() / kNanosPerSecond) * kNanosPerSecond;
  ASSIGN_OR_RETURN(auto writer, TakeWriter::Open(path, MakeTakeInfo(options, path, start_ns)));
  for (const VirtualSensor& sensor : sensors) {
    v1::SensorCalibration calibration = MakeCalibration(sensor, options.fps);
    if (&sensor == &sensors.back() && options.calibration_error_m > 0) {
      v1::Vector3* t = calibration.mutable_world_from_depth()->mutable_translation_m();
      t->set_x(t->x() + options.calibration_error_m);
    }
    RETURN_IF_ERROR(writer->AddSensor(calibration));
  }
  RETURN_IF_ERROR(WriteTopology(writer.get(), actor.model, scene.body_texture, options));

  ThreadPool pool(2);
  std::deque<PendingShot> pending;
  auto drain = [&](size_t keep) -> absl::Status {
    while (pending.size() > keep) {
      ASSIGN_OR_RETURN(SensorMessages messages, pending.front().get());
      pending.pop_front();
      RETURN_IF_ERROR(WriteSensorMessages(
          writer.get(), messages, options.sensor_skeleton == SynthOptions::SensorSkeleton::kTruth));
    }
    return absl::OkStatus();
  };
  std::mt19937_64 latency_rng(options.seed + 99);
  std::uniform_int_distribution<int64_t> latency_ns(20'000'000, 26'000'000);
  const double period_s = 1.0 / options.fps;
  for (int f = 0; f < actor.num_frames; ++f) {
    const body::BodyPose pose = actor.PoseAt(f * period_s);
    ASSIGN_OR_RETURN(body::PosedBody posed, body::PoseBody(actor.model, pose, actor.shape));
    const int64_t stamp_ns = start_ns + SecondsToNs(f * period_s);
    RETURN_IF_ERROR(
        WriteGroundTruth(writer.get(), actor, f, stamp_ns, pose, posed, options.ground_truth_mesh));
    for (const VirtualSensor& sensor : sensors) {
      // Each sensor exposes at its own phase and sees the body at that instant.
      const double exposure_s = f * period_s + sensor.phase_ns * 1e-9;
      ASSIGN_OR_RETURN(body::PosedBody seen,
                       body::PoseBody(actor.model, actor.PoseAt(exposure_s), actor.shape));
      RETURN_IF_ERROR(
          scene.renderer->UpdateMeshPositions(scene.body_mesh, seen.vertices_m.cast<float>()));
      SensorShot shot;
      shot.sensor = &sensor;
      shot.frame_index = f;
      const int64_t exposure_ns = start_ns + SecondsToNs(exposure_s);
      shot.device_stamp_ns = exposure_ns - sensor.clock_offset_ns;
      shot.host_stamp_ns = exposure_ns + latency_ns(latency_rng);
      shot.joints_in_world = seen.joints_m;
      shot.num_frames = actor.num_frames;
      RETURN_IF_ERROR(RenderShot(scene, sensor, distortion, &shot));
      pending.push_back(ScheduleEncode(&pool, std::move(shot), options));
    }
    RETURN_IF_ERROR(drain(2 * sensors.size()));
    if (progress) {
      Progress p{"synthesise", (f + 1.0) / actor.num_frames, f + 1, actor.num_frames};
      if (!progress(p)) {
        pool.Wait();
        return absl::CancelledError("synthesis cancelled");
      }
    }
  }
  RETURN_IF_ERROR(drain(0));
  RETURN_IF_ERROR(writer->Close());
  summary->frames = actor.num_frames;
  summary->sensors = static_cast<int>(sensors.size());
  summary->body_vertices = actor.model.num_vertices();
  summary->body_shape_components = actor.model.num_shape_components();
  summary->motion_scale = actor.motion.scale;
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<SynthSummary> SynthesizeTake(const SynthOptions& options,
                                            const std::string& out_path,
                                            const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  const int64_t begin_ns = SteadyNowNs();
  const std::string partial = out_path + ".partial";
  SynthSummary summary;
  absl::Status status = SynthesizeInto(options, partial, progress, &summary);
  std::error_code ec;
  if (!status.ok()) {
    std::filesystem::remove(partial, ec);
    return status;
  }
  std::filesystem::rename(partial, out_path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    return absl::PermissionDeniedError(
        absl::StrCat(out_path, ": cannot move the take in place: ", ec.message()));
  }
  summary.file_bytes = static_cast<int64_t>(std::filesystem::file_size(out_path, ec));
  summary.elapsed_s = NsToSeconds(SteadyNowNs() - begin_ns);
  return summary;
}

}  // namespace reenact::synth
