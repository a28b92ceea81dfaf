#include "common/body/procedural_body.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/shape_space.h"

namespace reenact::body {
namespace {

using Eigen::Matrix3d;
using Eigen::Matrix3Xd;
using Eigen::Vector3d;
using J = KinectV2Joint;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------
// Parts: finer than BodyRegion (sides apart); one UV chart each.

enum Part : uint8_t {
  kPartHead,
  kPartTorso,
  kPartUpperArmL,
  kPartUpperArmR,
  kPartForearmL,
  kPartForearmR,
  kPartHandL,
  kPartHandR,
  kPartThighL,
  kPartThighR,
  kPartShinL,
  kPartShinR,
  kPartFootL,
  kPartFootR,
  kNumParts
};

// Side-free region of a part.
BodyRegion RegionOfPart(int part) {
  static constexpr BodyRegion kRegion[kNumParts] = {
      BodyRegion::kHead,    BodyRegion::kTorso,   BodyRegion::kUpperArm, BodyRegion::kUpperArm,
      BodyRegion::kForearm, BodyRegion::kForearm, BodyRegion::kHand,     BodyRegion::kHand,
      BodyRegion::kThigh,   BodyRegion::kThigh,   BodyRegion::kShin,     BodyRegion::kShin,
      BodyRegion::kFoot,    BodyRegion::kFoot};
  return kRegion[part];
}

// Limb a part belongs to: 0 axial (head, torso), 1 left arm, 2 right arm,
// 3 left leg, 4 right leg.
int LimbOfPart(int part) {
  static constexpr int kLimb[kNumParts] = {0, 0, 1, 2, 1, 2, 1, 2, 3, 4, 3, 4, 3, 4};
  return kLimb[part];
}

// ---------------------------------------------------------------------------
// Implicit primitives. Distances are approximate (exact on the zero set),
// which is all the polygonisation and the smooth union need.

struct Primitive {
  enum class Kind { kEllipsoid, kRoundedCone };
  Kind kind = Kind::kRoundedCone;
  Vector3d a = Vector3d::Zero();             // Ellipsoid centre, or cone start.
  Vector3d b = Vector3d::Zero();             // Ellipsoid radii, or cone end.
  double radius_a = 0.0;                     // Cone radius at a.
  double radius_b = 0.0;                     // Cone radius at b.
  Vector3d squash_axis = Vector3d::UnitX();  // Cone: flattened direction.
  double squash = 1.0;                       // Cone: thickness factor (<= 1).
  int part = kPartTorso;
};

double EllipsoidDistance(const Primitive& e, const Vector3d& p) {
  const Vector3d q = (p - e.a).cwiseQuotient(e.b);
  return (q.norm() - 1.0) * e.b.minCoeff();
}

// A cone whose radius varies linearly from a to b, with spherical-ish caps,
// optionally flattened across `squash_axis`.
double RoundedConeDistance(const Primitive& c, const Vector3d& p) {
  const Vector3d axis = c.b - c.a;
  const double t = std::clamp((p - c.a).dot(axis) / axis.squaredNorm(), 0.0, 1.0);
  Vector3d q = p - (c.a + t * axis);
  const double across = q.dot(c.squash_axis);
  q += c.squash_axis * (across / c.squash - across);
  const double radius = c.radius_a + t * (c.radius_b - c.radius_a);
  return (q.norm() - radius) * c.squash;
}

double PrimitiveDistance(const Primitive& primitive, const Vector3d& p) {
  return primitive.kind == Primitive::Kind::kEllipsoid ? EllipsoidDistance(primitive, p)
                                                       : RoundedConeDistance(primitive, p);
}

// Polynomial smooth minimum with blend width k (Quilez, "smooth minimum",
// iquilezles.org/articles/smin): min(a, b) - h^2 k / 4, h = max(k-|a-b|,0)/k.
double SmoothMin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

// ---------------------------------------------------------------------------
// The neutral body: joints and primitives from stature ratios.

struct Layout {
  double stature_m = 0.0;
  std::array<Vector3d, kNumKinectV2Joints> joints_m;
  // Primitives per blend group: [0] trunk and head, [1..2] arms L/R,
  // [3..4] legs L/R.
  std::array<std::vector<Primitive>, 5> groups;
  double k_trunk_m = 0.0;   // Blend width inside the trunk.
  double k_limb_m = 0.0;    // Blend width inside a limb.
  double k_attach_m = 0.0;  // Blend width of limbs onto the trunk.
  // Extra skinning points: top of the head, toe tips and heels.
  Vector3d head_top_m, toe_tip_m[2], heel_m[2];
};

Primitive Ellipsoid(const Vector3d& centre, const Vector3d& radii, int part) {
  Primitive e;
  e.kind = Primitive::Kind::kEllipsoid;
  e.a = centre;
  e.b = radii;
  e.part = part;
  return e;
}

Primitive Cone(const Vector3d& a, const Vector3d& b, double radius_a, double radius_b, int part,
               const Vector3d& squash_axis = Vector3d::UnitX(), double squash = 1.0) {
  Primitive c;
  c.a = a;
  c.b = b;
  c.radius_a = radius_a;
  c.radius_b = radius_b;
  c.part = part;
  c.squash_axis = squash_axis;
  c.squash = squash;
  return c;
}

// Trunk, neck and head. Heights are fractions of stature H (Winter Fig. 4.1:
// shoulder 0.818H, chin 0.870H; head height 0.130H so its centre sits at
// 0.935H). Widths and depths after adult breadths (chest ~0.18H, hip
// breadth ~0.20H, chest depth ~0.14H).
void AddTrunk(double h, Layout& layout) {
  auto& g = layout.groups[0];
  g.push_back(
      Ellipsoid(h * Vector3d(0, 0.540, -0.005), h * Vector3d(0.098, 0.072, 0.068), kPartTorso));
  g.push_back(
      Ellipsoid(h * Vector3d(0, 0.630, 0.0), h * Vector3d(0.086, 0.085, 0.062), kPartTorso));
  g.push_back(
      Ellipsoid(h * Vector3d(0, 0.725, 0.0), h * Vector3d(0.095, 0.100, 0.068), kPartTorso));
  g.push_back(Cone(h * Vector3d(-0.105, 0.800, -0.010), h * Vector3d(0.105, 0.800, -0.010),
                   0.040 * h, 0.040 * h, kPartTorso));
  g.push_back(Cone(h * Vector3d(0, 0.800, -0.010), h * Vector3d(0, 0.900, -0.005), 0.034 * h,
                   0.031 * h, kPartHead));
  g.push_back(
      Ellipsoid(h * Vector3d(0, 0.935, 0.008), h * Vector3d(0.044, 0.065, 0.055), kPartHead));
}

// One arm in the A-pose; side = +1 left (+X), -1 right.
void AddArm(double h, double angle_rad, double side, Layout& layout) {
  const bool left = side > 0;
  const Vector3d along(side * std::cos(angle_rad), -std::sin(angle_rad), 0.0);
  // Palm normal: in the frontal plane, towards the thigh.
  const Vector3d palm(-side * std::sin(angle_rad), -std::cos(angle_rad), 0.0);
  const Vector3d forward = Vector3d::UnitZ();
  auto& jt = layout.joints_m;
  const Vector3d shoulder = h * Vector3d(side * 0.1295, 0.818, 0.0);  // 0.259H apart.
  const Vector3d elbow = shoulder + 0.186 * h * along;                // Upper arm 0.186H.
  const Vector3d wrist = elbow + 0.146 * h * along;                   // Forearm 0.146H.
  jt[Index(left ? J::kShoulderLeft : J::kShoulderRight)] = shoulder;
  jt[Index(left ? J::kElbowLeft : J::kElbowRight)] = elbow;
  jt[Index(left ? J::kWristLeft : J::kWristRight)] = wrist;
  jt[Index(left ? J::kHandLeft : J::kHandRight)] = wrist + 0.050 * h * along;
  // Hand length 0.108H; the joint is the centre of the fingertip cap.
  jt[Index(left ? J::kHandTipLeft : J::kHandTipRight)] = wrist + 0.096 * h * along;
  const Vector3d thumb_tip = wrist + h * (0.045 * along + 0.036 * forward);
  jt[Index(left ? J::kThumbLeft : J::kThumbRight)] = thumb_tip;

  auto& g = layout.groups[left ? 1 : 2];
  g.push_back(Cone(shoulder, elbow, 0.033 * h, 0.026 * h, left ? kPartUpperArmL : kPartUpperArmR));
  g.push_back(
      Cone(elbow, wrist, 0.025 * h, 0.017 * h, left ? kPartForearmL : kPartForearmR, palm, 0.8));
  const int hand = left ? kPartHandL : kPartHandR;
  const Vector3d knuckles = wrist + 0.055 * h * along;
  g.push_back(Cone(wrist, knuckles, 0.019 * h, 0.024 * h, hand, palm, 0.42));
  g.push_back(Cone(knuckles, wrist + 0.096 * h * along, 0.023 * h, 0.012 * h, hand, palm, 0.5));
  g.push_back(
      Cone(wrist + h * (0.012 * along + 0.010 * forward), thumb_tip, 0.0085 * h, 0.0072 * h, hand));
}

// One leg; hip joint centres 0.103H apart (Bell et al. 1990: about 0.36 of
// the inter-ASIS width from the midline), knee 0.285H, ankle 0.039H, foot
// length 0.152H (Winter Fig. 4.1). Feet a little apart.
void AddLeg(double h, double side, Layout& layout) {
  const bool left = side > 0;
  auto& jt = layout.joints_m;
  const Vector3d hip = h * Vector3d(side * 0.0515, 0.530, 0.0);
  const Vector3d knee = h * Vector3d(side * 0.060, 0.285, 0.0);
  const Vector3d ankle = h * Vector3d(side * 0.068, 0.039, -0.005);
  const Vector3d heel = h * Vector3d(side * 0.068, 0.021, -0.012);
  const Vector3d toe = h * Vector3d(side * 0.074, 0.016, 0.093);
  jt[Index(left ? J::kHipLeft : J::kHipRight)] = hip;
  jt[Index(left ? J::kKneeLeft : J::kKneeRight)] = knee;
  jt[Index(left ? J::kAnkleLeft : J::kAnkleRight)] = ankle;
  jt[Index(left ? J::kFootLeft : J::kFootRight)] = toe;
  const int s = left ? 0 : 1;
  layout.heel_m[s] = heel - h * Vector3d(0, 0, 0.02);
  layout.toe_tip_m[s] = toe + h * Vector3d(0, 0, 0.02);

  auto& g = layout.groups[left ? 3 : 4];
  g.push_back(Cone(hip, knee, 0.049 * h, 0.034 * h, left ? kPartThighL : kPartThighR));
  g.push_back(Cone(knee, ankle, 0.034 * h, 0.021 * h, left ? kPartShinL : kPartShinR));
  // Calf muscle, behind the upper shin.
  g.push_back(Ellipsoid(h * Vector3d(side * 0.062, 0.215, -0.010),
                        h * Vector3d(0.030, 0.060, 0.033), left ? kPartShinL : kPartShinR));
  g.push_back(Cone(heel, toe, 0.027 * h, 0.020 * h, left ? kPartFootL : kPartFootR,
                   Vector3d::UnitY(), 0.75));
}

Layout MakeLayout(double h, double arm_angle_rad) {
  Layout layout;
  layout.stature_m = h;
  auto& jt = layout.joints_m;
  jt[Index(J::kSpineBase)] = h * Vector3d(0, 0.545, 0.0);
  jt[Index(J::kSpineMid)] = h * Vector3d(0, 0.665, 0.0);
  jt[Index(J::kSpineShoulder)] = h * Vector3d(0, 0.818, 0.0);
  jt[Index(J::kNeck)] = h * Vector3d(0, 0.865, -0.005);
  jt[Index(J::kHead)] = h * Vector3d(0, 0.935, 0.008);
  layout.head_top_m = h * Vector3d(0, 0.990, 0.008);
  AddTrunk(h, layout);
  AddArm(h, arm_angle_rad, +1.0, layout);
  AddArm(h, arm_angle_rad, -1.0, layout);
  AddLeg(h, +1.0, layout);
  AddLeg(h, -1.0, layout);
  layout.k_trunk_m = 0.035 * h;
  layout.k_limb_m = 0.012 * h;
  layout.k_attach_m = 0.028 * h;
  return layout;
}

// Signed distance of the body: each limb is a smooth union of its own
// primitives; arms (and legs) are joined to each other by a hard minimum so
// they never bridge, then smoothly onto the trunk.
double BodyDistance(const Layout& layout, const Vector3d& p) {
  auto group_distance = [&](int group, double k) {
    double d = 1e9;
    for (const Primitive& primitive : layout.groups[group]) {
      d = SmoothMin(d, PrimitiveDistance(primitive, p), k);
    }
    return d;
  };
  const double trunk = group_distance(0, layout.k_trunk_m);
  const double arms =
      std::min(group_distance(1, layout.k_limb_m), group_distance(2, layout.k_limb_m));
  const double legs =
      std::min(group_distance(3, layout.k_limb_m), group_distance(4, layout.k_limb_m));
  return SmoothMin(SmoothMin(trunk, arms, layout.k_attach_m), legs, layout.k_attach_m);
}

// Part of the primitive nearest to p.
int NearestPart(const Layout& layout, const Vector3d& p) {
  double best = 1e9;
  int part = kPartTorso;
  for (const auto& group : layout.groups) {
    for (const Primitive& primitive : group) {
      const double d = PrimitiveDistance(primitive, p);
      if (d < best) {
        best = d;
        part = primitive.part;
      }
    }
  }
  return part;
}

// ---------------------------------------------------------------------------
// Polygonisation: marching cubes resolved face by face.

struct Mesh {
  Matrix3Xd vertices_m;
  std::vector<Eigen::Vector3i> triangles;
};

struct Grid {
  int nx = 0, ny = 0, nz = 0;
  Vector3d origin_m = Vector3d::Zero();
  double spacing_m = 0.0;
  std::vector<float> value_m;  // Signed distance at each grid point.

