#include "common/tracking/training_data.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <random>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/thread_pool.h"
#include "common/body/model_spec.h"
#include "common/body/motion.h"
#include "common/body/retarget.h"
#include "common/synth/depth_noise.h"
#include "common/tracking/body_part_forest.h"

namespace reenact::tracking {
namespace {

// A body model with one shape, and every motion retargeted onto it.
struct Actor {
  std::shared_ptr<const body::BodyModel> model;
  std::shared_ptr<const std::vector<uint8_t>> vertex_parts;
  Eigen::VectorXd shape;
  std::vector<body::BodyPose> poses;  // Sampled frames of all motions.
};

Eigen::VectorXd RandomShape(const body::BodyModel& model, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::VectorXd shape(model.num_shape_components());
  for (int k = 0; k < shape.size(); ++k) shape[k] = std::clamp(normal(*rng), -2.0, 2.0);
  // As the synthesiser does: MakeHuman's directions are whole macro targets.
  if (model.name != "procedural") shape *= 0.3;
  return shape;
}

absl::StatusOr<std::vector<body::Motion>> LoadMotions(const TrainingDataOptions& options) {
  std::vector<body::Motion> motions;
  for (size_t i = 0; i < options.motion_paths.size(); ++i) {
    const std::string asf = i < options.asf_paths.size() ? options.asf_paths[i] : "";
    ASSIGN_OR_RETURN(body::Motion motion, body::ReadMotion(options.motion_paths[i], asf));
    motions.push_back(std::move(motion));
  }
  return motions;
}

absl::Status AddPoses(const std::vector<body::Motion>& motions, int stride, Actor* actor) {
  for (const body::Motion& motion : motions) {
    ASSIGN_OR_RETURN(body::RetargetedMotion retargeted,
                     body::RetargetMotion(motion, *actor->model, actor->shape));
    for (size_t f = 0; f < retargeted.poses.size(); f += static_cast<size_t>(stride)) {
      body::BodyPose pose = retargeted.poses[f];
      pose.root_translation_m.x() = 0;  // The camera is placed round the actor.
      pose.root_translation_m.z() = 0;
      actor->poses.push_back(pose);
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<Actor>> PrepareActors(const TrainingDataOptions& options) {
  ASSIGN_OR_RETURN(const std::vector<body::Motion> motions, LoadMotions(options));
  std::mt19937_64 rng(options.seed);
  std::vector<Actor> actors;
  for (const std::string& spec : options.bodies) {
    ASSIGN_OR_RETURN(body::BodyModel loaded, body::LoadBodyModelSpec(spec));
    auto model = std::make_shared<const body::BodyModel>(std::move(loaded));
    auto parts = std::make_shared<const std::vector<uint8_t>>(VertexParts(*model));
    for (int s = 0; s < options.shapes_per_body; ++s) {
      Actor actor{model, parts, RandomShape(*model, &rng), {}};
      RETURN_IF_ERROR(AddPoses(motions, options.frame_stride, &actor));
      if (actor.poses.empty()) return absl::InvalidArgumentError("the motions have no frames");
      actors.push_back(std::move(actor));
    }
  }
  return actors;
}

// ------------------------------------------------------------ the camera

struct Shot {
  CameraIntrinsics intrinsics;
  Rigid3d camera_from_world;
  double wall_distance_m = 0;  // Of the room's back wall from the camera.
  bool structured_light = false;
};

// A camera round the actor (the root at x = z = 0), looking at its body;
// OpenCV axes: x = forward x up (right), y = forward x right (down).
Shot PlaceCamera(const TrainingDataOptions& o, const Eigen::Vector3d& root_m,
                 std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const auto uniform = [&](double a, double b) { return a + (b - a) * u01(*rng); };
  Shot shot;
  const bool close_up = u01(*rng) < o.close_up_fraction;
  const double distance =
      close_up ? uniform(0.8, 1.3) : uniform(o.min_distance_m, o.max_distance_m);
  const double height = close_up ? uniform(1.0, 1.6) : uniform(o.min_height_m, o.max_height_m);
  const double azimuth = uniform(0, 2 * M_PI);
  const Eigen::Vector3d eye(distance * std::sin(azimuth), height, distance * std::cos(azimuth));
  Eigen::Vector3d target(0, close_up ? uniform(1.1, 1.5) : uniform(0.6, 1.0) * root_m.y() + 0.1, 0);
  if (u01(*rng) < o.off_centre_fraction) {
    target += Eigen::Vector3d(uniform(-0.8, 0.8), uniform(-0.5, 0.5), uniform(-0.8, 0.8));
  }
  const Eigen::Vector3d forward = (target - eye).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d world_from_camera;
  world_from_camera << right, down, forward;
  const Eigen::AngleAxisd roll(uniform(-0.05, 0.05), Eigen::Vector3d::UnitZ());
  const Rigid3d world_from(Eigen::Quaterniond(world_from_camera * roll.toRotationMatrix()), eye);
  shot.camera_from_world = world_from.Inverse();
  shot.intrinsics = KinectV2DepthIntrinsics();
  shot.intrinsics.k1 = shot.intrinsics.k2 = shot.intrinsics.k3 = 0;
  shot.intrinsics.p1 = shot.intrinsics.p2 = 0;
  const double focal = uniform(330, 540);
  shot.intrinsics.fx = shot.intrinsics.fy = focal;
  if (o.camera) {
    shot.intrinsics = *o.camera;
    shot.intrinsics.k1 = shot.intrinsics.k2 = shot.intrinsics.k3 = 0;
    shot.intrinsics.p1 = shot.intrinsics.p2 = 0;
  }
  shot.wall_distance_m = distance + uniform(0.8, 3.0);
  shot.structured_light = u01(*rng) < o.structured_light_fraction;
  return shot;
}

// ------------------------------------------------------- the rasteriser

struct Raster {
  FloatImage depth_m;
  std::vector<uint8_t> part;
};

// Z-buffered triangles; depth interpolated as 1/z (linear in the image).
void RasteriseTriangle(const std::array<Eigen::Vector3d, 3>& p, uint8_t part,
                       const CameraIntrinsics& k, Raster* r) {
  std::array<Eigen::Vector2d, 3> s;
  for (int i = 0; i < 3; ++i) {
    if (p[i].z() < 0.05) return;
    s[i] = {k.fx * p[i].x() / p[i].z() + k.cx, k.fy * p[i].y() / p[i].z() + k.cy};
  }
  const double area = (s[1] - s[0]).x() * (s[2] - s[0]).y() - (s[1] - s[0]).y() * (s[2] - s[0]).x();
  if (std::abs(area) < 1e-12) return;
  const int x0 =
      std::max(0, static_cast<int>(std::floor(std::min({s[0].x(), s[1].x(), s[2].x()}))));
  const int x1 =
      std::min(k.width - 1, static_cast<int>(std::ceil(std::max({s[0].x(), s[1].x(), s[2].x()}))));
  const int y0 =
      std::max(0, static_cast<int>(std::floor(std::min({s[0].y(), s[1].y(), s[2].y()}))));
  const int y1 =
      std::min(k.height - 1, static_cast<int>(std::ceil(std::max({s[0].y(), s[1].y(), s[2].y()}))));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d q(x, y);
      double w[3];
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector2d& a = s[(i + 1) % 3];
        const Eigen::Vector2d& b = s[(i + 2) % 3];
        w[i] = ((b - a).x() * (q - a).y() - (b - a).y() * (q - a).x()) / area;
      }
      if (w[0] < 0 || w[1] < 0 || w[2] < 0) continue;
      const double inv_z = w[0] / p[0].z() + w[1] / p[1].z() + w[2] / p[2].z();
      const float z = static_cast<float>(1.0 / inv_z);
      float& d = r->depth_m.at(x, y);
      if (d > 0 && d <= z) continue;
      d = z;
      r->part[static_cast<size_t>(y) * k.width + x] = part;
    }
  }
}

Raster RasteriseBody(const body::BodyModel& model, const std::vector<uint8_t>& vertex_parts,
                     const Eigen::Matrix3Xd& vertices_in_camera_m, const CameraIntrinsics& k) {
  Raster r{FloatImage(k.width, k.height, 0.0f),
           std::vector<uint8_t>(static_cast<size_t>(k.width) * k.height, kNoPart)};
  for (const Eigen::Vector3i& t : model.triangles) {
    const std::array<Eigen::Vector3d, 3> p = {vertices_in_camera_m.col(t[0]),
                                              vertices_in_camera_m.col(t[1]),
                                              vertices_in_camera_m.col(t[2])};
    RasteriseTriangle(p, vertex_parts[static_cast<size_t>(t[0])], k, &r);
  }
  return r;
}

// The room behind the body: the floor (y = 0) and a wall across the view.
void AddRoom(const Shot& shot, FloatImage* depth_m) {
  const Rigid3d world_from_camera = shot.camera_from_world.Inverse();
  const CameraIntrinsics& k = shot.intrinsics;
  const Eigen::Vector3d eye = world_from_camera.translation;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      float& d = depth_m->at(x, y);
      if (d > 0) continue;
      const Eigen::Vector3d ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);  // z = 1.
      const Eigen::Vector3d ray_world = world_from_camera.rotation * ray;
      double z = shot.wall_distance_m;  // The wall is roughly facing the camera.
      if (ray_world.y() < -1e-6) z = std::min(z, -eye.y() / ray_world.y());
      if (z < 8.0) d = static_cast<float>(z);
    }
  }
}

