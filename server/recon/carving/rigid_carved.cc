// Method "rigid-carved" (thesis 3.4.1; contract in rigid_carved.h).
//
// 1. Part frames at each part's first valid instant from the fused skeleton
//    (body_parts.h PartPosesFromJoints); the part's volume V_b is a box
//    around its bone in that frame, sized from adult proportions (ShapeOf).
// 2. Register, instant by instant (Eq. 3.7-3.9, part_registration.h): the
//    part's points at n-1 against D_n of every sensor (point-to-plane),
//    optical flow between I_{n-1} and I_n (point-to-point), and the
//    skeleton at n.
// 3. Fuse the depth images into every part's truncated SDF with the
//    registered T_{b,n} (Eq. 3.10-3.11, tsdf.h).
// 4. Mesh: marching cubes per part (marching_cubes.h).
// 5. Texture keyframes and baked textures (rigid_texturing.h), as the
//    cylinders method does.
//
// Departures from the thesis and choices it leaves open:
//  - Several sensors: registration sums the terms over the sensors (each
//    point paired in its own sensor), fusion integrates every sensor.
//  - Which pixels belong to a part: the thesis takes the depth pixels inside
//    the part's volume. The volumes of neighbouring parts overlap and hold
//    pieces of other parts (the torso beside a hanging arm, the floor under
//    a foot), so each actor pixel is labelled with the part whose nominal
//    shape (an elliptic cylinder round the bone, ShapeOf) is nearest, among
//    the parts whose box holds it. Registration uses a part's labelled
//    pixels; fusion takes near-surface values (eta < mu) only from them and
//    free-space values (eta >= mu) from every pixel, background included
//    (tsdf.h SurfaceOwnership). Option ownership=false restores the
//    thesis' volumes (on the synthetic take: 5.7 mm mean surface error
//    instead of 4.1 mm).
//  - w_s: the thesis sets w_s to half the number of voxels of V_b against
//    ICP sums over all depth pixels of the part. Here the ICP residuals are
//    weighted by the full-resolution pixels each decimated point stands for
//    (so the sums are the thesis' whatever the decimation), and w_s =
//    w_s_per_voxel x |V_b| per anchor. With the thesis' 0.5 the skeleton
//    term outweighs the depth ~30 to 1 and the poses follow the tracker's
//    jitter (synthetic takes: 6.8-7.1 mm mean surface error); 0.005 lets
//    the depth and flow terms lead (3.9-4.4 mm over three motions) while the
//    skeleton still stops drift (0.0005 drifts: the part frames end up
//    16 mm from the true joints). The value is tied to voxel_mm, as the
//    thesis' is: |V_b| grows with the cube of the resolution.
//  - Anchors of E_s: the proximal joint, the distal joint at the part's
//    reference length along the skeleton's bone and, when twist_weight > 0,
//    a point on the part's X axis; the skeleton's twist about the bone is a
//    convention of body_parts.h rather than a measurement, so it weighs 0
//    by default (twist then follows the depth and the flow).
//  - The first iterate of dT is the skeleton's own motion from n-1 to n
//    (the thesis starts from the identity), which keeps fast limbs within
//    the projective association's reach.
//  - Depth pixels at discontinuities are dropped (time-of-flight "flying
//    pixels", sensor_frame.h RemoveDepthEdges) before registration and
//    fusion.
//  - Free space from the silhouette: depth pixels without a return that lie
//    more than 2 px off the actor mask carve their whole ray as free
//    (MarkFreeRays, option carve_no_return). Eq. 3.11 only uses returns;
//    where the background returns nothing (open space, the synthetic take's
//    empty room) the voxels beside a limb were never observed, and with two
//    facing sensors the limb's sides stayed open. On a 2 s front kick
//    (1080p, eval at 90 degrees): IoU 0.815 -> 0.880, PSNR 16.6 -> 17.8 dB,
//    surface 6.7 -> 6.1 mm. A "visual hull" rule for unobserved voxels
//    (inside when every image saw them behind this part's own surface) was
//    tried with it and dropped: IoU 0.863 instead of 0.880.
//  - Fast motion (a run, jumps, spins): chaining Eq. 3.7 from instant to
//    instant lets a limb drift off its bone or jump to a neighbouring
//    surface, and a lost part never comes back. A part whose registered pose
//    puts its anchors more than max_drift_mm (60) from the skeleton's, or
//    that found nothing to register against, restarts from the skeleton's
//    pose at that instant (figure part_restarts).
//  - A ray without a return is free only as far as the sensor reaches
//    (free_ray_max_mm, 4000: the shorter of Kinect v1's and v2's specified
//    ranges): an actor beyond it returns nothing either. Carving the whole
//    ray erased a runner wherever one sensor saw them past its range while
//    the other saw them near: on the CMU run 09_06 (2 sensors, view at 90
//    degrees) IoU 0.17 -> 0.78, PSNR 13.1 -> 16.6 dB; the jumps 01_01 are
//    unchanged (18.95 dB, IoU 0.897).
//  - A part whose skeleton bone is missing at the first instant starts at
//    the first instant it is present; an instant without a skeleton is
//    registered without the skeleton term; a part with nothing to register
//    against keeps its pose.
//  - Fusion takes every fuse_stride-th instant (default: ~15 per second of
//    take; consecutive 30 fps frames add little: 4.03 vs 3.98 mm).
//  - Meshes keep the connected components of at least 10 % of the largest
//    (floaters go; with two sensors facing each other a part's front and
//    back can be separate components). A part whose mesh is empty (never
//    observed) gets a capped cylinder of the default radius rate
//    (cylinders.h) so it still shows.
#include "server/recon/carving/rigid_carved.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "server/recon/body_parts.h"
#include "server/recon/carving/marching_cubes.h"
#include "server/recon/carving/optical_flow.h"
#include "server/recon/carving/part_registration.h"
#include "server/recon/carving/sensor_frame.h"
#include "server/recon/carving/tsdf.h"
#include "server/recon/cylinders/cylinders.h"
#include "server/recon/method_util.h"
#include "server/recon/rigid_texturing.h"

