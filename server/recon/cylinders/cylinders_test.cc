#include "server/recon/cylinders/cylinders.h"

#include <cmath>
#include <map>

#include <gtest/gtest.h>

#include "common/io/proto_convert.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "server/recon/testing/short_take.h"

namespace reenact::recon {
namespace {

using body::KinectV2Joint;
using Eigen::Vector3d;
using J = KinectV2Joint;
using recon::testing::GetSharedTake;

void Set(JointArray& joints, J j, double x, double y, double z) {
  joints[body::Index(j)] = Vector3d(x, y, z);
}

// A person 2.5 m in front of a depth camera (OpenCV axes: x right, y down,
// z forward), facing it, so the person's left is the image's right (+x).
// `arm_drop_deg`: arms 0 = out sideways, 90 = hanging; `cross`: legs crossed.
JointArray PersonFacingCamera(double arm_drop_deg, bool cross = false) {
  JointArray j = MissingJoints();
  const double z = 2.5;
  Set(j, J::kSpineBase, 0, 0.1, z);
  Set(j, J::kSpineMid, 0, -0.1, z);
  Set(j, J::kSpineShoulder, 0, -0.4, z);
  Set(j, J::kNeck, 0, -0.48, z);
  Set(j, J::kHead, 0, -0.6, z);
  const double a = arm_drop_deg * M_PI / 180.0;
  for (double side : {1.0, -1.0}) {
    const bool left = side > 0;
    const Vector3d shoulder(side * 0.18, -0.4, z);
    const Vector3d dir(side * std::cos(a), std::sin(a), 0.0);
    auto put = [&](J l, J r, const Vector3d& p) { j[body::Index(left ? l : r)] = p; };
    put(J::kShoulderLeft, J::kShoulderRight, shoulder);
    put(J::kElbowLeft, J::kElbowRight, shoulder + 0.3 * dir);
    put(J::kWristLeft, J::kWristRight, shoulder + 0.55 * dir);
    put(J::kHandLeft, J::kHandRight, shoulder + 0.62 * dir);
    put(J::kHandTipLeft, J::kHandTipRight, shoulder + 0.72 * dir);
    const double foot_x = (cross ? -1.0 : 1.0) * side * 0.15;
    put(J::kHipLeft, J::kHipRight, Vector3d(side * 0.09, 0.12, z));
    put(J::kKneeLeft, J::kKneeRight, Vector3d(0.5 * (side * 0.09 + foot_x), 0.55, z));
    put(J::kAnkleLeft, J::kAnkleRight, Vector3d(foot_x, 0.98, z));
    put(J::kFootLeft, J::kFootRight, Vector3d(foot_x, 1.0, z - 0.15));
  }
  return j;
}

TEST(ScoreRepresentative, PrefersArmsOutAndLegsUncrossed) {
  const RepresentativeScore t_pose = ScoreRepresentative(PersonFacingCamera(0), 0.5);
  const RepresentativeScore arms_down = ScoreRepresentative(PersonFacingCamera(85), 0.5);
  const RepresentativeScore crossed = ScoreRepresentative(PersonFacingCamera(0, true), 0.5);
  ASSERT_TRUE(t_pose.valid && arms_down.valid && crossed.valid);
  // Eq. 3.4 in the T-pose: theta = 90 degrees, |a| = 1 per arm, g = 1.
  EXPECT_NEAR(t_pose.theta_left_rad, M_PI / 2, 1e-9);
  EXPECT_NEAR(t_pose.a_right, 1.0, 1e-9);
  EXPECT_EQ(t_pose.g, 1.0);
  EXPECT_NEAR(t_pose.e, M_PI + 0.5, 1e-9);
  EXPECT_LT(arms_down.e, 0.5 * t_pose.e);
  EXPECT_EQ(crossed.g, 0.0);  // Eq. 3.3.
  EXPECT_NEAR(crossed.e, M_PI, 1e-9);
  JointArray missing = PersonFacingCamera(0);
  missing[body::Index(J::kWristLeft)] = Vector3d::Constant(std::nan(""));
  EXPECT_FALSE(ScoreRepresentative(missing, 0.5).valid);
}

TEST(CylinderOptions, ReadsAndValidatesOptions) {
  CylinderOptions options;
  const std::map<std::string, std::string> good = {{"lambda", "1.5"},
                                                   {"segments", "12"},
                                                   {"keyframe_stride", "3"},
                                                   {"color_scale", "2"},
                                                   {"bake", "false"},
                                                   {"representative_instant", "4"},
                                                   {"representative_sensor", "1"}};
  OptionReader reader(good);
  ASSERT_TRUE(options.Read(reader).ok());
  EXPECT_TRUE(reader.Finish().ok());
  EXPECT_DOUBLE_EQ(options.lambda, 1.5);
  EXPECT_EQ(options.segments, 12);
  EXPECT_EQ(options.texturing.keyframe_stride, 3);
  EXPECT_EQ(options.texturing.color_scale, 2);
  EXPECT_FALSE(options.texturing.bake);
  EXPECT_EQ(options.representative_instant, 4);
  for (const auto& [key, value] :
       std::map<std::string, std::string>{{"color_scale", "3"},
                                          {"lambda", "-1"},
                                          {"segments", "2"},
                                          {"rings", "x"},
                                          {"representative_instant", "4"}}) {
    CylinderOptions o;
    const std::map<std::string, std::string> one = {{key, value}};
    OptionReader r(one);
    EXPECT_EQ(o.Read(r).code(), absl::StatusCode::kInvalidArgument) << key << "=" << value;
  }
}

// Ray-casts capped-free cylinders (axis a->b, radius r) into a depth image.
struct Cylinder {
  Vector3d a, b;
  double r;
};

void Render(const std::vector<Cylinder>& cylinders, const CameraIntrinsics& k, DepthImageMm* depth,
            MaskImage* mask) {
  *depth = DepthImageMm(k.width, k.height, 4000);  // A wall 4 m away.
  *mask = MaskImage(k.width, k.height, 0);
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const Vector3d d((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
      double best = 1e9;
      for (const Cylinder& c : cylinders) {
        const Vector3d axis = (c.b - c.a).normalized();
        // |(t d - a) x axis| = r, quadratic in t.
        const Vector3d dp = d - d.dot(axis) * axis;
        const Vector3d ap = -c.a - (-c.a).dot(axis) * axis;
        const double qa = dp.squaredNorm(), qb = 2 * dp.dot(ap), qc = ap.squaredNorm() - c.r * c.r;
        const double disc = qb * qb - 4 * qa * qc;
        if (disc < 0) continue;
        const double t = (-qb - std::sqrt(disc)) / (2 * qa);
        const double s = (t * d - c.a).dot(axis);
        if (t > 0 && s >= 0 && s <= (c.b - c.a).norm()) best = std::min(best, t);
      }
      if (best < 1e8) {
        depth->at(x, y) = static_cast<uint16_t>(std::lround(best * 1000));
        mask->at(x, y) = 1;
      }
    }
  }
}

TEST(FitPartRadii, MeasuresAnAnalyticCylinderInFrontOfAnother) {
  CameraIntrinsics k;
  k.width = 512;
  k.height = 424;
  k.fx = k.fy = 365.0;
  k.cx = 255.5;
  k.cy = 211.5;
  JointArray joints = MissingJoints();
  Set(joints, J::kElbowLeft, -0.25, 0.02, 2.0);
  Set(joints, J::kWristLeft, 0.25, -0.03, 2.0);
  // Forearm r = 40 mm; a trunk (r = 150 mm) crossing 0.35 m behind it.
  const std::vector<Cylinder> scene = {
      {joints[body::Index(J::kElbowLeft)], joints[body::Index(J::kWristLeft)], 0.04},
      {Vector3d(0, -0.6, 2.5), Vector3d(0, 0.6, 2.5), 0.15}};
  DepthImageMm depth;
  MaskImage mask;
  Render(scene, k, &depth, &mask);
  auto radii = FitPartRadii(joints, depth, mask, k, CylinderOptions{});
  ASSERT_TRUE(radii.ok()) << radii.status();
  const PartRadius& forearm = (*radii)[Index(BodyPart::kForearmLeft)];
  ASSERT_TRUE(forearm.fitted);
  std::printf("[ figures  ] analytic forearm: radius %.1f mm (true 40.0), %d lines\n",
              1e3 * forearm.radius_m, forearm.lines);
  // One depth pixel is 5.5 mm at 2 m; the median of the lines is within 2 mm.
  EXPECT_NEAR(forearm.radius_m, 0.04, 0.002);
  EXPECT_NEAR(forearm.length_m, std::hypot(0.5, 0.05), 1e-9);
  EXPECT_NEAR(forearm.radius_rate, forearm.radius_m / forearm.length_m, 1e-12);
  // Parts without joints take the default rate, or the mirror part's.
  EXPECT_FALSE((*radii)[Index(BodyPart::kHead)].fitted);
  EXPECT_DOUBLE_EQ((*radii)[Index(BodyPart::kHead)].radius_rate,
                   DefaultRadiusRate(BodyPart::kHead));
  EXPECT_DOUBLE_EQ((*radii)[Index(BodyPart::kForearmRight)].radius_rate, forearm.radius_rate);

  MaskImage small(10, 10);
  EXPECT_EQ(FitPartRadii(joints, depth, small, k, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(MakeCylinderGeometry, ClosedOutwardCounterClockwise) {
  const PartMesh g = MakeCylinderGeometry(0.05, 0.0, 0.3, 24, 8);
  const int n = static_cast<int>(g.positions_in_part_m.cols());
  EXPECT_EQ(n, 9 * 24 + 2 * 25);
  EXPECT_EQ(g.triangles.size(), 2u * 24 * 8 + 2u * 24);
  for (const Eigen::Vector3i& t : g.triangles) {
    for (int c = 0; c < 3; ++c) ASSERT_TRUE(t[c] >= 0 && t[c] < n);
    const Eigen::Vector3f p0 = g.positions_in_part_m.col(t[0]);
    const Eigen::Vector3f p1 = g.positions_in_part_m.col(t[1]);
    const Eigen::Vector3f p2 = g.positions_in_part_m.col(t[2]);
    const Eigen::Vector3f face = (p1 - p0).cross(p2 - p0);
    const Eigen::Vector3f centroid = (p0 + p1 + p2) / 3;
    // Outward from the axis segment's middle.
    const Eigen::Vector3f out = centroid - Eigen::Vector3f(0, 0.15f, 0);
    EXPECT_GT(face.dot(out), 0) << t.transpose();
    // Vertex normals agree with the face.
    EXPECT_GT(face.dot(g.normals_in_part.col(t[0])), 0);
  }
  for (int v = 0; v < n; ++v) {
    EXPECT_NEAR(g.normals_in_part.col(v).norm(), 1.0f, 1e-6f);
    const Eigen::Vector3f p = g.positions_in_part_m.col(v);
    EXPECT_LE(std::hypot(p.x(), p.z()), 0.05f + 1e-6f);
    EXPECT_GE(p.y(), -1e-6f);
    EXPECT_LE(p.y(), 0.3f + 1e-6f);
  }
  const PartMesh mesh = ToPartMesh(BodyPart::kShinLeft, g, 0.2f, 0.25f);
  EXPECT_EQ(mesh.part, Index(BodyPart::kShinLeft));
  EXPECT_EQ(mesh.name, "shin_left");
  EXPECT_EQ(mesh.num_vertices(), static_cast<int>(n));
  EXPECT_EQ(mesh.triangles.size(), g.triangles.size());
  EXPECT_EQ(mesh.radius_rate, 0.2f);
  EXPECT_EQ(mesh.reference_length_m, 0.25f);
}

// Nearest point parameter of p on segment a-b and the distance to it.
std::pair<double, double> SegmentDistance(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return {t, (p - (a + t * ab)).norm()};
}

// The true radius of `part` at one frame of the synthetic take: the mean
// distance from the bone axis of the ground-truth mesh vertices nearest to
// that bone (of all 15), in the middle of the bone (30-70 %).
double TrueRadius(BodyPart part, const std::vector<Vector3d>& vertices, const JointArray& joints) {
  double sum = 0;
  int n = 0;
  for (const Vector3d& v : vertices) {
    int nearest = -1;
    double nearest_d = 1e9, nearest_t = 0;
    for (int p = 0; p < kNumBodyParts; ++p) {
      const BodyPartInfo& info = BodyParts()[p];
      auto [t, d] =
          SegmentDistance(v, joints[body::Index(info.proximal)], joints[body::Index(info.distal)]);
      if (d < nearest_d) {
        nearest_d = d;
        nearest = p;
        nearest_t = t;
      }
    }
    if (nearest == Index(part) && nearest_t > 0.3 && nearest_t < 0.7) {
      sum += nearest_d;
      ++n;
    }
  }
  return n > 0 ? sum / n : 0.0;
}

TEST(FitCylinderModel, RadiiMatchTheGroundTruthMesh) {
  RECON_REQUIRE_SHARED_TAKE();
  const auto& shared = GetSharedTake();
  auto take = TakeFrames::Load(shared.path);
  ASSERT_TRUE(take.ok()) << take.status();
  auto model = FitCylinderModel(**take, CylinderOptions{});
  ASSERT_TRUE(model.ok()) << model.status();
  const int rep = model->representative.instant;
  const int64_t frame_index = (*take)->instant(rep).views[model->representative.sensor].frame_index;
  std::printf(
      "[ figures  ] representative frame: instant %d of %d, sensor %d, E = %.3f "
      "(theta L/R %.0f/%.0f deg, |a| L/R %.2f/%.2f, g %.0f)\n",
      rep, (*take)->num_instants(), model->representative.sensor, model->representative.score.e,
      model->representative.score.theta_left_rad * 180 / M_PI,
      model->representative.score.theta_right_rad * 180 / M_PI, model->representative.score.a_left,
      model->representative.score.a_right, model->representative.score.g);
  // The arm raise lifts the arms over the take: the best frame is late.
  EXPECT_GT(rep, (*take)->num_instants() / 2);

  // Ground truth at the representative frame.
  auto reader = TakeReader::Open(shared.path);
  ASSERT_TRUE(reader.ok());
  std::vector<Vector3d> vertices;
  JointArray truth = MissingJoints();
  ASSERT_TRUE((*reader)
                  ->ForEach<v1::GroundTruthMesh>(
                      kGroundTruthMeshTopic,
                      [&](const v1::GroundTruthMesh& m) {
                        if (m.frame_index() != frame_index) {
                          return absl::OkStatus();
                        }
                        auto floats = UnpackFloats(m.positions_in_world_m_f32());
                        if (!floats.ok()) return floats.status();
                        for (size_t i = 0; i + 2 < floats->size(); i += 3) {
                          vertices.emplace_back((*floats)[i], (*floats)[i + 1], (*floats)[i + 2]);
                        }
                        return absl::OkStatus();
                      })
                  .ok());
  ASSERT_TRUE((*reader)
                  ->ForEach<v1::GroundTruthJoints>(
                      kGroundTruthJointsTopic,
                      [&](const v1::GroundTruthJoints& g) {
                        if (g.frame_index() != frame_index) return absl::OkStatus();
                        for (int i = 0; i < g.joint_names_size(); ++i) {
                          if (auto j = body::KinectV2JointFromName(g.joint_names(i))) {
                            truth[body::Index(*j)] = FromProto(g.positions_in_world_m(i));
                          }
                        }
                        return absl::OkStatus();
                      })
                  .ok());
  ASSERT_FALSE(vertices.empty());

  double worst_mm = 0;
  for (BodyPart part : {BodyPart::kForearmLeft, BodyPart::kForearmRight, BodyPart::kUpperArmLeft,
                        BodyPart::kUpperArmRight, BodyPart::kThighLeft, BodyPart::kThighRight,
                        BodyPart::kShinLeft, BodyPart::kShinRight}) {
    const PartRadius& fit = model->radii[Index(part)];
    const double true_r = TrueRadius(part, vertices, truth);
    ASSERT_GT(true_r, 0.01) << GetBodyPartInfo(part).name;
    const double error_mm = 1e3 * (fit.radius_m - true_r);
    std::printf(
        "[ figures  ] %-16s fitted r %.1f mm (%s, %d lines), true mean r %.1f mm, "
        "error %+.1f mm\n",
        std::string(GetBodyPartInfo(part).name).c_str(), 1e3 * fit.radius_m,
        fit.fitted ? "measured" : "default", fit.lines, 1e3 * true_r, error_mm);
    EXPECT_TRUE(fit.fitted) << GetBodyPartInfo(part).name;
    worst_mm = std::max(worst_mm, std::abs(error_mm));
  }
  // Depth pixels are ~7 mm at 2.5 m; the noisy sensor skeleton shifts the
  // axis by ~7 mm. Bound: 12 mm on every measured limb (the left shin, whose
  // calf the cylinder's mean radius underestimates, measures 10.2 mm since
  // the built-in motions' upper body was corrected; under 10 mm before).
  EXPECT_LT(worst_mm, 12.0);
  for (int p = 0; p < kNumBodyParts; ++p) {
    EXPECT_GT(model->reference_length_m[p], 0.02) << BodyParts()[p].name;
    EXPECT_GT(model->radii[p].radius_rate, 0.02) << BodyParts()[p].name;
  }
}

}  // namespace
}  // namespace reenact::recon