// ------------------------------------------------------------ one image

TrainingImage CropImage(const Raster& raster, const DepthImageMm& noisy, const Shot& shot) {
  const CameraIntrinsics& k = shot.intrinsics;
  int x0 = k.width, y0 = k.height, x1 = -1, y1 = -1;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const size_t i = static_cast<size_t>(y) * k.width + x;
      if (raster.part[i] == kNoPart || noisy.data[i] == 0) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
  }
  TrainingImage image;
  if (x1 < 0) return image;
  image.intrinsics = k;
  image.intrinsics.width = x1 - x0 + 1;
  image.intrinsics.height = y1 - y0 + 1;
  image.intrinsics.cx -= x0;
  image.intrinsics.cy -= y0;
  image.depth_m = FloatImage(image.intrinsics.width, image.intrinsics.height, kBackgroundDepthM);
  image.part.assign(image.depth_m.num_pixels(), kNoPart);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const size_t i = static_cast<size_t>(y) * k.width + x;
      if (raster.part[i] == kNoPart || noisy.data[i] == 0) continue;
      const size_t j = static_cast<size_t>(y - y0) * image.intrinsics.width + (x - x0);
      image.depth_m.data[j] = noisy.data[i] * 0.001f;
      image.part[j] = raster.part[i];
    }
  }
  return image;
}