namespace reenact::recon {
namespace {

using carving::ColorLookup;
using carving::FlowField;
using carving::GreyImage;
using carving::PosedCamera;
using carving::SurfaceMap;
using carving::TsdfVolume;
using carving::VolumeBox;
using Clock = std::chrono::steady_clock;

constexpr double kPi = 3.14159265358979323846;
// Margin of the optical-flow crop around the actor, flow pixels.
constexpr int kFlowMarginPx = 12;
// Most voxels of all part volumes together (8 bytes each).
constexpr int64_t kMaxTotalVoxels = int64_t{1} << 27;

// The largest distance between where a pose and the skeleton put a part's
// anchors, metres (0 without anchors).
double AnchorDriftM(const std::vector<carving::SkeletonAnchor>& anchors) {
  double drift_m = 0.0;
  for (const carving::SkeletonAnchor& anchor : anchors) {
    drift_m = std::max(drift_m, (anchor.point_in_world_m - anchor.target_in_world_m).norm());
  }
  return drift_m;
}

carving::PartRegistrationOptions RegistrationOptionsOf(const RigidCarvedOptions& o) {
  carving::PartRegistrationOptions options;
  options.w_o = o.w_o;
  options.max_pair_distance_m = o.max_pair_distance_mm * 1e-3;
  options.max_normal_angle_deg = o.max_normal_angle_deg;
  options.min_update_deg = o.min_update_deg;
  options.min_update_mm = o.min_update_mm;
  options.max_iterations = o.max_iterations;
  return options;
}

// The nominal shape of a part, in bone lengths L (part frame): an elliptic
// cylinder of half-axes rx L (along X) and rz L (along Z) from y0 L to y1 L,
// from adult proportions (the procedural body of common/synth measures
// within ~20 % of these). It sizes the volume V_b (StartParts) and decides
// which part a depth pixel belongs to (Label: the nearest nominal surface).
struct PartShape {
  double rx;
  double rz;
  double y0;
  double y1;
};

PartShape ShapeOf(BodyPart part) {
  switch (part) {
    case BodyPart::kHead:
      return {0.8, 0.75, -0.3, 1.9};
    case BodyPart::kChest:
      return {0.5, 0.42, 0.0, 1.1};
    case BodyPart::kAbdomen:
      return {0.7, 0.6, -0.35, 1.0};
    case BodyPart::kUpperArmLeft:
    case BodyPart::kUpperArmRight:
      return {0.16, 0.16, -0.1, 1.0};
    case BodyPart::kForearmLeft:
    case BodyPart::kForearmRight:
      return {0.16, 0.16, 0.0, 1.0};
    case BodyPart::kHandLeft:
    case BodyPart::kHandRight:
      return {0.25, 0.25, 0.0, 1.05};
    case BodyPart::kThighLeft:
    case BodyPart::kThighRight:
      return {0.2, 0.2, -0.15, 1.0};
    case BodyPart::kShinLeft:
    case BodyPart::kShinRight:
      return {0.13, 0.13, 0.0, 1.1};
    case BodyPart::kFootLeft:
    case BodyPart::kFootRight:
      return {0.25, 0.35, -0.15, 1.15};
  }
  return {0.2, 0.2, 0.0, 1.0};
}

// Approximate signed distance from a part-frame point to the nominal shape
// (metres; negative inside): the radial distance to the ellipse, measured
// in its smaller half-axis, combined with the distance past the ends.
float NominalDistance(const Eigen::Vector3f& in_part, const Eigen::Vector4f& shape_m) {
  const float rx = shape_m[0];
  const float rz = shape_m[1];
  const float radial = (std::hypot(in_part.x() / rx, in_part.z() / rz) - 1.0f) * std::min(rx, rz);
  const float axial = std::max(shape_m[2] - in_part.y(), in_part.y() - shape_m[3]);
  const float outside = std::hypot(std::max(radial, 0.0f), std::max(axial, 0.0f));
  return outside + std::min(std::max(radial, axial), 0.0f);
}

// Closes the surface where no depth image reached: voxels with N*(v) = 0
// inside the nominal shape become inside (-mu). With two sensors facing each
// other the sides of a limb are seen edge-on, their depth pixels fall to the
// edge filter, and the front and back sheets of the TSDF never meet; the
// voxels between them are unobserved. Filling them puts the side surface at
// the boundary of the observed free space (MarkFreeRays), as a visual hull
// would.
void FillUnseenInterior(const Eigen::Vector4f& shape_m, double mu_m, carving::SdfGrid* grid) {
  for (int k = 0; k < grid->nz; ++k) {
    for (int j = 0; j < grid->ny; ++j) {
      for (int i = 0; i < grid->nx; ++i) {
        const size_t index = grid->Index(i, j, k);
        if (grid->observed[index]) continue;
        const Eigen::Vector3f in_part =
            (grid->origin_m + grid->voxel_m * Eigen::Vector3d(i, j, k)).cast<float>();
        if (NominalDistance(in_part, shape_m) >= 0.0f) continue;
        grid->sdf[index] = static_cast<float>(-mu_m);
        grid->observed[index] = 1;
      }
    }
  }
}

// Pixels farther than this from the actor mask may carve as free rays.
constexpr int kNoReturnGuardPx = 2;

// Gives pixels without a depth return (0) that lie farther than guard_px
// from every actor pixel of the mask the depth kFreeRayMm, so that fusion
// counts their whole ray as free space: the actor mask says the actor is not
// on that ray (a visual hull's silhouette constraint). Without it, voxels
// beside a limb whose background returns nothing (open space, a far wall,
// the edge filter's band) are never observed, and the limb's side surface,
// seen edge-on by facing sensors, is not closed. Used only for fusion: the
// surface map for registration is built before.
void MarkFreeRays(const MaskImage& actor, int guard_px, DepthImageMm* depth_mm) {
  const int width = depth_mm->width;
  const int height = depth_mm->height;
  if (actor.width != width || actor.height != height) return;
  // Distance to the nearest actor pixel, as a separable max filter (square guard).
  std::vector<uint8_t> near(static_cast<size_t>(width) * height, 0);
  std::vector<uint8_t> row_near(static_cast<size_t>(width) * height, 0);
  for (int y = 0; y < height; ++y) {
    int last = -1 << 20;
    for (int x = 0; x < width; ++x) {
      if (actor.at(x, y) != 0) last = x;
      if (x - last <= guard_px) row_near[static_cast<size_t>(y) * width + x] = 1;
    }
    last = 1 << 20;
    for (int x = width - 1; x >= 0; --x) {
      if (actor.at(x, y) != 0) last = x;
      if (last - x <= guard_px) row_near[static_cast<size_t>(y) * width + x] = 1;
    }
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      bool hit = false;
      for (int dy = -guard_px; dy <= guard_px && !hit; ++dy) {
        const int yy = y + dy;
        hit = yy >= 0 && yy < height && row_near[static_cast<size_t>(yy) * width + x] != 0;
      }
      near[static_cast<size_t>(y) * width + x] = hit ? 1 : 0;
    }
  }
  for (size_t i = 0; i < near.size(); ++i) {
    if (depth_mm->data[i] == 0 && near[i] == 0) depth_mm->data[i] = carving::kFreeRayMm;
  }
}

Rigid3d ToRigid(const Eigen::Isometry3d& isometry) {
  return Rigid3d(Eigen::Quaterniond(isometry.linear()), isometry.translation());
}

Eigen::Isometry3d ToIsometry(const Rigid3d& rigid) {
  Eigen::Isometry3d isometry = Eigen::Isometry3d::Identity();
  isometry.linear() = rigid.rotation.toRotationMatrix();
  isometry.translation() = rigid.translation;
  return isometry;
}

// One part's state through the take.
struct PartTrack {
  bool started = false;
  double reference_length_m = 0.0;
  VolumeBox box;
  Eigen::Vector4f shape_m = Eigen::Vector4f::Zero();    // rx, rz, y0, y1 of ShapeOf, metres.
  std::vector<std::optional<Rigid3d>> world_from_part;  // Per instant.
};

// The sensors' cameras: depth in the world, colour at the flow resolution.
struct SensorCameras {
  std::optional<PosedCamera> depth;
  std::optional<PosedCamera> flow_color;  // Made at the first decoded colour.
};

// What fusion needs of one sensor at one instant (kept from registration
// while the cache budget lasts).
struct FusionInput {
  bool present = false;
  DepthImageMm depth_mm;
  MaskImage labels;
};

// One sensor at one instant, as registration uses it.
struct SensorFrame {
  bool present = false;
  DepthImageMm depth_mm;  // Full image (fusion carves with the background too).
  SurfaceMap surface;     // Actor pixels only, decimated.
  MaskImage labels;       // Per surface cell: 0 none, part + 1.
  GreyImage grey;         // Flow resolution; empty without colour.
  ColorLookup lookup;
  // Per surface cell of the previous instant's frame, the cell of this
  // frame that the optical flow leads to (-1 none); empty without flow.
  std::vector<int32_t> flow_targets;
};

// What registration, fusion and meshing make (AssembleCarved turns it into
// the untextured reenactment).
struct RegisteredTrack {
  double reference_length_m = 0.0;
  std::vector<std::optional<Rigid3d>> world_from_part;  // Per instant.
};
struct CarvedParts {
  std::vector<PartMesh> meshes;  // kNumBodyParts, part-id order, before baking.
  std::array<RegisteredTrack, kNumBodyParts> tracks;
  std::map<std::string, double> figures;
};

class RigidCarved {
 public:
  RigidCarved(const TakeFrames& take, const RigidCarvedOptions& options,
              const StageProgress& stages, const LogCallback& log)
      : take_(take),
        options_(options),
        stages_(stages),
        log_(log),
        fuse_stride_(options.fuse_stride > 0
                         ? options.fuse_stride
                         : std::max(1, static_cast<int>(std::lround(take.fps() / 15.0)))) {}