  int64_t Id(int i, int j, int k) const {
    return i + static_cast<int64_t>(nx) * (j + static_cast<int64_t>(ny) * k);
  }
  Vector3d Point(int i, int j, int k) const { return origin_m + spacing_m * Vector3d(i, j, k); }
};

Grid SampleBody(const Layout& layout, double spacing_m) {
  Vector3d lo = Vector3d::Constant(1e9), hi = Vector3d::Constant(-1e9);
  for (const auto& group : layout.groups) {
    for (const Primitive& p : group) {
      if (p.kind == Primitive::Kind::kEllipsoid) {
        lo = lo.cwiseMin(p.a - p.b);
        hi = hi.cwiseMax(p.a + p.b);
      } else {
        const double r = std::max(p.radius_a, p.radius_b);
        lo = lo.cwiseMin(p.a.cwiseMin(p.b) - Vector3d::Constant(r));
        hi = hi.cwiseMax(p.a.cwiseMax(p.b) + Vector3d::Constant(r));
      }
    }
  }
  Grid grid;
  grid.spacing_m = spacing_m;
  grid.origin_m = lo - Vector3d::Constant(2.5 * spacing_m);
  const Vector3d extent = hi - lo + Vector3d::Constant(5.0 * spacing_m);
  grid.nx = static_cast<int>(std::ceil(extent.x() / spacing_m)) + 1;
  grid.ny = static_cast<int>(std::ceil(extent.y() / spacing_m)) + 1;
  grid.nz = static_cast<int>(std::ceil(extent.z() / spacing_m)) + 1;
  grid.value_m.resize(static_cast<size_t>(grid.nx) * grid.ny * grid.nz);
  for (int k = 0; k < grid.nz; ++k) {
    for (int j = 0; j < grid.ny; ++j) {
      for (int i = 0; i < grid.nx; ++i) {
        grid.value_m[grid.Id(i, j, k)] =
            static_cast<float>(BodyDistance(layout, grid.Point(i, j, k)));
      }
    }
  }
  return grid;
}

// Local corner c of a cube has offsets (c & 1, (c >> 1) & 1, (c >> 2) & 1).
Eigen::Vector3i CornerOffset(int c) { return {c & 1, (c >> 1) & 1, (c >> 2) & 1}; }

class CubeMarcher {
 public:
  explicit CubeMarcher(const Grid& grid) : grid_(grid) {}

