#include "server/recon/cylinders/cylinders.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::recon {
namespace {

using body::KinectV2Joint;
using Eigen::Vector2d;
using Eigen::Vector3d;
using J = KinectV2Joint;
using P = BodyPart;

const Vector3d& Joint(const JointArray& joints, J j) { return joints[body::Index(j)]; }

double AngleRad(const Vector3d& a, const Vector3d& b) {
  const double n = a.norm() * b.norm();
  if (!(n > 0)) return 0.0;
  return std::acos(std::clamp(a.dot(b) / n, -1.0, 1.0));
}

// Where along the bone (fractions of proximal -> distal) the width is
// measured; see the header.
std::pair<double, double> MeasureRange(P part) {
  switch (part) {
    case P::kHead:
      return {0.7, 1.4};
    case P::kChest:
      return {0.2, 0.7};
    case P::kAbdomen:
      return {0.2, 0.8};
    case P::kHandLeft:
    case P::kHandRight:
      return {0.2, 0.6};
    case P::kThighLeft:
    case P::kThighRight:
      return {0.35, 0.75};
    case P::kFootLeft:
    case P::kFootRight:
      return {0.3, 0.8};
    default:
      return {0.25, 0.75};
  }
}

std::optional<P> MirrorPart(P part) {
  switch (part) {
    case P::kUpperArmLeft:
      return P::kUpperArmRight;
    case P::kForearmLeft:
      return P::kForearmRight;
    case P::kHandLeft:
      return P::kHandRight;
    case P::kThighLeft:
      return P::kThighRight;
    case P::kShinLeft:
      return P::kShinRight;
    case P::kFootLeft:
      return P::kFootRight;
    case P::kUpperArmRight:
      return P::kUpperArmLeft;
    case P::kForearmRight:
      return P::kForearmLeft;
    case P::kHandRight:
      return P::kHandLeft;
    case P::kThighRight:
      return P::kThighLeft;
    case P::kShinRight:
      return P::kShinLeft;
    case P::kFootRight:
      return P::kFootLeft;
    default:
      return std::nullopt;
  }
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  double m = values[mid];
  if (values.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(values.begin(), values.begin() + mid));
  }
  return m;
}

constexpr int kLinesPerPart = 15;
constexpr int kMinLines = 4;
constexpr double kMinProjectedBonePx = 6.0;
constexpr double kStepPx = 0.5;
constexpr double kMaxGapPx = 1.5;

// Joints that span the 15 parts and enter Eq. 3.4.
std::vector<J> RequiredJoints() {
  std::vector<J> joints;
  for (const BodyPartInfo& info : BodyParts()) {
    joints.push_back(info.proximal);
    joints.push_back(info.distal);
  }
  for (J j : {J::kSpineBase, J::kSpineShoulder, J::kShoulderLeft, J::kShoulderRight, J::kWristLeft,
              J::kWristRight, J::kHipLeft, J::kHipRight, J::kAnkleLeft, J::kAnkleRight}) {
    joints.push_back(j);
  }
  return joints;
}

// True when every joint the method needs is present and projects into the
// depth image in front of the camera.
bool SkeletonInView(const JointArray& joints_in_depth, const CameraIntrinsics& k) {
  static const std::vector<J> required = RequiredJoints();
  for (J j : required) {
    const Vector3d& p = Joint(joints_in_depth, j);
    if (!IsJointValid(p) || p.z() <= 0.1) return false;
    auto pixel = k.Project(p);
    if (!pixel || !k.IsInside(*pixel)) return false;
  }
  return true;
}

JointArray ToDepthFrame(const JointArray& joints_in_world, const Rigid3d& world_from_depth) {
  const Rigid3d depth_from_world = world_from_depth.Inverse();
  JointArray out = MissingJoints();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (IsJointValid(joints_in_world[j])) out[j] = depth_from_world * joints_in_world[j];
  }
  return out;
}