  absl::StatusOr<CarvedParts> Carve();

 private:
  absl::Status MakeCameras();
  absl::Status LoadFrame(int instant, int sensor, bool with_colour, SensorFrame* frame);
  absl::Status AddFlowTargets(int sensor, const SensorFrame& previous, SensorFrame* current) const;
  void StartParts(int instant);
  void Label(int instant, SensorFrame* frame) const;
  absl::Status Register();
  std::vector<carving::SourcePoint> PartSources(int part, const Rigid3d& pose_before,
                                                const std::vector<SensorFrame>& previous,
                                                const std::vector<SensorFrame>& current) const;
  std::vector<carving::SkeletonAnchor> PartAnchors(int part, const Rigid3d& pose_before,
                                                   const Rigid3d& skeleton_pose) const;
  void RegisterInstant(int instant, const std::vector<SensorFrame>& previous,
                       const std::vector<SensorFrame>& current);
  void KeepForFusion(int instant, std::vector<SensorFrame>* frames);
  absl::Status Fuse(std::vector<std::optional<TsdfVolume>>* volumes);
  absl::StatusOr<std::vector<PartMesh>> Mesh(const std::vector<std::optional<TsdfVolume>>& volumes);

  const TakeFrames& take_;
  const RigidCarvedOptions& options_;
  const StageProgress& stages_;
  const LogCallback& log_;
  const int fuse_stride_;
  std::vector<SensorCameras> cameras_;
  std::mutex cameras_mutex_;
  std::array<PartTrack, kNumBodyParts> parts_;
  // Per instant (fused ones only) and sensor; empty when not kept.
  std::vector<std::vector<FusionInput>> fusion_cache_;
  int64_t fusion_cache_bytes_ = 0;
  // Figures.
  double plane_rms_sum_m_ = 0.0;
  double flow_rms_sum_m_ = 0.0;
  double skeleton_rms_sum_m_ = 0.0;
  int64_t registrations_ = 0;
  int64_t iterations_sum_ = 0;
  int64_t unsolved_ = 0;
  int64_t restarts_ = 0;  // Parts restarted from the skeleton (max_drift_mm).
  std::mutex figures_mutex_;
  double register_seconds_ = 0.0;
  double fuse_seconds_ = 0.0;
  double mesh_seconds_ = 0.0;
  int fallback_parts_ = 0;
  int64_t voxels_ = 0;
  int64_t triangles_ = 0;
};

absl::Status RigidCarved::MakeCameras() {
  for (const TakeSensor& sensor : take_.sensors()) {
    SensorCameras cameras;
    ASSIGN_OR_RETURN(PosedCamera depth,
                     PosedCamera::Create(sensor.depth_intrinsics, sensor.world_from_depth));
    cameras.depth = std::move(depth);
    cameras_.push_back(std::move(cameras));
  }
  return absl::OkStatus();
}

absl::Status RigidCarved::LoadFrame(int instant, int sensor, bool with_colour, SensorFrame* frame) {
  const SensorView& view = take_.instant(instant).views[sensor];
  frame->present = view.present;
  if (!view.present) return absl::OkStatus();
  ASSIGN_OR_RETURN(frame->depth_mm, take_.LoadDepth(instant, sensor));
  ASSIGN_OR_RETURN(const MaskImage actor, take_.LoadActorMask(instant, sensor));
  carving::RemoveDepthEdges(options_.edge_filter_mm, &frame->depth_mm);
  carving::SurfaceMapOptions surface_options;
  surface_options.step = options_.depth_step;
  ASSIGN_OR_RETURN(
      frame->surface,
      carving::BuildSurfaceMap(*cameras_[sensor].depth, frame->depth_mm, &actor, surface_options));
  if (options_.carve_no_return) MarkFreeRays(actor, kNoReturnGuardPx, &frame->depth_mm);
  if (!with_colour || view.color_jpeg.empty()) return absl::OkStatus();
  int denominator = 1;
  while (denominator < 8 && take_.sensors()[sensor].color_intrinsics.width / (2 * denominator) >=
                                options_.flow_width_px) {
    denominator *= 2;
  }
  ASSIGN_OR_RETURN(const RgbImage colour, take_.LoadColor(instant, sensor, denominator));
  ASSIGN_OR_RETURN(frame->grey, carving::GreyAtSize(colour, colour.width, colour.height));
  const PosedCamera* flow_color = nullptr;
  {
    std::lock_guard<std::mutex> lock(cameras_mutex_);
    SensorCameras& cameras = cameras_[sensor];
    if (!cameras.flow_color || cameras.flow_color->width() != colour.width ||
        cameras.flow_color->height() != colour.height) {
      ASSIGN_OR_RETURN(const CameraIntrinsics intrinsics,
                       take_.ColorIntrinsicsForImage(sensor, colour));
      const TakeSensor& info = take_.sensors()[sensor];
      ASSIGN_OR_RETURN(
          PosedCamera camera,
          PosedCamera::Create(intrinsics, info.world_from_depth * info.color_from_depth.Inverse()));
      cameras.flow_color = std::move(camera);
    }
    flow_color = &*cameras.flow_color;
  }
  frame->lookup = carving::BuildColorLookup(frame->surface, *flow_color);
  return absl::OkStatus();
}

// Starts the parts whose bone the skeleton has at `instant` and that have
// not started yet: part frame from the skeleton, volume around the bone.
void RigidCarved::StartParts(int instant) {
  const Instant& at = take_.instant(instant);
  if (!at.valid) return;
  const PartPoses poses = PartPosesFromJoints(at.joints_in_world_m);
  const double voxel_m = options_.voxel_mm * 1e-3;
  for (int p = 0; p < kNumBodyParts; ++p) {
    PartTrack& track = parts_[p];
    if (track.started || !poses[p].valid) continue;
    track.started = true;
    track.reference_length_m = poses[p].length_m;
    const PartShape shape = ShapeOf(static_cast<BodyPart>(p));
    const double length = track.reference_length_m;
    const double scale = options_.radius_scale;
    track.shape_m = Eigen::Vector4d(shape.rx * scale * length, shape.rz * scale * length,
                                    shape.y0 * length, shape.y1 * length)
                        .cast<float>();
    // V_b: the nominal shape grown by a quarter of its size and the margin.
    const double margin = options_.margin_mm * 1e-3;
    const double radius = 1.25 * std::max(shape.rx, shape.rz) * scale * length + margin;
    const double grow = 0.25 * std::max(shape.rx, shape.rz) * length + margin;
    track.box =
        carving::BoneBox(shape.y0 * length - grow, shape.y1 * length + grow, radius, voxel_m);
    track.world_from_part[instant] = ToRigid(poses[p].world_from_part);
  }
}

// Labels every surface cell with the part whose nominal shape (ShapeOf) is
// nearest among the parts whose box holds it; 0 when no box does.
void RigidCarved::Label(int instant, SensorFrame* frame) const {
  const SurfaceMap& surface = frame->surface;
  frame->labels = MaskImage(surface.width, surface.height, 0);
  struct Candidate {
    int part;
    Eigen::Matrix3f rotation_t;  // part_from_world rotation.
    Eigen::Vector3f origin;      // Part origin in the world.
    const PartTrack* track;
  };
  std::vector<Candidate> candidates;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const auto& pose = parts_[p].world_from_part[instant];
    if (!pose) continue;
    candidates.push_back({p, pose->rotation.toRotationMatrix().transpose().cast<float>(),
                          pose->translation.cast<float>(), &parts_[p]});
  }
  for (size_t cell = 0; cell < surface.points_in_world_m.size(); ++cell) {
    if (!surface.HasPoint(cell)) continue;
    const Eigen::Vector3f& point = surface.points_in_world_m[cell];
    float best = std::numeric_limits<float>::infinity();
    int best_part = -1;
    for (const Candidate& candidate : candidates) {
      const Eigen::Vector3f in_part = candidate.rotation_t * (point - candidate.origin);
      if (!candidate.track->box.Contains(in_part.cast<double>())) continue;
      const float distance = NominalDistance(in_part, candidate.track->shape_m);
      if (distance < best) {
        best = distance;
        best_part = candidate.part;
      }
    }
    if (best_part >= 0) frame->labels.data[cell] = static_cast<uint8_t>(best_part + 1);
  }
}