  // Emits the surface polygons of every cube, counter-clockwise seen from
  // outside (f > 0).
  void Run() {
    for (int k = 0; k + 1 < grid_.nz; ++k) {
      for (int j = 0; j + 1 < grid_.ny; ++j) {
        for (int i = 0; i + 1 < grid_.nx; ++i) MarchCube(i, j, k);
      }
    }
  }

  std::vector<Vector3d> vertices_m;
  std::vector<std::vector<int>> polygons;

 private:
  struct Segment {
    int from, to;  // Vertex ids.
  };

  bool Inside(float value) const { return value < 0.0f; }

  // Vertex on the grid edge between local corners a and b of cube (i, j, k).
  int EdgeVertex(int i, int j, int k, int a, int b) {
    if (a > b) std::swap(a, b);  // a is the lower corner along the edge axis.
    const Eigen::Vector3i pa = Eigen::Vector3i(i, j, k) + CornerOffset(a);
    const Eigen::Vector3i pb = Eigen::Vector3i(i, j, k) + CornerOffset(b);
    const int axis = (b - a) == 1 ? 0 : ((b - a) == 2 ? 1 : 2);
    const int64_t key = grid_.Id(pa.x(), pa.y(), pa.z()) * 3 + axis;
    auto [it, inserted] = vertex_of_edge_.try_emplace(key, static_cast<int>(vertices_m.size()));
    if (inserted) {
      const double fa = grid_.value_m[grid_.Id(pa.x(), pa.y(), pa.z())];
      const double fb = grid_.value_m[grid_.Id(pb.x(), pb.y(), pb.z())];
      // Keep crossings off the corners so no two vertices coincide.
      const double t = std::clamp(fa / (fa - fb), 0.02, 0.98);
      const Vector3d xa = grid_.Point(pa.x(), pa.y(), pa.z());
      const Vector3d xb = grid_.Point(pb.x(), pb.y(), pb.z());
      vertices_m.push_back(xa + t * (xb - xa));
    }
    return it->second;
  }

  void MarchCube(int i, int j, int k) {
    float f[8];
    int inside = 0;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3i p = Eigen::Vector3i(i, j, k) + CornerOffset(c);
      f[c] = grid_.value_m[grid_.Id(p.x(), p.y(), p.z())];
      inside += Inside(f[c]) ? 1 : 0;
    }
    if (inside == 0 || inside == 8) return;
    std::vector<Segment> segments;
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) AddFaceSegments(i, j, k, f, axis, side, segments);
    }
    ChainLoops(segments);
  }

  // Segments of one cube face. The face's corners are taken in cyclic order;
  // a face with four crossings is resolved by the asymptotic decider (Nielson
  // & Hamann 1991), which depends on the face's values alone, so the two
  // cubes sharing the face agree.
  void AddFaceSegments(int i, int j, int k, const float f[8], int axis, int side,
                       std::vector<Segment>& segments) {
    const int b = (axis + 1) % 3, c = (axis + 2) % 3;
    static constexpr int kCycle[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    int corner[4];
    for (int q = 0; q < 4; ++q) {
      corner[q] = (side << axis) | (kCycle[q][0] << b) | (kCycle[q][1] << c);
    }
    bool crossing[4];
    int num_crossings = 0;
    for (int q = 0; q < 4; ++q) {
      crossing[q] = Inside(f[corner[q]]) != Inside(f[corner[(q + 1) % 4]]);
      num_crossings += crossing[q] ? 1 : 0;
    }
    if (num_crossings == 0) return;
    // Pairs of face edges (edge q joins cyclic corners q and q + 1).
    std::vector<std::pair<int, int>> pairs;
    if (num_crossings == 2) {
      int first = -1, second = -1;
      for (int q = 0; q < 4; ++q) {
        if (!crossing[q]) continue;
        (first < 0 ? first : second) = q;
      }
      pairs.push_back({first, second});
    } else {
      const double f0 = f[corner[0]], f1 = f[corner[1]], f2 = f[corner[2]], f3 = f[corner[3]];
      const double saddle = (f0 * f2 - f1 * f3) / (f0 + f2 - f1 - f3);
      // Cut off the two corners whose sign differs from the saddle's.
      const bool saddle_inside = saddle < 0.0;
      for (int q = 0; q < 4; ++q) {
        if (Inside(f[corner[q]]) != saddle_inside) pairs.push_back({(q + 3) % 4, q});
      }
    }
    const Vector3d normal = (side ? 1.0 : -1.0) * Vector3d::Unit(axis);
    for (const auto& [p, q] : pairs) {
      segments.push_back(OrientedSegment(i, j, k, f, corner, p, q, normal));
    }
  }

  // Orients the segment between face edges p and q so that the polygon it
  // bounds runs counter-clockwise seen from outside the body: with g the
  // in-face direction from inside to outside corners and N the face normal
  // (out of the cube), the segment runs along g x N.
  Segment OrientedSegment(int i, int j, int k, const float f[8], const int corner[4], int p, int q,
                          const Vector3d& normal) {
    auto local = [](int c) -> Vector3d { return CornerOffset(c).cast<double>(); };
    auto split = [&](int edge, Vector3d& in, Vector3d& out) {
      const int c0 = corner[edge], c1 = corner[(edge + 1) % 4];
      const bool c0_inside = Inside(f[c0]);
      in = local(c0_inside ? c0 : c1);
      out = local(c0_inside ? c1 : c0);
    };
    Vector3d in_p, out_p, in_q, out_q;
    split(p, in_p, out_p);
    split(q, in_q, out_q);
    const Vector3d g = out_p + out_q - in_p - in_q;
    const Vector3d mid_p = 0.5 * (in_p + out_p), mid_q = 0.5 * (in_q + out_q);
    const bool forward = g.cross(normal).dot(mid_q - mid_p) > 0.0;
    const int vp = EdgeVertex(i, j, k, corner[p], corner[(p + 1) % 4]);
    const int vq = EdgeVertex(i, j, k, corner[q], corner[(q + 1) % 4]);
    return forward ? Segment{vp, vq} : Segment{vq, vp};
  }

  void ChainLoops(const std::vector<Segment>& segments) {
    std::vector<bool> used(segments.size(), false);
    for (size_t s = 0; s < segments.size(); ++s) {
      if (used[s]) continue;
      std::vector<int> loop;
      size_t current = s;
      while (!used[current]) {
        used[current] = true;
        loop.push_back(segments[current].from);
        const int next_vertex = segments[current].to;
        for (size_t t = 0; t < segments.size(); ++t) {
          if (!used[t] && segments[t].from == next_vertex) {
            current = t;
            break;
          }
        }
      }
      if (loop.size() >= 3) polygons.push_back(std::move(loop));
    }
  }

  const Grid& grid_;
  std::unordered_map<int64_t, int> vertex_of_edge_;
};

uint64_t EdgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<uint64_t>(a) << 32) | static_cast<uint32_t>(b);
}

// Triangulates polygons by fans; a polygon whose fan diagonal would be
// shared by more than two triangles is triangulated around a new centre
// vertex instead, which keeps every edge shared by exactly two triangles.
Mesh TriangulatePolygons(std::vector<Vector3d> vertices_m,
                         const std::vector<std::vector<int>>& polygons) {
  std::vector<bool> use_centre(polygons.size(), false);
  std::vector<Eigen::Vector3i> triangles;
  for (int attempt = 0; attempt < 4; ++attempt) {
    triangles.clear();
    std::vector<Vector3d> extra;
    std::vector<std::pair<size_t, std::vector<uint64_t>>> diagonals;
    for (size_t p = 0; p < polygons.size(); ++p) {
      const std::vector<int>& poly = polygons[p];
      const int n = static_cast<int>(poly.size());
      if (use_centre[p]) {
        Vector3d centre = Vector3d::Zero();
        for (int v : poly) centre += vertices_m[v];
        const int c = static_cast<int>(vertices_m.size() + extra.size());
        extra.push_back(centre / n);
        for (int q = 0; q < n; ++q) triangles.push_back({poly[q], poly[(q + 1) % n], c});
        continue;
      }
      std::vector<uint64_t> poly_diagonals;
      for (int q = 1; q + 1 < n; ++q) {
        triangles.push_back({poly[0], poly[q], poly[q + 1]});
        if (q > 1) poly_diagonals.push_back(EdgeKey(poly[0], poly[q]));
      }
      if (!poly_diagonals.empty()) diagonals.push_back({p, std::move(poly_diagonals)});
    }
    std::unordered_map<uint64_t, int> count;
    for (const auto& t : triangles) {
      for (int e = 0; e < 3; ++e) ++count[EdgeKey(t[e], t[(e + 1) % 3])];
    }
    bool changed = false;
    for (const auto& [p, keys] : diagonals) {
      for (uint64_t key : keys) {
        if (count[key] != 2) {
          use_centre[p] = true;
          changed = true;
        }
      }
    }
    if (!changed || attempt == 3) {
      vertices_m.insert(vertices_m.end(), extra.begin(), extra.end());
      break;
    }
  }
  Mesh mesh;
  mesh.vertices_m.resize(3, static_cast<Eigen::Index>(vertices_m.size()));
  for (size_t v = 0; v < vertices_m.size(); ++v) mesh.vertices_m.col(v) = vertices_m[v];
  mesh.triangles = std::move(triangles);
  return mesh;
}