// Half-widths of the actor on one measurement line: walks from `centre`
// along +-`normal` (unit, pixels) while pixels are actor with depth inside
// [near_m, far_m]. nullopt when the centre pixel is not such a pixel or a
// walk reaches `max_px` (the line ran into something else).
std::optional<std::pair<double, double>> WalkLine(const Vector2d& centre, const Vector2d& normal,
                                                  double near_m, double far_m, double max_px,
                                                  const DepthImageMm& depth,
                                                  const MaskImage& actor) {
  auto accept = [&](const Vector2d& q) -> std::optional<bool> {
    const int x = static_cast<int>(std::lround(q.x()));
    const int y = static_cast<int>(std::lround(q.y()));
    if (x < 0 || y < 0 || x >= depth.width || y >= depth.height) return std::nullopt;
    if (actor.at(x, y) == 0) return false;
    const double z = depth.at(x, y) * 1e-3;
    return z >= near_m && z <= far_m;
  };
  auto centre_ok = accept(centre);
  if (!centre_ok || !*centre_ok) return std::nullopt;
  double extent[2] = {0.0, 0.0};
  for (int side = 0; side < 2; ++side) {
    const Vector2d dir = side == 0 ? normal : Vector2d(-normal);
    double last_ok = 0.0, gap = 0.0;
    bool hit_limit = true;
    for (double s = kStepPx; s <= max_px; s += kStepPx) {
      auto ok = accept(centre + s * dir);
      if (!ok) {  // Left the image.
        hit_limit = false;
        break;
      }
      if (*ok) {
        last_ok = s;
        gap = 0.0;
      } else {
        gap += kStepPx;
        if (gap > kMaxGapPx) {
          hit_limit = false;
          break;
        }
      }
    }
    if (hit_limit) return std::nullopt;
    // Nearest-pixel lookups accept points up to the edge of the last actor
    // pixel's footprint, which is where the silhouette lies (a pixel is the
    // actor's when its centre is); the edge is on average half a step past
    // the last accepted point.
    extent[side] = last_ok + 0.5 * kStepPx;
  }
  return std::make_pair(extent[0], extent[1]);
}

// One part's rectangle (see the header); nullopt when it cannot be measured.
std::optional<PartRadius> FitPart(P part, const JointArray& joints, const DepthImageMm& depth,
                                  const MaskImage& actor, const CameraIntrinsics& k,
                                  const CylinderOptions& options) {
  const BodyPartInfo& info = GetBodyPartInfo(part);
  const Vector3d a = Joint(joints, info.proximal);
  const Vector3d b = Joint(joints, info.distal);
  if (!IsJointValid(a) || !IsJointValid(b) || a.z() <= 0.1 || b.z() <= 0.1) return std::nullopt;
  const double length = (b - a).norm();
  if (length < 1e-3) return std::nullopt;
  auto pa = k.Project(a), pb = k.Project(b);
  if (!pa || !pb || (*pb - *pa).norm() < kMinProjectedBonePx) return std::nullopt;
  const double expected_r = DefaultRadiusRate(part) * length;
  const auto [t0, t1] = MeasureRange(part);
  std::vector<double> radii;
  for (int line = 0; line < kLinesPerPart; ++line) {
    const double t = t0 + (t1 - t0) * (line + 0.5) / kLinesPerPart;
    const Vector3d axis_point = a + t * (b - a);
    auto centre = k.Project(axis_point);
    auto ahead = k.Project(axis_point + 0.01 * (b - a) / length);
    if (!centre || !ahead || (*ahead - *centre).norm() < 1e-9) continue;
    const Vector2d along = (*ahead - *centre).normalized();
    const Vector2d normal(-along.y(), along.x());
    const double z = axis_point.z();
    const double near_m = z - 1.5 * expected_r - options.depth_window_m;
    const double far_m = z + options.depth_window_m;
    // Farther than three expected radii from the axis is another part.
    const double max_px = 3.0 * expected_r * k.fx / z + 4.0;
    auto extents = WalkLine(*centre, normal, near_m, far_m, max_px, depth, actor);
    if (!extents) continue;
    // The edge points at the axis's depth: the silhouette of a cylinder
    // grazes it at about the axis's depth.
    auto left = k.Unproject(*centre + extents->first * normal, z);
    auto right = k.Unproject(*centre - extents->second * normal, z);
    if (!left || !right) continue;
    radii.push_back(0.5 * (*left - *right).norm());
  }
  if (static_cast<int>(radii.size()) < kMinLines) return std::nullopt;
  PartRadius fit;
  fit.radius_m = Median(radii);
  fit.length_m = length;
  fit.radius_rate = fit.radius_m / length;
  fit.lines = static_cast<int>(radii.size());
  fit.fitted = true;
  return fit;
}

}  // namespace