void RigidCarved::KeepForFusion(int instant, std::vector<SensorFrame>* frames) {
  if (instant % fuse_stride_ != 0) return;
  int64_t bytes = 0;
  for (const SensorFrame& frame : *frames) {
    bytes += static_cast<int64_t>(frame.depth_mm.data.size() * sizeof(uint16_t) +
                                  frame.labels.data.size());
  }
  if (fusion_cache_bytes_ + bytes > int64_t{options_.cache_mb} * (1 << 20)) return;
  fusion_cache_bytes_ += bytes;
  std::vector<FusionInput>& kept = fusion_cache_[instant];
  for (SensorFrame& frame : *frames) {
    // The depth is not needed by the next registration step; the labels are.
    kept.push_back({frame.present, std::move(frame.depth_mm), frame.labels});
  }
}

absl::Status RigidCarved::Register() {
  const int n = take_.num_instants();
  const auto start = Clock::now();
  for (PartTrack& track : parts_) track.world_from_part.assign(n, std::nullopt);
  fusion_cache_.assign(n, {});
  const int num_sensors = take_.num_sensors();
  std::vector<SensorFrame> previous(num_sensors);
  std::vector<SensorFrame> current(num_sensors);
  bool have_previous = false;
  for (int i = 0; i < n; ++i) {
    std::mutex mutex;
    absl::Status status = absl::OkStatus();
    // Per sensor: decode, surface, colour and the flow from the previous instant.
    take_.pool().ParallelFor(0, num_sensors, [&](int s) {
      current[s] = SensorFrame();
      absl::Status loaded = LoadFrame(i, s, options_.use_flow, &current[s]);
      if (loaded.ok() && have_previous) loaded = AddFlowTargets(s, previous[s], &current[s]);
      if (!loaded.ok()) {
        std::lock_guard<std::mutex> lock(mutex);
        if (status.ok()) status = loaded;
      }
    });
    RETURN_IF_ERROR(status);
    if (have_previous) RegisterInstant(i, previous, current);
    StartParts(i);
    if (options_.ownership) {
      take_.pool().ParallelFor(0, num_sensors, [&](int s) {
        if (current[s].present) Label(i, &current[s]);
      });
    }
    KeepForFusion(i, &current);
    std::swap(previous, current);
    have_previous = true;
    RETURN_IF_ERROR(stages_.Report("register", i + 1, n));
  }
  register_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
  return absl::OkStatus();
}