int FindRoot(std::vector<int>& parent, int v) {
  while (parent[v] != v) {
    parent[v] = parent[parent[v]];
    v = parent[v];
  }
  return v;
}

// Keeps the connected component with the most triangles and drops vertices
// no triangle uses.
Mesh LargestComponent(const Mesh& mesh) {
  const int num_vertices = static_cast<int>(mesh.vertices_m.cols());
  std::vector<int> parent(num_vertices);
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& t : mesh.triangles) {
    for (int e = 1; e < 3; ++e) parent[FindRoot(parent, t[0])] = FindRoot(parent, t[e]);
  }
  std::unordered_map<int, int> size;
  for (const auto& t : mesh.triangles) ++size[FindRoot(parent, t[0])];
  int best_root = -1, best_size = -1;
  for (const auto& [root, n] : size) {
    if (n > best_size || (n == best_size && root < best_root)) {
      best_root = root;
      best_size = n;
    }
  }
  std::vector<int> remap(num_vertices, -1);
  Mesh out;
  std::vector<Vector3d> kept;
  for (const auto& t : mesh.triangles) {
    if (FindRoot(parent, t[0]) != best_root) continue;
    Eigen::Vector3i nt;
    for (int e = 0; e < 3; ++e) {
      if (remap[t[e]] < 0) {
        remap[t[e]] = static_cast<int>(kept.size());
        kept.push_back(mesh.vertices_m.col(t[e]));
      }
      nt[e] = remap[t[e]];
    }
    out.triangles.push_back(nt);
  }
  out.vertices_m.resize(3, static_cast<Eigen::Index>(kept.size()));
  for (size_t v = 0; v < kept.size(); ++v) out.vertices_m.col(v) = kept[v];
  return out;
}