absl::Status CylinderOptions::Read(OptionReader& reader) {
  RETURN_IF_ERROR(
      reader.Double("lambda", &lambda, 0.0, 100.0, "weight of the leg-crossing term of Eq. 3.4"));
  RETURN_IF_ERROR(reader.Int("representative_instant", &representative_instant, -1, INT_MAX,
                             "force the representative frame's instant (-1: Eq. 3.5)"));
  RETURN_IF_ERROR(reader.Int("representative_sensor", &representative_sensor, -1, INT_MAX,
                             "force the representative frame's sensor index (-1: Eq. 3.5)"));
  RETURN_IF_ERROR(reader.Double("depth_window_m", &depth_window_m, 0.001, 2.0,
                                "depth window around the bone for a part's width, metres"));
  RETURN_IF_ERROR(reader.Int("segments", &segments, 3, 256, "cylinder segments round"));
  RETURN_IF_ERROR(reader.Int("rings", &rings, 1, 256, "cylinder rings along the bone"));
  RETURN_IF_ERROR(reader.Double("head_top_extension", &head_top_extension, 0.0, 3.0,
                                "head cylinder past the Head joint, bone lengths"));
  RETURN_IF_ERROR(texturing.Read(reader));
  return Validate();
}

int64_t CylinderOptions::MemoryBytes(const TakeSize& take) const {
  // As MakeCylinderMesh (below) lays them out, for each of the parts.
  const int parts = static_cast<int>(BodyPartNames().size());
  const int64_t part_triangles = int64_t{2} * segments * rings + int64_t{2} * segments;
  const int64_t part_vertices = int64_t{rings + 1} * segments + int64_t{2} * (segments + 1);
  // The representative frame: its colour and depth of every sensor.
  const int64_t representative =
      int64_t{std::max(take.sensors, 1)} * (memory::kColourFrameBytes + memory::kDepthFrameBytes);
  return representative + memory::MeshBytes(parts * part_triangles) +
         texturing.MemoryBytes(take, std::vector<int64_t>(parts, part_triangles),
                               parts * part_vertices);
}

absl::Status CylinderOptions::Validate() const {
  if (!(lambda >= 0) || !std::isfinite(lambda)) {
    return absl::InvalidArgumentError("lambda must be a finite number >= 0");
  }
  if ((representative_instant < 0) != (representative_sensor < 0)) {
    return absl::InvalidArgumentError(
        "representative_instant and representative_sensor go together");
  }
  if (!(depth_window_m > 0) || !std::isfinite(depth_window_m)) {
    return absl::InvalidArgumentError("depth_window_m must be > 0");
  }
  if (segments < 3) return absl::InvalidArgumentError("segments must be >= 3");
  if (rings < 1) return absl::InvalidArgumentError("rings must be >= 1");
  if (!(head_top_extension >= 0) || !std::isfinite(head_top_extension)) {
    return absl::InvalidArgumentError("head_top_extension must be >= 0");
  }
  return texturing.Validate();
}