absl::Status RigidCarved::AddFlowTargets(int sensor, const SensorFrame& previous,
                                         SensorFrame* current) const {
  if (!options_.use_flow || !previous.present || !current->present || previous.grey.empty() ||
      current->grey.empty() || previous.grey.width != current->grey.width ||
      previous.grey.height != current->grey.height) {
    return absl::OkStatus();
  }
  // Flow only around the actor (at both instants), which is all E_o uses.
  const carving::PixelBox a = carving::SurfaceBounds(previous.lookup, kFlowMarginPx);
  const carving::PixelBox b = carving::SurfaceBounds(current->lookup, kFlowMarginPx);
  if (a.empty() || b.empty()) return absl::OkStatus();
  const carving::PixelBox region{std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1),
                                 std::max(a.y1, b.y1)};
  ASSIGN_OR_RETURN(const FlowField flow,
                   carving::ComputeOpticalFlow(previous.grey, current->grey, {}, region));
  ASSIGN_OR_RETURN(current->flow_targets,
                   carving::FlowTargets(previous.surface, *cameras_[sensor].flow_color,
                                        previous.lookup, flow, current->lookup));
  return absl::OkStatus();
}

// The part's points at n-1 (E_p / E_o sources), each with its flow target
// at n, subsampled to max_points_per_part.
std::vector<carving::SourcePoint> RigidCarved::PartSources(
    int part, const Rigid3d& pose_before, const std::vector<SensorFrame>& previous,
    const std::vector<SensorFrame>& current) const {
  std::vector<carving::SourcePoint> sources;
  const Rigid3d part_from_world = pose_before.Inverse();
  for (int s = 0; s < take_.num_sensors(); ++s) {
    if (!previous[s].present || !current[s].present) continue;
    const SurfaceMap& surface = previous[s].surface;
    const std::vector<int32_t>& targets = current[s].flow_targets;
    for (size_t cell = 0; cell < surface.points_in_world_m.size(); ++cell) {
      if (!surface.HasNormal(cell)) continue;
      if (options_.ownership) {
        if (previous[s].labels.data[cell] != part + 1) continue;
      } else if (!parts_[part].box.Contains(part_from_world *
                                            surface.points_in_world_m[cell].cast<double>())) {
        continue;  // The thesis: every point inside the part's volume.
      }
      carving::SourcePoint source;
      source.point_in_world_m = surface.points_in_world_m[cell];
      source.normal_in_world = surface.normals_in_world[cell];
      source.view = s;
      source.weight = static_cast<float>(surface.step * surface.step);
      if (!targets.empty() && targets[cell] >= 0) {
        source.has_flow_target = true;
        source.flow_target_in_world_m = current[s].surface.points_in_world_m[targets[cell]];
      }
      sources.push_back(source);
    }
  }
  if (static_cast<int>(sources.size()) <= options_.max_points_per_part) return sources;
  // An even subsample; weights grow so that the sums stay full-resolution sums.
  const double keep_every = static_cast<double>(sources.size()) / options_.max_points_per_part;
  std::vector<carving::SourcePoint> kept;
  for (int k = 0; k < options_.max_points_per_part; ++k) {
    carving::SourcePoint source = sources[static_cast<size_t>(k * keep_every)];
    source.weight *= static_cast<float>(keep_every);
    kept.push_back(source);
  }
  return kept;
}

// E_s anchors: part points placed by T_{b,n-1} and by the skeleton's T*_{b,n}.
std::vector<carving::SkeletonAnchor> RigidCarved::PartAnchors(int part, const Rigid3d& pose_before,
                                                              const Rigid3d& skeleton_pose) const {
  const double length = parts_[part].reference_length_m;
  const std::array<std::pair<Eigen::Vector3d, double>, 3> points = {{
      {Eigen::Vector3d::Zero(), 1.0},                                    // Proximal joint.
      {Eigen::Vector3d(0.0, length, 0.0), 1.0},                          // Distal joint.
      {Eigen::Vector3d(0.5 * length, 0.0, 0.0), options_.twist_weight},  // Twist.
  }};
  std::vector<carving::SkeletonAnchor> anchors;
  for (const auto& [point_in_part, weight] : points) {
    if (weight > 0.0) {
      anchors.push_back({pose_before * point_in_part, skeleton_pose * point_in_part, weight});
    }
  }
  return anchors;
}

void RigidCarved::RegisterInstant(int instant, const std::vector<SensorFrame>& previous,
                                  const std::vector<SensorFrame>& current) {
  const int num_sensors = take_.num_sensors();
  std::vector<carving::RegistrationView> views(num_sensors);
  for (int s = 0; s < num_sensors; ++s) views[s] = {&*cameras_[s].depth, &current[s].surface};
  const Instant& now = take_.instant(instant);
  const Instant& before = take_.instant(instant - 1);
  std::optional<PartPoses> skeleton_now;
  std::optional<PartPoses> skeleton_before;
  if (now.valid) skeleton_now = PartPosesFromJoints(now.joints_in_world_m);
  if (before.valid) skeleton_before = PartPosesFromJoints(before.joints_in_world_m);

  take_.pool().ParallelFor(0, kNumBodyParts, [&](int p) {
    PartTrack& track = parts_[p];
    const std::optional<Rigid3d>& pose_before = track.world_from_part[instant - 1];
    if (!pose_before) return;
    const std::vector<carving::SourcePoint> sources =
        PartSources(p, *pose_before, previous, current);
    carving::PartRegistrationOptions options = RegistrationOptionsOf(options_);
    options.w_s = options_.w_s_per_voxel * static_cast<double>(track.box.num_voxels());
    std::vector<carving::SkeletonAnchor> anchors;
    Rigid3d initial;  // dT's first iterate: the skeleton's motion when known.
    std::optional<Rigid3d> skeleton_pose;
    if (skeleton_now && (*skeleton_now)[p].valid) {
      skeleton_pose = ToRigid((*skeleton_now)[p].world_from_part);
      anchors = PartAnchors(p, *pose_before, *skeleton_pose);
      if (skeleton_before && (*skeleton_before)[p].valid) {
        initial = *skeleton_pose * ToRigid((*skeleton_before)[p].world_from_part).Inverse();
      }
    }
    absl::StatusOr<carving::PartRegistrationSummary> summary =
        carving::RegisterPart(sources, views, anchors, options, initial);
    std::optional<Rigid3d> pose;
    if (summary.ok() && summary->solved) {
      pose = summary->delta * *pose_before;  // Eq. 3.7.
      pose->rotation.normalize();
    }
    // Fast motion: a lost or drifted part restarts from the skeleton.
    const bool restart = skeleton_pose && options_.max_drift_mm > 0 &&
                         (!pose || AnchorDriftM(PartAnchors(p, *pose, *skeleton_pose)) >
                                       options_.max_drift_mm * 1e-3);
    std::lock_guard<std::mutex> lock(figures_mutex_);
    if (restart) {
      track.world_from_part[instant] = *skeleton_pose;
      ++restarts_;
      if (!pose) ++unsolved_;
      return;
    }
    if (!pose) {
      track.world_from_part[instant] = *pose_before;  // Nothing to register with.
      ++unsolved_;
      return;
    }
    track.world_from_part[instant] = *pose;
    ++registrations_;
    iterations_sum_ += summary->iterations;
    plane_rms_sum_m_ += summary->plane_rms_m;
    flow_rms_sum_m_ += summary->flow_rms_m;
    skeleton_rms_sum_m_ += summary->skeleton_rms_m;
  });
}