std::vector<std::vector<int>> VertexNeighbours(const Mesh& mesh) {
  std::vector<std::vector<int>> neighbours(mesh.vertices_m.cols());
  for (const auto& t : mesh.triangles) {
    for (int e = 0; e < 3; ++e) {
      neighbours[t[e]].push_back(t[(e + 1) % 3]);
      neighbours[t[e]].push_back(t[(e + 2) % 3]);
    }
  }
  for (auto& n : neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  return neighbours;
}

// Taubin's lambda|mu smoothing (G. Taubin, "A signal processing approach to
// fair surface design", SIGGRAPH 1995): alternating shrink (lambda > 0) and
// inflate (mu < -lambda) umbrella steps smooth without overall shrinkage.
void TaubinSmooth(int iterations, Mesh& mesh) {
  const auto neighbours = VertexNeighbours(mesh);
  constexpr double kLambda = 0.5, kMu = -0.53;
  for (int it = 0; it < 2 * iterations; ++it) {
    const double step = (it % 2 == 0) ? kLambda : kMu;
    Matrix3Xd next = mesh.vertices_m;
    for (Eigen::Index v = 0; v < mesh.vertices_m.cols(); ++v) {
      if (neighbours[v].empty()) continue;
      Vector3d mean = Vector3d::Zero();
      for (int n : neighbours[v]) mean += mesh.vertices_m.col(n);
      mean /= static_cast<double>(neighbours[v].size());
      next.col(v) += step * (mean - mesh.vertices_m.col(v));
    }
    mesh.vertices_m = std::move(next);
  }
}

absl::StatusOr<Mesh> PolygoniseBody(const Layout& layout, double spacing_m, int smoothing) {
  const Grid grid = SampleBody(layout, spacing_m);
  CubeMarcher marcher(grid);
  marcher.Run();
  if (marcher.polygons.empty()) return absl::InternalError("polygonisation found no surface");
  Mesh mesh =
      LargestComponent(TriangulatePolygons(std::move(marcher.vertices_m), marcher.polygons));
  TaubinSmooth(smoothing, mesh);
  return mesh;
}

// ---------------------------------------------------------------------------
// Skinning: weights from distances to the bones of the Kinect v2 tree.

struct SkinBone {
  int joint;            // The joint whose transform moves the bone.
  Vector3d a_m, b_m;    // Rest endpoints.
  int home_limb;        // Limb whose vertices it moves freely.
  int other_limb = -1;  // Limb whose vertices it moves with a penalty.
};

double SegmentDistance(const Vector3d& a, const Vector3d& b, const Vector3d& p) {
  const Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

std::vector<SkinBone> MakeSkinBones(const Layout& layout) {
  const auto& jt = layout.joints_m;
  auto bone = [&](J from, const Vector3d& to, int home, int other = -1) {
    return SkinBone{Index(from), jt[Index(from)], to, home, other};
  };
  auto at = [&](J j) { return jt[Index(j)]; };
  std::vector<SkinBone> bones = {
      bone(J::kSpineBase, at(J::kSpineMid), 0), bone(J::kSpineMid, at(J::kSpineShoulder), 0),
      bone(J::kSpineShoulder, at(J::kNeck), 0), bone(J::kNeck, at(J::kHead), 0),
      bone(J::kHead, layout.head_top_m, 0),
  };
  for (int s = 0; s < 2; ++s) {
    const bool left = s == 0;
    const int arm = left ? 1 : 2, leg = left ? 3 : 4;
    const J sh = left ? J::kShoulderLeft : J::kShoulderRight;
    const J el = left ? J::kElbowLeft : J::kElbowRight;
    const J wr = left ? J::kWristLeft : J::kWristRight;
    const J hand = left ? J::kHandLeft : J::kHandRight;
    const J tip = left ? J::kHandTipLeft : J::kHandTipRight;
    const J thumb = left ? J::kThumbLeft : J::kThumbRight;
    const J hip = left ? J::kHipLeft : J::kHipRight;
    const J knee = left ? J::kKneeLeft : J::kKneeRight;
    const J ankle = left ? J::kAnkleLeft : J::kAnkleRight;
    const J foot = left ? J::kFootLeft : J::kFootRight;
    bones.push_back(bone(J::kSpineShoulder, at(sh), 0, arm));
    bones.push_back(bone(sh, at(el), arm, 0));
    bones.push_back(bone(el, at(wr), arm));
    bones.push_back(bone(wr, at(hand), arm));
    bones.push_back(bone(wr, at(thumb), arm));
    bones.push_back(bone(hand, at(tip), arm));
    bones.push_back(bone(J::kSpineBase, at(hip), 0, leg));
    bones.push_back(bone(hip, at(knee), leg, 0));
    bones.push_back(bone(knee, at(ankle), leg));
    bones.push_back(bone(ankle, at(foot), leg));
    bones.push_back(bone(ankle, layout.heel_m[s], leg));
    bones.push_back(bone(foot, layout.toe_tip_m[s], leg));
  }
  return bones;
}

// Dense per-vertex joint weights (25 x V): a Gaussian falloff in the excess
// distance over the nearest allowed bone. Bones of another limb are not
// allowed; limb bones seen from the trunk (and trunk bones seen from a limb)
// count as farther by a penalty, which keeps the chest from following the
// arm.
Eigen::MatrixXd BoneDistanceWeights(const Matrix3Xd& vertices_m, const std::vector<int>& parts,
                                    const std::vector<SkinBone>& bones, double stature_m) {
  const double sigma = 0.02 * stature_m;
  const double trunk_to_limb_penalty = 0.04 * stature_m;
  const double limb_to_trunk_penalty = 0.01 * stature_m;
  Eigen::MatrixXd weights = Eigen::MatrixXd::Zero(kNumKinectV2Joints, vertices_m.cols());
  std::vector<double> distance(bones.size());
  for (Eigen::Index v = 0; v < vertices_m.cols(); ++v) {
    const int limb = LimbOfPart(parts[v]);
    double nearest = 1e9;
    for (size_t b = 0; b < bones.size(); ++b) {
      const SkinBone& bone = bones[b];
      double d = 1e9;
      if (bone.home_limb == limb) {
        d = SegmentDistance(bone.a_m, bone.b_m, vertices_m.col(v));
      } else if (bone.other_limb == limb) {
        d = SegmentDistance(bone.a_m, bone.b_m, vertices_m.col(v)) +
            (limb == 0 ? trunk_to_limb_penalty : limb_to_trunk_penalty);
      }
      distance[b] = d;
      nearest = std::min(nearest, d);
    }
    for (size_t b = 0; b < bones.size(); ++b) {
      const double excess = (distance[b] - nearest) / sigma;
      if (excess < 4.0) weights(bones[b].joint, v) += std::exp(-excess * excess);
    }
    weights.col(v) /= weights.col(v).sum();
  }
  return weights;
}

// Averages weights over mesh neighbours, then keeps each vertex's
// kMaxInfluences largest and renormalises them.
void SmoothAndTruncateWeights(const std::vector<std::vector<int>>& neighbours, int iterations,
                              Eigen::MatrixXd& weights, BodyModel& model) {
  for (int it = 0; it < iterations; ++it) {
    Eigen::MatrixXd next = weights;
    for (Eigen::Index v = 0; v < weights.cols(); ++v) {
      if (neighbours[v].empty()) continue;
      Eigen::VectorXd mean = Eigen::VectorXd::Zero(weights.rows());
      for (int n : neighbours[v]) mean += weights.col(n);
      next.col(v) = 0.5 * weights.col(v) + 0.5 * mean / static_cast<double>(neighbours[v].size());
    }
    weights = std::move(next);
  }
  const Eigen::Index num_vertices = weights.cols();
  model.skin_joints.assign(num_vertices, {0, 0, 0, 0});
  model.skin_weights.assign(num_vertices, {0.f, 0.f, 0.f, 0.f});
  for (Eigen::Index v = 0; v < num_vertices; ++v) {
    std::array<int, kNumKinectV2Joints> order;
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + kMaxInfluences, order.end(),
                      [&](int a, int b) { return weights(a, v) > weights(b, v); });
    double sum = 0.0;
    for (int i = 0; i < kMaxInfluences; ++i) sum += weights(order[i], v);
    for (int i = 0; i < kMaxInfluences; ++i) {
      model.skin_joints[v][i] = order[i];
      model.skin_weights[v][i] = static_cast<float>(weights(order[i], v) / sum);
    }
    // Make the float weights sum to 1 as closely as floats allow.
    float total = 0.f;
    for (int i = 1; i < kMaxInfluences; ++i) total += model.skin_weights[v][i];
    model.skin_weights[v][0] = 1.0f - total;
  }
}

// ---------------------------------------------------------------------------
// Joint regressor.

struct RegressorSite {
  Vector3d axis;           // Bone direction through the joint.
  double reach_m;          // Radius of the vertex ring considered.
  std::vector<int> parts;  // Parts the ring may use.
};

RegressorSite SiteOf(int joint, const std::array<Vector3d, kNumKinectV2Joints>& jt, double h) {
  const J j = static_cast<J>(joint);
  const std::optional<J> parent = KinectV2Parent(j);
  Vector3d axis = Vector3d::UnitY();
  if (parent && j != J::kShoulderLeft && j != J::kShoulderRight && j != J::kHipLeft &&
      j != J::kHipRight && j != J::kSpineShoulder && j != J::kNeck && j != J::kHead) {
    axis = (jt[joint] - jt[Index(*parent)]).normalized();
  }
  const bool left = joint == Index(J::kShoulderLeft) || joint == Index(J::kElbowLeft) ||
                    joint == Index(J::kWristLeft) || joint == Index(J::kHandLeft) ||
                    joint == Index(J::kHandTipLeft) || joint == Index(J::kThumbLeft) ||
                    joint == Index(J::kHipLeft) || joint == Index(J::kKneeLeft) ||
                    joint == Index(J::kAnkleLeft) || joint == Index(J::kFootLeft);
  const int l = left ? 0 : 1;
  switch (j) {
    case J::kSpineBase:
    case J::kSpineMid:
    case J::kSpineShoulder:
      return {axis, 0.14 * h, {kPartTorso}};
    case J::kNeck:
    case J::kHead:
      return {axis, 0.07 * h, {kPartHead}};
    case J::kShoulderLeft:
    case J::kShoulderRight:
      axis = (jt[joint + 1] - jt[joint]).normalized();  // Towards the elbow.
      return {axis, 0.06 * h, {kPartTorso, kPartUpperArmL + l}};
    case J::kElbowLeft:
    case J::kElbowRight:
      return {axis, 0.05 * h, {kPartUpperArmL + l, kPartForearmL + l}};
    case J::kWristLeft:
    case J::kWristRight:
      return {axis, 0.04 * h, {kPartForearmL + l, kPartHandL + l}};
    case J::kHandLeft:
    case J::kHandRight:
    case J::kHandTipLeft:
    case J::kHandTipRight:
    case J::kThumbLeft:
    case J::kThumbRight:
      return {axis, 0.035 * h, {kPartHandL + l}};
    case J::kHipLeft:
    case J::kHipRight:
      return {axis, 0.08 * h, {kPartTorso, kPartThighL + l}};
    case J::kKneeLeft:
    case J::kKneeRight:
      return {axis, 0.06 * h, {kPartThighL + l, kPartShinL + l}};
    case J::kAnkleLeft:
    case J::kAnkleRight:
      return {axis, 0.05 * h, {kPartShinL + l, kPartFootL + l}};
    default:  // Feet.
      axis = Vector3d::UnitZ();
      return {axis, 0.04 * h, {kPartFootL + l}};
  }
}

// Per joint: a ring of vertices (a thin slab across the bone axis through the
// joint, within reach, of the joint's parts), weighted as uniformly as
// possible subject to reproducing the joint exactly and summing to 1 (the
// minimum-norm correction of uniform weights). Falls back to the nearest
// vertices of those parts when the ring is too small.
absl::StatusOr<Eigen::SparseMatrix<double, Eigen::RowMajor>> MakeJointRegressor(
    const Matrix3Xd& vertices_m, const std::vector<int>& parts,
    const std::array<Vector3d, kNumKinectV2Joints>& joints_m, double h, double slab_m) {
  std::vector<Eigen::Triplet<double>> triplets;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    const RegressorSite site = SiteOf(j, joints_m, h);
    std::vector<std::pair<double, int>> allowed;
    std::vector<int> ring;
    for (Eigen::Index v = 0; v < vertices_m.cols(); ++v) {
      if (std::find(site.parts.begin(), site.parts.end(), parts[v]) == site.parts.end()) continue;
      const Vector3d offset = vertices_m.col(v) - joints_m[j];
      allowed.push_back({offset.norm(), static_cast<int>(v)});
      if (std::abs(offset.dot(site.axis)) < slab_m && offset.norm() < site.reach_m) {
        ring.push_back(static_cast<int>(v));
      }
    }
    if (ring.size() < 12) {
      const size_t n = std::min<size_t>(16, allowed.size());
      std::partial_sort(allowed.begin(), allowed.begin() + n, allowed.end());
      ring.clear();
      for (size_t i = 0; i < n; ++i) ring.push_back(allowed[i].second);
    }
    if (ring.size() < 4) {
      return absl::InternalError(absl::StrCat("too few vertices to regress joint ", j));
    }
    const int n = static_cast<int>(ring.size());
    Eigen::MatrixXd a(4, n);
    for (int i = 0; i < n; ++i) a.col(i) << vertices_m.col(ring[i]), 1.0;
    const Eigen::VectorXd uniform = Eigen::VectorXd::Constant(n, 1.0 / n);
    Eigen::Vector4d target;
    target << joints_m[j], 1.0;
    const Eigen::Matrix4d normal = a * a.transpose();
    const Eigen::Vector4d lagrange = normal.fullPivLu().solve(target - a * uniform);
    const Eigen::VectorXd w = uniform + a.transpose() * lagrange;
    if (!w.allFinite()) return absl::InternalError(absl::StrCat("regressor row ", j, " failed"));
    for (int i = 0; i < n; ++i) triplets.emplace_back(j, ring[i], w(i));
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> regressor(kNumKinectV2Joints, vertices_m.cols());
  regressor.setFromTriplets(triplets.begin(), triplets.end());
  return regressor;
}

// ---------------------------------------------------------------------------
// UV atlas: one chart per part, cylindrical about the bone for trunk and
// limb segments, spherical about the centre for head, hands and feet (their
// caps would fold under a cylinder). Charts keep metric proportions and are
// shelf-packed into the unit square. Seams run at the back (limbs, trunk,
// head) or the sole (feet).

struct ChartFrame {
  Vector3d origin, axis, front;  // front: the direction at u = 0.5.
  bool spherical = false;
};

ChartFrame FrameOfPart(int part, const std::array<Vector3d, kNumKinectV2Joints>& jt) {
  auto at = [&](J j) { return jt[Index(j)]; };
  const int l = (part - kPartUpperArmL) % 2;  // 0 left, 1 right for limb parts.
  auto pick = [&](J left, J right) { return at(l == 0 ? left : right); };
  auto make = [](const Vector3d& from, const Vector3d& to, const Vector3d& front, bool sphere) {
    ChartFrame f;
    f.origin = sphere ? 0.5 * (from + to) : from;
    f.axis = (to - from).normalized();
    f.front = (front - front.dot(f.axis) * f.axis).normalized();
    f.spherical = sphere;
    return f;
  };
  const Vector3d z = Vector3d::UnitZ(), y = Vector3d::UnitY();
  switch (part) {
    case kPartHead: {
      ChartFrame f = make(at(J::kNeck), at(J::kHead), z, true);
      f.origin = at(J::kHead);
      f.axis = y;
      return f;
    }
    case kPartTorso:
      return make(at(J::kSpineBase), at(J::kSpineShoulder), z, false);
    case kPartUpperArmL:
    case kPartUpperArmR:
      return make(pick(J::kShoulderLeft, J::kShoulderRight), pick(J::kElbowLeft, J::kElbowRight), z,
                  false);
    case kPartForearmL:
    case kPartForearmR:
      return make(pick(J::kElbowLeft, J::kElbowRight), pick(J::kWristLeft, J::kWristRight), z,
                  false);
    case kPartHandL:
    case kPartHandR:
      return make(pick(J::kWristLeft, J::kWristRight), pick(J::kHandTipLeft, J::kHandTipRight), z,
                  true);
    case kPartThighL:
    case kPartThighR:
      return make(pick(J::kHipLeft, J::kHipRight), pick(J::kKneeLeft, J::kKneeRight), z, false);
    case kPartShinL:
    case kPartShinR:
      return make(pick(J::kKneeLeft, J::kKneeRight), pick(J::kAnkleLeft, J::kAnkleRight), z, false);
    default:  // Feet: sphere about the foot centre, seam along the sole.
      return make(pick(J::kAnkleLeft, J::kAnkleRight) - 0.03 * z,
                  pick(J::kFootLeft, J::kFootRight) + 0.03 * z, y, true);
  }
}

// Chart coordinates (metres along the surface, roughly) of a point.
Eigen::Vector2d ChartCoordinates(const ChartFrame& f, double radius_m, const Vector3d& p) {
  const Vector3d q = p - f.origin;
  const Vector3d side = f.axis.cross(f.front);
  // Angle from the back (-front), so the seam sits at u = 0 and u = 1.
  const double angle = std::atan2(-q.dot(side), -q.dot(f.front)) + kPi;  // [0, 2 pi].
  const double u = angle / (2 * kPi);
  if (f.spherical) {
    const double polar = std::acos(std::clamp(q.normalized().dot(f.axis), -1.0, 1.0));
    return {u * 2 * kPi * radius_m, polar * radius_m};
  }
  return {u * 2 * kPi * radius_m, q.dot(f.axis)};
}

struct UvAtlas {
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_triangles;
};

UvAtlas MakeUvAtlas(const Matrix3Xd& vertices_m, const std::vector<Eigen::Vector3i>& triangles,
                    const std::vector<int>& triangle_part,
                    const std::array<Vector3d, kNumKinectV2Joints>& joints_m) {
  std::array<ChartFrame, kNumParts> frames;
  std::array<double, kNumParts> radius{}, count{};
  for (int p = 0; p < kNumParts; ++p) frames[p] = FrameOfPart(p, joints_m);
  for (size_t t = 0; t < triangles.size(); ++t) {
    const ChartFrame& f = frames[triangle_part[t]];
    for (int c = 0; c < 3; ++c) {
      const Vector3d q = vertices_m.col(triangles[t][c]) - f.origin;
      radius[triangle_part[t]] += f.spherical ? q.norm() : (q - q.dot(f.axis) * f.axis).norm();
      count[triangle_part[t]] += 1;
    }
  }
  for (int p = 0; p < kNumParts; ++p) radius[p] = count[p] > 0 ? radius[p] / count[p] : 0.05;

  // Chart-space uvs, one per (vertex, part, wrapped) corner.
  std::vector<Eigen::Vector2d> chart_uv;
  std::vector<int> uv_part;
  std::unordered_map<uint64_t, int> uv_of_corner;
  UvAtlas atlas;
  atlas.uv_triangles.resize(triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    const int part = triangle_part[t];
    Eigen::Vector2d corner[3];
    for (int c = 0; c < 3; ++c) {
      corner[c] = ChartCoordinates(frames[part], radius[part], vertices_m.col(triangles[t][c]));
    }
    const double width = 2 * kPi * radius[part];
    const double lo = std::min({corner[0].x(), corner[1].x(), corner[2].x()});
    const double hi = std::max({corner[0].x(), corner[1].x(), corner[2].x()});
    const bool wraps = hi - lo > 0.5 * width;
    for (int c = 0; c < 3; ++c) {
      const bool shifted = wraps && corner[c].x() < 0.5 * width;
      if (shifted) corner[c].x() += width;
      const uint64_t key = (static_cast<uint64_t>(triangles[t][c]) << 8) |
                           (static_cast<uint64_t>(part) << 1) | (shifted ? 1 : 0);
      auto [it, inserted] = uv_of_corner.try_emplace(key, static_cast<int>(chart_uv.size()));
      if (inserted) {
        chart_uv.push_back(corner[c]);
        uv_part.push_back(part);
      }
      atlas.uv_triangles[t][c] = it->second;
    }
  }

  // Chart rectangles, padded, shelf-packed; the atlas side is the smallest
  // over a sweep of shelf widths.
  std::array<Eigen::Vector2d, kNumParts> lo, hi;
  lo.fill(Eigen::Vector2d::Constant(1e9));
  hi.fill(Eigen::Vector2d::Constant(-1e9));
  for (size_t i = 0; i < chart_uv.size(); ++i) {
    lo[uv_part[i]] = lo[uv_part[i]].cwiseMin(chart_uv[i]);
    hi[uv_part[i]] = hi[uv_part[i]].cwiseMax(chart_uv[i]);
  }
  const double pad = 0.01;  // Metres of chart space between charts.
  std::vector<int> order;
  double total_area = 0.0, widest = 0.0;
  for (int p = 0; p < kNumParts; ++p) {
    if (hi[p].x() < lo[p].x()) continue;
    order.push_back(p);
    const Eigen::Vector2d size = hi[p] - lo[p] + Eigen::Vector2d::Constant(2 * pad);
    total_area += size.prod();
    widest = std::max(widest, size.x());
  }
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return hi[a].y() - lo[a].y() > hi[b].y() - lo[b].y(); });
  auto pack = [&](double shelf_width, std::array<Eigen::Vector2d, kNumParts>& offset) {
    double x = 0, y = 0, row_height = 0, used_width = 0;
    for (int p : order) {
      const Eigen::Vector2d size = hi[p] - lo[p] + Eigen::Vector2d::Constant(2 * pad);
      if (x > 0 && x + size.x() > shelf_width) {
        y += row_height;
        x = row_height = 0;
      }
      offset[p] = Eigen::Vector2d(x + pad, y + pad);
      x += size.x();
      used_width = std::max(used_width, x);
      row_height = std::max(row_height, size.y());
    }
    return std::max(used_width, y + row_height);
  };
  std::array<Eigen::Vector2d, kNumParts> offset, best_offset;
  double best_side = 1e9;
  for (int step = 0; step <= 60; ++step) {
    const double shelf = std::max(widest, std::sqrt(total_area) * (0.8 + 0.02 * step));
    const double side = pack(shelf, offset);
    if (side < best_side) {
      best_side = side;
      best_offset = offset;
    }
  }
  atlas.uvs.resize(chart_uv.size());
  for (size_t i = 0; i < chart_uv.size(); ++i) {
    const int p = uv_part[i];
    const Eigen::Vector2d uv = (best_offset[p] + chart_uv[i] - lo[p]) / best_side;
    atlas.uvs[i] = uv.cwiseMax(0.0).cwiseMin(1.0).cast<float>();
  }
  return atlas;
}