RepresentativeScore ScoreRepresentative(const JointArray& joints, double lambda) {
  RepresentativeScore s;
  for (J j : {J::kSpineBase, J::kSpineShoulder, J::kShoulderLeft, J::kShoulderRight, J::kWristLeft,
              J::kWristRight, J::kHipLeft, J::kHipRight, J::kAnkleLeft, J::kAnkleRight}) {
    if (!IsJointValid(Joint(joints, j))) return s;
  }
  const Vector3d torso = Joint(joints, J::kSpineBase) - Joint(joints, J::kSpineShoulder);
  const Vector3d arm_l = Joint(joints, J::kWristLeft) - Joint(joints, J::kShoulderLeft);
  const Vector3d arm_r = Joint(joints, J::kWristRight) - Joint(joints, J::kShoulderRight);
  const Vector3d leg_l = Joint(joints, J::kAnkleLeft) - Joint(joints, J::kHipLeft);
  const Vector3d leg_r = Joint(joints, J::kAnkleRight) - Joint(joints, J::kHipRight);
  if (torso.norm() < 1e-6 || arm_l.norm() < 1e-6 || arm_r.norm() < 1e-6) return s;
  s.theta_left_rad = AngleRad(torso, arm_l);
  s.theta_right_rad = AngleRad(torso, arm_r);
  s.a_left = std::abs(arm_l.normalized().x());  // |a|: see the header.
  s.a_right = std::abs(arm_r.normalized().x());
  s.phi_left_rad = AngleRad(Vector3d::UnitX(), leg_l);
  s.phi_right_rad = AngleRad(Vector3d::UnitX(), leg_r);
  s.g = s.phi_right_rad > s.phi_left_rad ? 1.0 : 0.0;  // Eq. 3.3.
  // Eq. 3.4.
  s.e = s.theta_left_rad * s.a_left + s.theta_right_rad * s.a_right + lambda * s.g;
  s.valid = true;
  return s;
}

absl::StatusOr<RepresentativeFrame> FindRepresentativeFrame(const TakeFrames& take,
                                                            const CylinderOptions& options) {
  RepresentativeFrame best;
  auto consider = [&](int i, int s) -> bool {
    const Instant& instant = take.instant(i);
    if (!instant.valid || !instant.views[s].present) return false;
    const TakeSensor& sensor = take.sensors()[s];
    const JointArray joints = ToDepthFrame(instant.joints_in_world_m, sensor.world_from_depth);
    if (!SkeletonInView(joints, sensor.depth_intrinsics)) return false;
    const RepresentativeScore score = ScoreRepresentative(joints, options.lambda);
    if (!score.valid) return false;
    if (best.instant < 0 || score.e > best.score.e) best = {i, s, score};
    return true;
  };
  if (options.representative_instant >= 0) {
    const int i = options.representative_instant, s = options.representative_sensor;
    if (i >= take.num_instants() || s >= take.num_sensors() || !consider(i, s)) {
      return absl::InvalidArgumentError(
          absl::StrCat("representative_instant ", i, " / representative_sensor ", s,
                       " is not a view with a complete skeleton inside the depth image"));
    }
    return best;
  }
  // Eq. 3.5: argmax_n E(n), over every (instant, sensor).
  for (int i = 0; i < take.num_instants(); ++i) {
    for (int s = 0; s < take.num_sensors(); ++s) consider(i, s);
  }
  if (best.instant < 0) {
    return absl::InvalidArgumentError(
        "no instant of the take has a complete skeleton inside a sensor's depth image");
  }
  return best;
}

double DefaultRadiusRate(BodyPart part) {
  // r / l from adult proportions (stature H; Winter's segment lengths and
  // breadths): head radius ~0.05H over Neck->Head ~0.07H; chest half-breadth
  // ~0.095H over SpineMid->SpineShoulder ~0.15H; abdomen ~0.086H / 0.12H;
  // upper arm ~0.03H / 0.186H; forearm ~0.021H / 0.146H; hand (flat, half
  // breadth) ~0.025H / 0.1H; thigh ~0.042H / 0.245H; shin ~0.028H / 0.246H;
  // foot ~0.024H / 0.1H.
  switch (part) {
    case P::kHead:
      return 0.70;
    case P::kChest:
      return 0.62;
    case P::kAbdomen:
      return 0.72;
    case P::kUpperArmLeft:
    case P::kUpperArmRight:
      return 0.16;
    case P::kForearmLeft:
    case P::kForearmRight:
      return 0.145;
    case P::kHandLeft:
    case P::kHandRight:
      return 0.25;
    case P::kThighLeft:
    case P::kThighRight:
      return 0.17;
    case P::kShinLeft:
    case P::kShinRight:
      return 0.115;
    case P::kFootLeft:
    case P::kFootRight:
      return 0.24;
  }
  return 0.15;
}