// A unit vector drawn uniformly on the sphere.
Eigen::Vector3d RandomDirection(std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d d;
  do {
    d = Eigen::Vector3d(normal(*rng), normal(*rng), normal(*rng));
  } while (d.norm() < 1e-6);
  return d.normalized();
}

// Poses one arm at random where the motions seldom put it: upper arm down,
// forward or across, forearm anywhere a bent elbow (at most 150 degrees) can
// put it short of the torso. The mocap clips hold few arms in front of the
// body, and a forest that never saw a forearm before the chest reads such a
// person from the back: the front-back confusion of depth-only trackers.
// Directions are drawn in the frame of the shoulders' parent (SpineShoulder),
// which at rest is the model's: +X the body's left, +Y up, +Z forward.
void PoseArmAtRandom(const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& rest_m, bool left,
                     std::mt19937_64* rng, body::BodyPose* pose) {
  using J = body::KinectV2Joint;
  const J shoulder = left ? J::kShoulderLeft : J::kShoulderRight;
  const J elbow = left ? J::kElbowLeft : J::kElbowRight;
  const J wrist = left ? J::kWristLeft : J::kWristRight;
  const double side = left ? 1.0 : -1.0;
  const Eigen::Vector3d upper_rest = rest_m[body::Index(elbow)] - rest_m[body::Index(shoulder)];
  const Eigen::Vector3d fore_rest = rest_m[body::Index(wrist)] - rest_m[body::Index(elbow)];
  if (upper_rest.norm() < 1e-6 || fore_rest.norm() < 1e-6) return;
  const Eigen::Vector3d shoulder_at =
      rest_m[body::Index(shoulder)] - rest_m[body::Index(J::kSpineShoulder)];
  Eigen::Vector3d upper, fore;
  for (int attempt = 0; attempt < 200; ++attempt) {
    upper = RandomDirection(rng);
    if (upper.y() > 0.7 || upper.z() < -0.2 || side * upper.x() < -0.5) continue;
    fore = RandomDirection(rng);
    if (upper.dot(fore) < std::cos(150.0 * M_PI / 180.0) || fore.z() < -0.4) continue;
    const Eigen::Vector3d hand = shoulder_at + upper_rest.norm() * upper + fore_rest.norm() * fore;
    // Not into the chest or the belly, not behind the back.
    const bool in_torso = std::abs(hand.x()) < 0.17 && hand.y() < 0.05 && hand.y() > -0.6 &&
                          hand.z() < 0.14 && hand.z() > -0.14;
    if (in_torso || hand.z() < -0.2) continue;
    const Eigen::Quaterniond at_shoulder =
        Eigen::Quaterniond::FromTwoVectors(upper_rest.normalized(), upper);
    pose->local_rotation[body::Index(shoulder)] = at_shoulder;
    pose->local_rotation[body::Index(elbow)] =
        Eigen::Quaterniond::FromTwoVectors(fore_rest.normalized(), at_shoulder.inverse() * fore);
    return;
  }
}