// ---------------------------------------------------------------------------
// Population: anthropometric variations of the neutral body, made by
// deforming its mesh per joint (so every member shares its topology).

// Deterministic normal samples (Box-Muller on a 64-bit generator), the same
// on every standard library.
class NormalSampler {
 public:
  explicit NormalSampler(uint64_t seed) : state_(seed ^ 0x9E3779B97F4A7C15ull) {}
  // N(0, 1), clipped to +-3.
  double Next() {
    const double u1 = (static_cast<double>(NextBits() >> 11) + 0.5) * 0x1.0p-53;
    const double u2 = (static_cast<double>(NextBits() >> 11) + 0.5) * 0x1.0p-53;
    const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(2 * kPi * u2);
    return std::clamp(z, -3.0, 3.0);
  }

 private:
  // SplitMix64 (Steele, Lea & Flood, OOPSLA 2014).
  uint64_t NextBits() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  uint64_t state_;
};

// Relative body measures of one member (1 = the neutral body). Standard
// deviations are of the order of adult coefficients of variation in ANSUR II
// (segment lengths 3-5%, breadths 5-6%, girths 8-12%); "fullness" is a
// shared BMI-like factor that couples the girths.
struct BodyParameters {
  double stature = 1, trunk = 1, leg = 1, arm = 1, shoulder_width = 1, hip_width = 1;
  double torso_width = 1, torso_depth = 1, arm_girth = 1, thigh_girth = 1, shin_girth = 1;
  double neck_girth = 1, head = 1, hand = 1, foot = 1;
};