absl::StatusOr<std::array<PartRadius, kNumBodyParts>> FitPartRadii(
    const JointArray& joints_in_depth_m, const DepthImageMm& depth_mm, const MaskImage& actor,
    const CameraIntrinsics& k, const CylinderOptions& options) {
  RETURN_IF_ERROR(k.Validate());
  if (depth_mm.width != k.width || depth_mm.height != k.height || actor.width != k.width ||
      actor.height != k.height || depth_mm.data.size() != depth_mm.num_pixels() ||
      actor.data.size() != actor.num_pixels()) {
    return absl::InvalidArgumentError(absl::StrCat("depth ", depth_mm.width, "x", depth_mm.height,
                                                   " and mask ", actor.width, "x", actor.height,
                                                   " must both be ", k.width, "x", k.height));
  }
  std::array<PartRadius, kNumBodyParts> radii;
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (auto fit = FitPart(static_cast<P>(p), joints_in_depth_m, depth_mm, actor, k, options)) {
      radii[p] = *fit;
    }
  }
  // Unmeasured parts: the mirror part's rate when that was measured, else
  // the default rate.
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (radii[p].fitted) continue;
    const P part = static_cast<P>(p);
    const BodyPartInfo& info = GetBodyPartInfo(part);
    const Vector3d a = Joint(joints_in_depth_m, info.proximal);
    const Vector3d b = Joint(joints_in_depth_m, info.distal);
    radii[p].length_m = IsJointValid(a) && IsJointValid(b) ? (b - a).norm() : 0.0;
    const auto mirror = MirrorPart(part);
    radii[p].radius_rate = mirror && radii[Index(*mirror)].fitted
                               ? radii[Index(*mirror)].radius_rate
                               : DefaultRadiusRate(part);
    radii[p].radius_m = radii[p].radius_rate * radii[p].length_m;
  }
  return radii;
}

PartMesh MakeCylinderGeometry(double radius_m, double y0_m, double y1_m, int segments, int rings) {
  segments = std::max(segments, 3);
  rings = std::max(rings, 1);
  const int side_vertices = (rings + 1) * segments;
  const int cap_vertices = 2 * (segments + 1);
  PartMesh g;
  g.positions_in_part_m.resize(3, side_vertices + cap_vertices);
  g.normals_in_part.resize(3, side_vertices + cap_vertices);
  auto set = [&](int v, double x, double y, double z, double nx, double ny, double nz) {
    g.positions_in_part_m.col(v) = Eigen::Vector3f(x, y, z);
    g.normals_in_part.col(v) = Eigen::Vector3f(nx, ny, nz);
  };
  auto side = [&](int ring, int seg) { return ring * segments + (seg % segments); };
  for (int ring = 0; ring <= rings; ++ring) {
    const double y = y0_m + (y1_m - y0_m) * ring / rings;
    for (int seg = 0; seg < segments; ++seg) {
      const double theta = 2.0 * M_PI * seg / segments;
      const double c = std::cos(theta), s = std::sin(theta);
      set(side(ring, seg), radius_m * c, y, radius_m * s, c, 0.0, s);
    }
  }
  // Side quads, counter-clockwise seen from outside (see the tests).
  for (int ring = 0; ring < rings; ++ring) {
    for (int seg = 0; seg < segments; ++seg) {
      g.triangles.emplace_back(side(ring, seg), side(ring + 1, seg), side(ring, seg + 1));
      g.triangles.emplace_back(side(ring, seg + 1), side(ring + 1, seg), side(ring + 1, seg + 1));
    }
  }
  // Caps: a centre vertex and a ring of their own (flat normals).
  for (int cap = 0; cap < 2; ++cap) {
    const int base = side_vertices + cap * (segments + 1);
    const double y = cap == 0 ? y0_m : y1_m;
    const double ny = cap == 0 ? -1.0 : 1.0;
    set(base, 0.0, y, 0.0, 0.0, ny, 0.0);
    for (int seg = 0; seg < segments; ++seg) {
      const double theta = 2.0 * M_PI * seg / segments;
      set(base + 1 + seg, radius_m * std::cos(theta), y, radius_m * std::sin(theta), 0.0, ny, 0.0);
    }
    for (int seg = 0; seg < segments; ++seg) {
      const int v0 = base + 1 + seg, v1 = base + 1 + (seg + 1) % segments;
      if (cap == 0) {
        g.triangles.emplace_back(base, v0, v1);  // Seen from below.
      } else {
        g.triangles.emplace_back(base, v1, v0);  // Seen from above.
      }
    }
  }
  return g;
}