absl::StatusOr<TrainingImage> MakeImage(const std::vector<Actor>& actors,
                                        const TrainingDataOptions& options, int index,
                                        bool keep_full) {
  std::mt19937_64 rng(options.seed * 7919u + static_cast<uint64_t>(index) * 104729u + 17u);
  const Actor& actor = options.sequence ? actors[0] : actors[rng() % actors.size()];
  body::BodyPose pose = options.sequence
                            ? actor.poses[static_cast<size_t>(index) % actor.poses.size()]
                            : actor.poses[rng() % actor.poses.size()];
  if (!options.sequence && options.arm_pose_fraction > 0.0) {
    std::mt19937_64 arm_rng(rng());
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    if (u01(arm_rng) < options.arm_pose_fraction) {
      ASSIGN_OR_RETURN(const body::PosedBody rest,
                       body::PoseBody(*actor.model, body::BodyPose(), actor.shape));
      // Mostly both arms (a guard), else one of them.
      const bool both = u01(arm_rng) < 0.6;
      const bool left = u01(arm_rng) < 0.5;
      if (both || left) PoseArmAtRandom(rest.joints_m, true, &arm_rng, &pose);
      if (both || !left) PoseArmAtRandom(rest.joints_m, false, &arm_rng, &pose);
    }
  }
  ASSIGN_OR_RETURN(const body::PosedBody posed, body::PoseBody(*actor.model, pose, actor.shape));
  std::mt19937_64 camera_rng(options.seed);
  const Shot shot = options.sequence ? PlaceCamera(options, {0, 0.95, 0}, &camera_rng)
                                     : PlaceCamera(options, posed.joints_m[0], &rng);
  Eigen::Matrix3Xd in_camera(3, posed.vertices_m.cols());
  for (Eigen::Index v = 0; v < in_camera.cols(); ++v) {
    in_camera.col(v) = shot.camera_from_world * Eigen::Vector3d(posed.vertices_m.col(v));
  }
  Raster raster = RasteriseBody(*actor.model, *actor.vertex_parts, in_camera, shot.intrinsics);
  AddRoom(shot, &raster.depth_m);
  const uint64_t noise_seed = rng();
  synth::DepthNoiseOptions tof;
  tof.axial_noise_scale = std::uniform_real_distribution<double>(1.0, 2.0)(rng);
  const DepthImageMm noisy =
      shot.structured_light
          ? ApplyStructuredLightNoise(raster.depth_m, noise_seed)
          : synth::ApplyKinectV2DepthNoise(raster.depth_m, shot.intrinsics, tof, noise_seed);
  TrainingImage image = CropImage(raster, noisy, shot);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    image.joints_in_camera_m[j] = shot.camera_from_world * posed.joints_m[j];
  }
  if (keep_full) {
    image.full_depth_mm = noisy;
    image.full_intrinsics = shot.intrinsics;
    image.full_mask = MaskImage(noisy.width, noisy.height);
    for (size_t i = 0; i < noisy.data.size(); ++i) {
      image.full_mask.data[i] = raster.part[i] != kNoPart && noisy.data[i] != 0 ? 1 : 0;
    }
  }
  return image;
}

}  // namespace

std::vector<uint8_t> VertexParts(const body::BodyModel& model) {
  std::vector<uint8_t> parts(static_cast<size_t>(model.num_vertices()), 0);
  for (size_t v = 0; v < parts.size() && v < model.skin_weights.size(); ++v) {
    int best = 0;
    for (int i = 1; i < body::kMaxInfluences; ++i) {
      if (model.skin_weights[v][i] > model.skin_weights[v][best]) best = i;
    }
    parts[v] = static_cast<uint8_t>(model.skin_joints[v][best]);
  }
  return parts;
}