BodyParameters SampleParameters(NormalSampler& rng) {
  BodyParameters p;
  const double fullness = rng.Next();
  p.stature = 1 + 0.040 * rng.Next();
  p.trunk = 1 + 0.030 * rng.Next();
  p.leg = 1 + 0.035 * rng.Next();
  p.arm = 1 + 0.030 * rng.Next();
  p.shoulder_width = 1 + 0.050 * rng.Next();
  p.hip_width = 1 + 0.045 * rng.Next() + 0.02 * fullness;
  p.torso_width = 1 + 0.060 * fullness + 0.025 * rng.Next();
  p.torso_depth = 1 + 0.100 * fullness + 0.030 * rng.Next();
  p.arm_girth = 1 + 0.070 * fullness + 0.030 * rng.Next();
  p.thigh_girth = 1 + 0.070 * fullness + 0.030 * rng.Next();
  p.shin_girth = 1 + 0.040 * fullness + 0.030 * rng.Next();
  p.neck_girth = 1 + 0.050 * fullness + 0.030 * rng.Next();
  p.head = 1 + 0.030 * rng.Next();
  p.hand = 1 + 0.040 * rng.Next();
  p.foot = 1 + 0.040 * rng.Next();
  return p;
}

// Scale `along` on direction d and `across` perpendicular to it.
Matrix3d AxialScale(const Vector3d& d, double along, double across) {
  return across * Matrix3d::Identity() + (along - across) * d * d.transpose();
}

// Per joint, the linear map applied to the rest offsets of what it moves.
std::array<Matrix3d, kNumKinectV2Joints> JointScales(
    const BodyParameters& p, const std::array<Vector3d, kNumKinectV2Joints>& jt) {
  std::array<Matrix3d, kNumKinectV2Joints> m;
  m.fill(Matrix3d::Identity());
  auto dir = [&](J from, J to) { return (jt[Index(to)] - jt[Index(from)]).normalized(); };
  m[Index(J::kSpineBase)] =
      Vector3d(p.hip_width * p.torso_width, p.trunk, p.torso_depth).asDiagonal();
  m[Index(J::kSpineMid)] = Vector3d(p.torso_width, p.trunk, p.torso_depth).asDiagonal();
  m[Index(J::kSpineShoulder)] = Vector3d(p.shoulder_width, p.trunk, p.torso_depth).asDiagonal();
  m[Index(J::kNeck)] = Vector3d(p.neck_girth, p.trunk, p.neck_girth).asDiagonal();
  m[Index(J::kHead)] = p.head * Matrix3d::Identity();
  for (int s = 0; s < 2; ++s) {
    const bool l = s == 0;
    const J sh = l ? J::kShoulderLeft : J::kShoulderRight, el = l ? J::kElbowLeft : J::kElbowRight;
    const J wr = l ? J::kWristLeft : J::kWristRight, hip = l ? J::kHipLeft : J::kHipRight;
    const J knee = l ? J::kKneeLeft : J::kKneeRight, ankle = l ? J::kAnkleLeft : J::kAnkleRight;
    m[Index(sh)] = AxialScale(dir(sh, el), p.arm, p.arm_girth);
    m[Index(el)] = AxialScale(dir(el, wr), p.arm, p.arm_girth);
    for (J j : {wr, l ? J::kHandLeft : J::kHandRight}) m[Index(j)] = p.hand * Matrix3d::Identity();
    m[Index(hip)] = AxialScale(dir(hip, knee), p.leg, p.thigh_girth);
    m[Index(knee)] = AxialScale(dir(knee, ankle), p.leg, p.shin_girth);
    for (J j : {ankle, l ? J::kFootLeft : J::kFootRight}) {
      m[Index(j)] = p.foot * Matrix3d::Identity();
    }
  }
  return m;
}

// Joints in an order where every parent precedes its children.
std::vector<int> TopologicalJointOrder() {
  std::vector<int> order = {Index(J::kSpineBase)};
  for (size_t i = 0; i < order.size(); ++i) {
    for (int j = 0; j < kNumKinectV2Joints; ++j) {
      const std::optional<J> parent = KinectV2Parent(static_cast<J>(j));
      if (parent && Index(*parent) == order[i]) order.push_back(j);
    }
  }
  return order;
}

struct Member {
  Matrix3Xd vertices_m;
  std::array<Vector3d, kNumKinectV2Joints> joints_m;
};

// v' = sum_i w_i (J'_i + M_i (v - J_i)), with J'_child = J'_parent +
// M_parent (J_child - J_parent), so each joint's map carries its children
// exactly; then feet back onto the floor and a uniform scale to the sampled
// stature.
Member DeformBody(const Matrix3Xd& vertices_m, const std::array<Vector3d, kNumKinectV2Joints>& jt,
                  const BodyModel& skin, const std::vector<int>& order, const BodyParameters& p,
                  double target_stature_m) {
  const auto scale = JointScales(p, jt);
  Member member;
  for (int j : order) {
    const std::optional<J> parent = KinectV2Parent(static_cast<J>(j));
    member.joints_m[j] = parent ? Vector3d(member.joints_m[Index(*parent)] +
                                           scale[Index(*parent)] * (jt[j] - jt[Index(*parent)]))
                                : jt[j];
  }
  member.vertices_m.resize(3, vertices_m.cols());
  for (Eigen::Index v = 0; v < vertices_m.cols(); ++v) {
    Vector3d out = Vector3d::Zero();
    for (int i = 0; i < kMaxInfluences; ++i) {
      const int j = skin.skin_joints[v][i];
      out +=
          skin.skin_weights[v][i] * (member.joints_m[j] + scale[j] * (vertices_m.col(v) - jt[j]));
    }
    member.vertices_m.col(v) = out;
  }
  const double floor_m = member.vertices_m.row(1).minCoeff();
  const double height_m = member.vertices_m.row(1).maxCoeff() - floor_m;
  const double s = target_stature_m / height_m;
  member.vertices_m.row(1).array() -= floor_m;
  member.vertices_m *= s;
  for (Vector3d& joint : member.joints_m) joint = s * (joint - Vector3d(0, floor_m, 0));
  return member;
}