PartMesh ToPartMesh(BodyPart part, PartMesh geometry, float radius_rate, float reference_length_m) {
  geometry.part = Index(part);
  geometry.name = std::string(GetBodyPartInfo(part).name);
  geometry.radius_rate = radius_rate;
  geometry.reference_length_m = reference_length_m;
  return geometry;
}

absl::StatusOr<CylinderModel> FitCylinderModel(const TakeFrames& take,
                                               const CylinderOptions& options) {
  CylinderModel model;
  ASSIGN_OR_RETURN(model.representative, FindRepresentativeFrame(take, options));
  const int i = model.representative.instant, s = model.representative.sensor;
  ASSIGN_OR_RETURN(DepthImageMm depth, take.LoadDepth(i, s));
  ASSIGN_OR_RETURN(MaskImage actor, take.LoadActorMask(i, s));
  const TakeSensor& sensor = take.sensors()[s];
  const JointArray joints =
      ToDepthFrame(take.instant(i).joints_in_world_m, sensor.world_from_depth);
  ASSIGN_OR_RETURN(model.radii,
                   FitPartRadii(joints, depth, actor, sensor.depth_intrinsics, options));
  // l_ref: the median bone length over the valid instants.
  std::array<std::vector<double>, kNumBodyParts> lengths;
  for (const Instant& instant : take.instants()) {
    if (!instant.valid) continue;
    const PartPoses poses = PartPosesFromJoints(instant.joints_in_world_m);
    for (int p = 0; p < kNumBodyParts; ++p) {
      if (poses[p].valid) lengths[p].push_back(poses[p].length_m);
    }
  }
  for (int p = 0; p < kNumBodyParts; ++p) {
    double l = Median(lengths[p]);
    if (!(l > 1e-3)) l = model.radii[p].length_m > 1e-3 ? model.radii[p].length_m : 0.1;
    model.reference_length_m[p] = l;
  }
  return model;
}

namespace {

// The method up to texturing: the cylinders (Eq. 3.3-3.5) and every
// instant's poses, with their figures, frame_count, fps and part names.
absl::StatusOr<Reenactment> UntexturedCylinders(const TakeFrames& take,
                                                const CylinderOptions& options,
                                                const StageProgress& stages,
                                                const LogCallback& log) {
  // Shape: Eq. 3.3-3.5, rectangles, radius rates.
  RETURN_IF_ERROR(stages.Report("shape", 0, 1));
  ASSIGN_OR_RETURN(const CylinderModel model, FitCylinderModel(take, options));
  RETURN_IF_ERROR(stages.Report("shape", 1, 1));
  Reenactment data;
  int fitted = 0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const P part = static_cast<P>(p);
    const double l_ref = model.reference_length_m[p];
    const double rate = model.radii[p].radius_rate;
    const double y1 = part == P::kHead ? l_ref * (1.0 + options.head_top_extension) : l_ref;
    data.parts.push_back(ToPartMesh(
        part, MakeCylinderGeometry(rate * l_ref, 0.0, y1, options.segments, options.rings),
        static_cast<float>(rate), static_cast<float>(l_ref)));
    fitted += model.radii[p].fitted ? 1 : 0;
    data.info.figures[absl::StrCat("radius_mm.", std::string(GetBodyPartInfo(part).name))] =
        1e3 * rate * l_ref;
  }
  if (log) {
    const RepresentativeScore& score = model.representative.score;
    std::string defaults;
    for (int p = 0; p < kNumBodyParts; ++p) {
      if (model.radii[p].fitted) continue;
      absl::StrAppend(&defaults, defaults.empty() ? " (not measured: " : ", ",
                      std::string(BodyParts()[p].name));
    }
    if (!defaults.empty()) defaults += ")";
    log(absl::StrCat("shape: representative frame ", model.representative.instant, " (sensor ",
                     take.sensors()[model.representative.sensor].sensor_id, ", E = ", score.e,
                     "), ", fitted, "/", kNumBodyParts, " parts measured", defaults));
  }