absl::Status RigidCarved::Fuse(std::vector<std::optional<TsdfVolume>>* volumes) {
  const auto start = Clock::now();
  const double mu_m = options_.mu_mm * 1e-3;
  volumes->assign(kNumBodyParts, std::nullopt);
  int64_t total_voxels = 0;
  for (const PartTrack& track : parts_) total_voxels += track.started ? track.box.num_voxels() : 0;
  if (total_voxels > kMaxTotalVoxels) {
    return absl::InvalidArgumentError(
        absl::StrCat("the part volumes would hold ", total_voxels, " voxels (at most ",
                     kMaxTotalVoxels, "); raise voxel_mm or lower radius_scale / margin_mm"));
  }
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (!parts_[p].started) continue;
    ASSIGN_OR_RETURN(TsdfVolume volume, TsdfVolume::Create(parts_[p].box, mu_m));
    (*volumes)[p] = std::move(volume);
    voxels_ += parts_[p].box.num_voxels();
  }
  const int n = take_.num_instants();
  const int num_sensors = take_.num_sensors();
  std::vector<FusionInput> frames(num_sensors);
  for (int i = 0; i < n; i += fuse_stride_) {
    std::mutex mutex;
    absl::Status status = absl::OkStatus();
    if (fusion_cache_[i].empty()) {
      // Not kept from registration: load and label again.
      take_.pool().ParallelFor(0, num_sensors, [&](int s) {
        SensorFrame frame;
        absl::Status loaded = LoadFrame(i, s, /*with_colour=*/false, &frame);
        if (loaded.ok() && frame.present && options_.ownership) Label(i, &frame);
        frames[s] = {frame.present, std::move(frame.depth_mm), std::move(frame.labels)};
        if (!loaded.ok()) {
          std::lock_guard<std::mutex> lock(mutex);
          if (status.ok()) status = loaded;
        }
      });
      RETURN_IF_ERROR(status);
    } else {
      frames = std::move(fusion_cache_[i]);
      fusion_cache_[i].clear();
    }
    take_.pool().ParallelFor(0, kNumBodyParts, [&](int p) {
      const std::optional<Rigid3d>& pose = parts_[p].world_from_part[i];
      if (!pose || !(*volumes)[p]) return;
      carving::SurfaceOwnership ownership;
      ownership.step = options_.depth_step;
      ownership.accepted[p + 1] = true;
      for (int s = 0; s < num_sensors; ++s) {
        if (!frames[s].present) continue;
        ownership.labels = &frames[s].labels;
        // Eq. 3.10-3.11 with T_{b,n}.
        absl::Status integrated =
            (*volumes)[p]->Integrate(*cameras_[s].depth, frames[s].depth_mm, *pose,
                                     options_.ownership ? &ownership : nullptr,
                                     static_cast<float>(options_.free_ray_max_mm * 1e-3));
        if (!integrated.ok()) {
          std::lock_guard<std::mutex> lock(mutex);
          if (status.ok()) status = integrated;
        }
      }
    });
    RETURN_IF_ERROR(status);
    RETURN_IF_ERROR(stages_.Report("fuse", std::min(n, i + 1), n));
  }
  RETURN_IF_ERROR(stages_.Report("fuse", n, n));
  fuse_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
  return absl::OkStatus();
}

// The geometry of a carved mesh, or nullopt when it is empty.
std::optional<PartMesh> ToGeometry(const carving::TriangleMesh& mesh) {
  if (mesh.num_triangles() == 0) return std::nullopt;
  PartMesh geometry;
  const Eigen::Index count = static_cast<Eigen::Index>(mesh.positions_m.size());
  geometry.positions_in_part_m.resize(3, count);
  geometry.normals_in_part.resize(3, count);
  for (Eigen::Index v = 0; v < count; ++v) {
    geometry.positions_in_part_m.col(v) = mesh.positions_m[v];
    geometry.normals_in_part.col(v) = mesh.normals[v];
  }
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    geometry.triangles.emplace_back(mesh.triangles[t], mesh.triangles[t + 1],
                                    mesh.triangles[t + 2]);
  }
  return geometry;
}

absl::StatusOr<std::vector<PartMesh>> RigidCarved::Mesh(
    const std::vector<std::optional<TsdfVolume>>& volumes) {
  const auto start = Clock::now();
  std::vector<std::optional<PartMesh>> geometry(kNumBodyParts);
  std::mutex mutex;
  absl::Status status = absl::OkStatus();
  RETURN_IF_ERROR(stages_.Report("mesh", 0, kNumBodyParts));
  take_.pool().ParallelFor(0, kNumBodyParts, [&](int p) {
    if (!volumes[p]) return;
    carving::SdfGrid grid = volumes[p]->ToSdfGrid();
    if (options_.fill_unseen) FillUnseenInterior(parts_[p].shape_m, volumes[p]->mu_m(), &grid);
    absl::StatusOr<carving::TriangleMesh> mesh = carving::MarchingCubes(grid);
    if (!mesh.ok()) {
      std::lock_guard<std::mutex> lock(mutex);
      if (status.ok()) status = mesh.status();
      return;
    }
    geometry[p] = ToGeometry(carving::KeepLargeComponents(*mesh, options_.min_component_fraction));
  });
  RETURN_IF_ERROR(status);
  std::vector<PartMesh> meshes;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const BodyPart part = static_cast<BodyPart>(p);
    double length = parts_[p].reference_length_m;
    if (!geometry[p]) {
      // Never observed (or never posed): a cylinder of the default rate.
      ++fallback_parts_;
      if (!(length > 1e-3)) length = 0.1;
      geometry[p] = MakeCylinderGeometry(DefaultRadiusRate(part) * length, 0.0, length, 16, 4);
    }
    triangles_ += static_cast<int64_t>(geometry[p]->triangles.size());
    meshes.push_back(ToPartMesh(part, *geometry[p], 0.0f, static_cast<float>(length)));
  }
  RETURN_IF_ERROR(stages_.Report("mesh", kNumBodyParts, kNumBodyParts));
  mesh_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
  return meshes;
}