absl::Status TrainingDataOptions::Validate() const {
  if (motion_paths.empty()) return absl::InvalidArgumentError("no motions to train on");
  if (bodies.empty() || shapes_per_body < 1) return absl::InvalidArgumentError("no bodies");
  if (camera) {
    if (absl::Status s = camera->Validate(); !s.ok()) return s;
    if (camera->width > 4096 || camera->height > 4096) {
      return absl::InvalidArgumentError("camera larger than 4096 px");
    }
  }
  if (num_images < 1 || num_images > 1000000) {
    return absl::InvalidArgumentError("images must be 1..1000000");
  }
  if (!(min_distance_m >= 0.5 && max_distance_m >= min_distance_m && max_distance_m <= 6.0)) {
    return absl::InvalidArgumentError("distances must satisfy 0.5 <= min <= max <= 6 m");
  }
  if (!(min_height_m >= 0.0 && max_height_m >= min_height_m && max_height_m <= 3.0)) {
    return absl::InvalidArgumentError("heights must satisfy 0 <= min <= max <= 3 m");
  }
  for (double f :
       {close_up_fraction, off_centre_fraction, structured_light_fraction, arm_pose_fraction}) {
    if (!(f >= 0.0 && f <= 1.0)) return absl::InvalidArgumentError("fractions must be in [0, 1]");
  }
  if (frame_stride < 1) return absl::InvalidArgumentError("frame stride must be >= 1");
  return absl::OkStatus();
}

absl::StatusOr<std::vector<TrainingImage>> SynthesizeTrainingImages(
    const TrainingDataOptions& options, bool keep_full_frames, const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(const std::vector<Actor> actors, PrepareActors(options));
  std::vector<absl::StatusOr<TrainingImage>> results(static_cast<size_t>(options.num_images),
                                                     absl::UnknownError("not run"));
  std::atomic<int> done{0};
  std::atomic<bool> cancelled{false};
  ThreadPool pool;
  pool.ParallelFor(0, options.num_images, [&](int i) {
    if (cancelled) return;
    results[static_cast<size_t>(i)] = MakeImage(actors, options, i, keep_full_frames);
    const int n = ++done;
    if (progress && n % 50 == 0 &&
        !progress(Progress{"synthesise", static_cast<double>(n) / options.num_images, n,
                           options.num_images})) {
      cancelled = true;
    }
  });
  if (cancelled) return absl::CancelledError("training data synthesis cancelled");
  std::vector<TrainingImage> images;
  images.reserve(results.size());
  for (auto& r : results) {
    if (!r.ok()) return r.status();
    if (r->part.empty()) continue;  // The camera missed the actor.
    images.push_back(*std::move(r));
  }
  return images;
}

DepthImageMm ApplyStructuredLightNoise(const FloatImage& ideal, uint64_t seed) {
  constexpr double kFocalBaselinePxM = 580.0 * 0.075;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  DepthImageMm out(ideal.width, ideal.height);
  for (int y = 0; y < ideal.height; ++y) {
    for (int x = 0; x < ideal.width; ++x) {
      const double z = ideal.at(x, y);
      if (z < 0.4 || z > 5.0) continue;
      // Projector shadow: no measurement just left of a closer surface.
      if (x + 2 < ideal.width) {
        const double zr = std::max(ideal.at(x + 1, y), ideal.at(x + 2, y));
        const double zn = std::min(ideal.at(x + 1, y), ideal.at(x + 2, y));
        if (zn > 0 && z - zn > 0.05 && zr > 0 && u01(rng) < 0.7) continue;
      }
      const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      const double noisy = z + sigma * normal(rng);
      const double disparity = std::round(8.0 * kFocalBaselinePxM / noisy) / 8.0;
      const double stepped = kFocalBaselinePxM / disparity;
      out.at(x, y) = static_cast<uint16_t>(std::clamp(std::lround(stepped * 1000.0), 0L, 65535L));
    }
  }
  return out;
}

TrainingDataOptions SequenceOptions(const std::string& motion_path, int frames,
                                    double min_distance_m, double max_distance_m, uint64_t seed) {
  TrainingDataOptions o;
  o.motion_paths = {motion_path};
  o.asf_paths = {""};
  o.num_images = frames;
  o.sequence = true;
  o.min_distance_m = min_distance_m;
  o.max_distance_m = max_distance_m;
  o.close_up_fraction = 0.0;
  o.off_centre_fraction = 0.0;
  o.structured_light_fraction = 0.0;
  o.arm_pose_fraction = 0.0;
  o.seed = seed;
  return o;
}

}  // namespace reenact::tracking