  // Pose: per instant the part frames of the fused skeleton, scaled by
  // l_n / l_ref so that the radius stays r/l of the length (3.3.1).
  const int n = take.num_instants();
  for (int i = 0; i < n; ++i) {
    const Instant& instant = take.instant(i);
    PartPoses poses;  // All invalid by default.
    if (instant.valid) poses = PartPosesFromJoints(instant.joints_in_world_m);
    std::array<double, kNumBodyParts> scales;
    for (int p = 0; p < kNumBodyParts; ++p) {
      scales[p] = poses[p].valid ? poses[p].length_m / model.reference_length_m[p] : 1.0;
    }
    data.frames.push_back(
        MakePartFrame(i, instant.stamp_ns, poses, scales, instant.joints_in_world_m));
    if (i % 64 == 0 || i + 1 == n) RETURN_IF_ERROR(stages.Report("pose", i + 1, n));
  }

  auto& figures = data.info.figures;
  figures["representative_frame"] = model.representative.instant;
  figures["representative_sensor"] = model.representative.sensor;
  figures["representative_score"] = model.representative.score.e;
  figures["parts_measured"] = fitted;
  data.info.frame_count = static_cast<int>(data.frames.size());
  data.info.fps = take.fps();
  data.info.part_names = BodyPartNames();
  return data;
}

}  // namespace

absl::StatusOr<Reenactment> RunRigidCylinders(const TakeFrames& take,
                                              const CylinderOptions& options,
                                              const MethodContext& context) {
  RETURN_IF_ERROR(options.Validate());
  const StageProgress stages(context.progress, {{"shape", 0.05}, {"pose", 0.05}, {"texture", 0.9}});
  ASSIGN_OR_RETURN(Reenactment data, UntexturedCylinders(take, options, stages, context.log));
  // Texture keyframes and baking.
  RETURN_IF_ERROR(
      AddRigidTextures(take, options.texturing, &data, stages.ForStage("texture"), context.log)
          .status());
  return data;
}

absl::StatusOr<std::string> PrepareRigidCylinders(const TakeFrames& take,
                                                  const CylinderOptions& options,
                                                  const MethodContext& context) {
  RETURN_IF_ERROR(options.Validate());
  const StageProgress stages(context.progress, {{"shape", 0.5}, {"pose", 0.5}});
  ASSIGN_OR_RETURN(const Reenactment data, UntexturedCylinders(take, options, stages, context.log));
  return PackUntexturedRigid(data, KeyframeStride(take, options.texturing));
}

namespace {

// The representative frame is chosen by the skeletons alone (Eq. 3.5): only
// its depth and actor mask are decoded.
TakeNeeds CylindersPrepareNeeds(const TakeFrames& take, const CylinderOptions& options) {
  TakeNeeds needs;
  const absl::StatusOr<RepresentativeFrame> representative = FindRepresentativeFrame(take, options);
  if (representative.ok()) needs.depth.push_back(representative->instant);
  return needs;
}

}  // namespace

const ReconstructionMethod& RigidCylindersMethod() {
  static const TypedMethod<CylinderOptions> method(
      {"rigid-cylinders",
       "rough shape: a cylinder per body part from one representative frame, textured by the "
       "pose-closest keyframe",
       "3.3, Eq. 3.3-3.6",
       /*live=*/false,
       methods::TextureMode::kPoseClosest,
       {}},
      &RunRigidCylinders, {},
      SegmentFunctions<CylinderOptions>{&PrepareRigidCylinders, &RigidSegmentPhase<CylinderOptions>,
                                        &RigidStitchPhase<CylinderOptions>,
                                        &RigidPhaseNeeds<CylinderOptions, &CylindersPrepareNeeds>});
  return method;
}

}  // namespace reenact::recon