absl::StatusOr<CarvedParts> RigidCarved::Carve() {
  if (take_.num_valid_instants() == 0) {
    return absl::InvalidArgumentError("the take has no instant with a skeleton");
  }
  RETURN_IF_ERROR(MakeCameras());
  RETURN_IF_ERROR(Register());
  std::vector<std::optional<TsdfVolume>> volumes;
  RETURN_IF_ERROR(Fuse(&volumes));
  CarvedParts carved;
  ASSIGN_OR_RETURN(carved.meshes, Mesh(volumes));
  volumes.clear();
  for (int p = 0; p < kNumBodyParts; ++p) {
    carved.tracks[p].reference_length_m = parts_[p].reference_length_m;
    carved.tracks[p].world_from_part = std::move(parts_[p].world_from_part);
  }

  const int n = take_.num_instants();
  auto& figures = carved.figures;
  const double registrations = std::max<int64_t>(1, registrations_);
  figures["registration_rms_mm"] = 1e3 * plane_rms_sum_m_ / registrations;
  figures["flow_rms_mm"] = 1e3 * flow_rms_sum_m_ / registrations;
  figures["skeleton_rms_mm"] = 1e3 * skeleton_rms_sum_m_ / registrations;
  figures["mean_iterations"] = static_cast<double>(iterations_sum_) / registrations;
  figures["registrations"] = static_cast<double>(registrations_);
  figures["registrations_unsolved"] = static_cast<double>(unsolved_);
  figures["part_restarts"] = static_cast<double>(restarts_);
  figures["voxels"] = static_cast<double>(voxels_);
  figures["triangles"] = static_cast<double>(triangles_);
  figures["parts_fallback"] = fallback_parts_;
  figures["register_seconds"] = register_seconds_;
  figures["fuse_seconds"] = fuse_seconds_;
  figures["mesh_seconds"] = mesh_seconds_;
  figures["fuse_stride"] = fuse_stride_;
  figures["carve_instants_per_second"] =
      n / std::max(1e-9, register_seconds_ + fuse_seconds_ + mesh_seconds_);
  if (log_) {
    log_(absl::StrCat("rigid-carved: ", n, " instants, registration rms ",
                      figures["registration_rms_mm"], " mm, ", figures["mean_iterations"],
                      " iterations, register ", register_seconds_, " s, fuse ", fuse_seconds_,
                      " s, mesh ", mesh_seconds_, " s, ", triangles_, " triangles"));
  }
  return carved;
}

// The reenactment of carved parts, untextured: the meshes, one frame per
// instant of the take (its registered poses, scale 1, and its fused
// skeleton), frame_count, fps, part names and the carving figures.
Reenactment AssembleCarved(const TakeFrames& take, const CarvedParts& carved) {
  Reenactment data;
  data.parts = carved.meshes;
  const int n = take.num_instants();
  for (int i = 0; i < n; ++i) {
    PartPoses poses;
    for (int p = 0; p < kNumBodyParts; ++p) {
      const RegisteredTrack& track = carved.tracks[p];
      if (static_cast<int>(track.world_from_part.size()) <= i) continue;
      const std::optional<Rigid3d>& pose = track.world_from_part[i];
      if (!pose) continue;
      poses[p].world_from_part = ToIsometry(*pose);
      poses[p].length_m = track.reference_length_m;
      poses[p].valid = true;
    }
    std::array<double, kNumBodyParts> scales;
    scales.fill(1.0);
    data.frames.push_back(MakePartFrame(i, take.instant(i).stamp_ns, poses, scales,
                                        take.instant(i).joints_in_world_m));
  }
  data.info.figures = carved.figures;
  data.info.frame_count = static_cast<int>(data.frames.size());
  data.info.fps = take.fps();
  data.info.part_names = BodyPartNames();
  return data;
}

}  // namespace

absl::Status RigidCarvedOptions::Read(OptionReader& reader) {
  RETURN_IF_ERROR(
      reader.Double("w_o", &w_o, 0.0, 1e6, "weight of the optical-flow term of Eq. 3.8"));
  RETURN_IF_ERROR(reader.Double("w_s_per_voxel", &w_s_per_voxel, 0.0, 1e6,
                                "skeleton weight w_s of Eq. 3.8 per voxel of the part's volume"));
  RETURN_IF_ERROR(reader.Double("twist_weight", &twist_weight, 0.0, 1e3,
                                "weight of the skeleton anchor on the part's X axis (twist)"));
  RETURN_IF_ERROR(reader.Double("max_drift_mm", &max_drift_mm, 0.0, 10000.0,
                                "a part whose joints drift farther than this from the "
                                "skeleton's restarts from the skeleton (0: never)"));
  RETURN_IF_ERROR(reader.Double("voxel_mm", &voxel_mm, 2.0, 100.0, "voxel side, millimetres"));
  RETURN_IF_ERROR(reader.Double("mu_mm", &mu_mm, 1.0, 500.0,
                                "truncation mu of Eq. 3.11, millimetres (>= voxel_mm)"));
  RETURN_IF_ERROR(reader.Int("max_iterations", &max_iterations, 1, 1000,
                             "registration iterations per instant"));
  RETURN_IF_ERROR(reader.Double("max_pair_distance_mm", &max_pair_distance_mm, 1.0, 1000.0,
                                "farthest point pair registration uses, millimetres"));
  RETURN_IF_ERROR(reader.Double("max_normal_angle_deg", &max_normal_angle_deg, 1.0, 180.0,
                                "largest normal disagreement of a pair, degrees"));
  RETURN_IF_ERROR(reader.Double("min_update_deg", &min_update_deg, 0.0, 10.0,
                                "registration stops below this rotation update, degrees"));
  RETURN_IF_ERROR(reader.Double("min_update_mm", &min_update_mm, 0.0, 100.0,
                                "registration stops below this translation update, millimetres"));
  RETURN_IF_ERROR(
      reader.Int("depth_step", &depth_step, 1, 16, "depth decimation for registration and labels"));
  RETURN_IF_ERROR(reader.Int("max_points_per_part", &max_points_per_part, 10, 1000000,
                             "most points a part registers with per instant"));
  RETURN_IF_ERROR(
      reader.Bool("use_flow", &use_flow, "use optical flow between instants (Eq. 3.8)"));
  RETURN_IF_ERROR(reader.Int("flow_width_px", &flow_width_px, 16, 8192,
                             "decode colour for the flow at least this wide, pixels"));
  RETURN_IF_ERROR(reader.Int("edge_filter_mm", &edge_filter_mm, 0, 10000,
                             "drop depth pixels at discontinuities above this step (0: off)"));
  RETURN_IF_ERROR(reader.Double("radius_scale", &radius_scale, 0.2, 5.0,
                                "scale of the nominal part shapes across the bone"));
  RETURN_IF_ERROR(reader.Double("margin_mm", &margin_mm, 0.0, 500.0,
                                "margin of the part volumes around their shapes, millimetres"));
  RETURN_IF_ERROR(reader.Int("fuse_stride", &fuse_stride, 0, 1000,
                             "fuse every k-th instant (0: about 15 per second)"));
  RETURN_IF_ERROR(
      reader.Bool("ownership", &ownership,
                  "label pixels by the nearest nominal part (false: the thesis' volumes)"));
  RETURN_IF_ERROR(reader.Bool("fill_unseen", &fill_unseen,
                              "unobserved voxels inside the nominal shape count as inside"));
  RETURN_IF_ERROR(reader.Double("free_ray_max_mm", &free_ray_max_mm, 500.0, 65000.0,
                                "how far from its sensor a pixel without a return, off the "
                                "actor, carves free space, millimetres (the sensor's range)"));
  RETURN_IF_ERROR(reader.Bool("carve_no_return", &carve_no_return,
                              "depth pixels without a return off the actor carve their ray"));
  RETURN_IF_ERROR(reader.Int("cache_mb", &cache_mb, 0, 1 << 20,
                             "decoded depth kept from registration for fusion, MiB"));
  RETURN_IF_ERROR(reader.Double("min_component_fraction", &min_component_fraction, 0.0, 1.0,
                                "drop mesh components below this fraction of the largest"));
  return texturing.Read(reader);
}