std::vector<Member> MakePopulation(const Matrix3Xd& vertices_m,
                                   const std::array<Vector3d, kNumKinectV2Joints>& jt,
                                   const BodyModel& skin, const ProceduralBodyOptions& options) {
  const int n = options.population_size + options.num_held_out;
  NormalSampler rng(options.seed);
  std::vector<BodyParameters> params(n);
  for (BodyParameters& p : params) p = SampleParameters(rng);
  // Centre the learning members' stature factors on 1, so the mean body has
  // the requested stature.
  double mean_stature = 0.0;
  for (int i = 0; i < options.population_size; ++i) mean_stature += params[i].stature;
  mean_stature /= options.population_size;
  const std::vector<int> order = TopologicalJointOrder();
  std::vector<Member> members;
  members.reserve(n);
  for (const BodyParameters& p : params) {
    const double stature = options.stature_m * (p.stature - mean_stature + 1.0);
    members.push_back(DeformBody(vertices_m, jt, skin, order, p, stature));
  }
  return members;
}

// Majority part of each triangle's corners (the first corner's on a tie).
std::vector<int> TriangleParts(const std::vector<Eigen::Vector3i>& triangles,
                               const std::vector<int>& vertex_part) {
  std::vector<int> parts(triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    const int a = vertex_part[triangles[t][0]], b = vertex_part[triangles[t][1]],
              c = vertex_part[triangles[t][2]];
    parts[t] = (b == c) ? b : a;
  }
  return parts;
}

void ShiftToFloor(Matrix3Xd& vertices_m, std::array<Vector3d, kNumKinectV2Joints>& joints_m) {
  const double floor_m = vertices_m.row(1).minCoeff();
  vertices_m.row(1).array() -= floor_m;
  for (Vector3d& j : joints_m) j.y() -= floor_m;
}

}  // namespace

absl::Status ProceduralBodyOptions::Validate() const {
  if (!(stature_m >= 1.0 && stature_m <= 2.3)) {
    return absl::InvalidArgumentError(absl::StrCat("stature_m ", stature_m, " outside [1, 2.3]"));
  }
  if (!(grid_spacing_m >= 0.006 && grid_spacing_m <= 0.03)) {
    return absl::InvalidArgumentError(
        absl::StrCat("grid_spacing_m ", grid_spacing_m, " outside [0.006, 0.03]"));
  }
  if (smoothing_iterations < 0 || smoothing_iterations > 50) {
    return absl::InvalidArgumentError("smoothing_iterations outside [0, 50]");
  }
  if (!(arm_angle_below_horizontal_deg >= 20 && arm_angle_below_horizontal_deg <= 60)) {
    return absl::InvalidArgumentError("arm_angle_below_horizontal_deg outside [20, 60]");
  }
  if (num_shape_components < 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("num_shape_components ", num_shape_components, " < 8"));
  }
  if (population_size <= num_shape_components || population_size > 2000) {
    return absl::InvalidArgumentError(absl::StrCat(
        "population_size ", population_size, " must exceed num_shape_components and be <= 2000"));
  }
  if (num_held_out < 0 || num_held_out > 1000) {
    return absl::InvalidArgumentError("num_held_out outside [0, 1000]");
  }
  return absl::OkStatus();
}

std::string_view BodyRegionName(BodyRegion region) {
  switch (region) {
    case BodyRegion::kHead:
      return "head";
    case BodyRegion::kTorso:
      return "torso";
    case BodyRegion::kUpperArm:
      return "upper_arm";
    case BodyRegion::kForearm:
      return "forearm";
    case BodyRegion::kHand:
      return "hand";
    case BodyRegion::kThigh:
      return "thigh";
    case BodyRegion::kShin:
      return "shin";
    case BodyRegion::kFoot:
      return "foot";
  }
  return "unknown";
}

absl::StatusOr<ProceduralBody> BuildProceduralBodyDetailed(const ProceduralBodyOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  const double h = options.stature_m;
  Layout layout = MakeLayout(h, options.arm_angle_below_horizontal_deg * kPi / 180.0);
  const double spacing_m = options.grid_spacing_m * h / 1.75;
  ASSIGN_OR_RETURN(Mesh base, PolygoniseBody(layout, spacing_m, options.smoothing_iterations));
  std::vector<int> vertex_part(base.vertices_m.cols());
  for (Eigen::Index v = 0; v < base.vertices_m.cols(); ++v) {
    vertex_part[v] = NearestPart(layout, base.vertices_m.col(v));
  }
  const double floor_m = base.vertices_m.row(1).minCoeff();
  ShiftToFloor(base.vertices_m, layout.joints_m);
  const Vector3d down(0, floor_m, 0);
  layout.head_top_m -= down;
  for (int s = 0; s < 2; ++s) {
    layout.heel_m[s] -= down;
    layout.toe_tip_m[s] -= down;
  }

  ProceduralBody body;
  BodyModel& model = body.model;
  model.name = "procedural";
  model.triangles = base.triangles;
  Eigen::MatrixXd dense_weights =
      BoneDistanceWeights(base.vertices_m, vertex_part, MakeSkinBones(layout), h);
  SmoothAndTruncateWeights(VertexNeighbours(base), 2, dense_weights, model);

  std::vector<Member> members = MakePopulation(base.vertices_m, layout.joints_m, model, options);
  std::vector<Matrix3Xd> learning;
  learning.reserve(options.population_size);
  std::array<Vector3d, kNumKinectV2Joints> mean_joints;
  mean_joints.fill(Vector3d::Zero());
  for (int i = 0; i < options.population_size; ++i) {
    learning.push_back(std::move(members[i].vertices_m));
    for (int j = 0; j < kNumKinectV2Joints; ++j) mean_joints[j] += members[i].joints_m[j];
  }
  for (Vector3d& j : mean_joints) j /= options.population_size;
  for (size_t i = options.population_size; i < members.size(); ++i) {
    body.held_out_members_m.push_back(std::move(members[i].vertices_m));
  }
  ASSIGN_OR_RETURN(ShapeSpace space, LearnShapeSpace(learning, options.num_shape_components));
  learning.clear();

  model.template_vertices_m = std::move(space.mean_m);
  ShiftToFloor(model.template_vertices_m, mean_joints);
  body.rest_joints_m = mean_joints;
  model.shape_directions_m = std::move(space.directions_m);
  for (int k = 0; k < model.num_shape_components(); ++k) {
    model.shape_names.push_back(absl::StrCat("pc", k));
  }
  body.explained_variance_ratio = std::move(space.explained_variance_ratio);
  ASSIGN_OR_RETURN(model.joint_regressor, MakeJointRegressor(model.template_vertices_m, vertex_part,
                                                             mean_joints, h, spacing_m));

  const std::vector<int> triangle_part = TriangleParts(model.triangles, vertex_part);
  UvAtlas atlas = MakeUvAtlas(base.vertices_m, model.triangles, triangle_part, layout.joints_m);
  model.uvs = std::move(atlas.uvs);
  model.uv_triangles = std::move(atlas.uv_triangles);
  body.triangle_region.reserve(triangle_part.size());
  for (int p : triangle_part) body.triangle_region.push_back(RegionOfPart(p));
  return body;
}

absl::StatusOr<BodyModel> BuildProceduralBody(const ProceduralBodyOptions& options) {
  ASSIGN_OR_RETURN(ProceduralBody body, BuildProceduralBodyDetailed(options));
  return std::move(body.model);
}

}  // namespace reenact::body