int64_t RigidCarvedOptions::MemoryBytes(const TakeSize& take) const {
  // Bone lengths of a tall adult (1.95 m), metres, by BodyPart: the parts'
  // volumes (StartParts) scale with them.
  static constexpr double kTallBoneM[kNumBodyParts] = {
      0.30, 0.32, 0.30, 0.36, 0.32, 0.12, 0.36, 0.32, 0.12, 0.52, 0.50, 0.20, 0.52, 0.50, 0.20};
  const double voxel_m = voxel_mm * 1e-3;
  const double margin = margin_mm * 1e-3;
  int64_t voxels = 0, triangles = 0;
  std::vector<int64_t> part_triangles;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartShape shape = ShapeOf(static_cast<BodyPart>(p));
    const double length = kTallBoneM[p];
    const double widest = std::max(shape.rx, shape.rz);
    const double radius = 1.25 * widest * radius_scale * length + margin;
    const double grow = 0.25 * widest * length + margin;
    const double along = (shape.y1 - shape.y0) * length + 2 * grow;
    const double nx = std::ceil(2 * radius / voxel_m) + 2;
    const double ny = std::ceil(along / voxel_m) + 2;
    voxels += static_cast<int64_t>(nx * nx * ny);
    // Marching cubes: about two triangles for each voxel-sized patch of the
    // surface; the surface taken as twice the nominal shape's (an elliptic
    // cylinder and its caps), for floaters and a front and back that do
    // not meet.
    const double a = shape.rx * radius_scale * length, b = shape.rz * radius_scale * length;
    const double perimeter = 2 * M_PI * std::sqrt(0.5 * (a * a + b * b));
    const double area = perimeter * (shape.y1 - shape.y0) * length + 2 * M_PI * a * b;
    const auto part = static_cast<int64_t>(2 * 2 * area / (voxel_m * voxel_m)) + 64;
    triangles += part;
    part_triangles.push_back(part);
  }
  // Each voxel: the running sums and counts of Eq. 3.11 (tsdf.h), the grid
  // that is meshed (distance, observed) and the labels of its cells.
  const int64_t volume_bytes = voxels * 20;
  // Decoded depth and labels kept for fusion: at most cache_mb.
  const int64_t depth = take.Instants(0) * std::max(take.sensors, 1) * memory::kDepthFrameBytes;
  const int64_t cache = std::min<int64_t>(depth, int64_t{cache_mb} * memory::kMiB);
  // Optical flow: two colour frames at flow width, and their pyramids.
  const int64_t flow = use_flow ? int64_t{8} * flow_width_px * flow_width_px * 4 : 0;
  return volume_bytes + cache + flow + memory::MeshBytes(triangles) +
         texturing.MemoryBytes(take, part_triangles, triangles / 2);
}

absl::Status RigidCarvedOptions::Validate() const {
  if (mu_mm < voxel_mm) {
    return absl::InvalidArgumentError(
        absl::StrCat("option mu_mm (", mu_mm, ") must be at least voxel_mm (", voxel_mm, ")"));
  }
  RETURN_IF_ERROR(RegistrationOptionsOf(*this).Validate());
  return texturing.Validate();
}

absl::StatusOr<Reenactment> RunRigidCarved(const TakeFrames& take,
                                           const RigidCarvedOptions& options,
                                           const MethodContext& context) {
  RETURN_IF_ERROR(options.Validate());
  const StageProgress stages(context.progress,
                             {{"register", 0.3}, {"fuse", 0.2}, {"mesh", 0.05}, {"texture", 0.45}});
  RigidCarved method(take, options, stages, context.log);
  ASSIGN_OR_RETURN(const CarvedParts carved, method.Carve());
  Reenactment data = AssembleCarved(take, carved);
  RETURN_IF_ERROR(
      AddRigidTextures(take, options.texturing, &data, stages.ForStage("texture"), context.log)
          .status());
  return data;
}

absl::StatusOr<std::string> PrepareRigidCarved(const TakeFrames& take,
                                               const RigidCarvedOptions& options,
                                               const MethodContext& context) {
  RETURN_IF_ERROR(options.Validate());
  const StageProgress stages(context.progress, {{"register", 0.3}, {"fuse", 0.2}, {"mesh", 0.05}});
  RigidCarved method(take, options, stages, context.log);
  ASSIGN_OR_RETURN(const CarvedParts carved, method.Carve());
  return PackUntexturedRigid(AssembleCarved(take, carved), KeyframeStride(take, options.texturing));
}

namespace {

// Registration and fusion: every instant's depth, and its colour for the
// optical flow.
TakeNeeds CarvedPrepareNeeds(const TakeFrames& take, const RigidCarvedOptions& options) {
  TakeNeeds needs = TakeNeeds::All(take);
  if (!options.use_flow) needs.color.clear();
  return needs;
}

}  // namespace

const ReconstructionMethod& RigidCarvedMethod() {
  static const TypedMethod<RigidCarvedOptions> method(
      {"rigid-carved",
       "rigid body parts registered over the take and carved into truncated SDFs, textured by "
       "the rotation-closest keyframe",
       "3.4, Eq. 3.7-3.15",
       /*live=*/false,
       methods::TextureMode::kRotationClosest,
       {}},
      &RunRigidCarved, {},
      SegmentFunctions<RigidCarvedOptions>{
          &PrepareRigidCarved, &RigidSegmentPhase<RigidCarvedOptions>,
          &RigidStitchPhase<RigidCarvedOptions>,
          &RigidPhaseNeeds<RigidCarvedOptions, &CarvedPrepareNeeds>});
  return method;
}

}  // namespace reenact::recon
