#include "common/body/retarget.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/body/makehuman_importer.h"
#include "common/body/procedural_body.h"
#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;

// Spine, neck, upper arms, forearms, thighs and shins.
constexpr std::array<std::pair<J, J>, 12> kCheckedBones = {{
    {J::kSpineBase, J::kSpineMid},
    {J::kSpineMid, J::kSpineShoulder},
    {J::kSpineShoulder, J::kNeck},
    {J::kNeck, J::kHead},
    {J::kShoulderLeft, J::kElbowLeft},
    {J::kElbowLeft, J::kWristLeft},
    {J::kShoulderRight, J::kElbowRight},
    {J::kElbowRight, J::kWristRight},
    {J::kHipLeft, J::kKneeLeft},
    {J::kKneeLeft, J::kAnkleLeft},
    {J::kHipRight, J::kKneeRight},
    {J::kKneeRight, J::kAnkleRight},
}};

constexpr int kFrameStride = 30;

std::string Cmu(const std::string& name) {
  return reenact::testing::TestDataPath("mocap/cmu/" + name);
}

const BodyModel* MakeHumanModel() {
  static const BodyModel* model = [] {
    absl::StatusOr<BodyModel> result =
        ImportMakeHuman(reenact::testing::TestDataPath("body/makehuman"));
    EXPECT_TRUE(result.ok()) << result.status();
    return result.ok() ? new BodyModel(std::move(*result)) : nullptr;
  }();
  return model;
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

struct ClipFigures {
  double max_error_deg = 0.0;
  double mean_error_deg = 0.0;
  int bones_checked = 0;
  double lowest_vertex_y_m = 1e9;  // Over the checked frames.
};

// Retargets every kFrameStride-th frame of `motion` onto `model`, poses it,
// and compares the model's bone directions with the motion's. Bones whose
// motion length is under 1 cm (coincident source joints) are skipped.
ClipFigures CheckClip(const Motion& motion, const BodyModel& model, const std::string& label) {
  ClipFigures figures;
  const absl::StatusOr<RetargetedMotion> retargeted =
      RetargetMotion(motion, model, Eigen::VectorXd());
  EXPECT_TRUE(retargeted.ok()) << retargeted.status();
  if (!retargeted.ok()) return figures;
  EXPECT_EQ(static_cast<int>(retargeted->poses.size()), motion.num_frames());
  double sum_deg = 0.0;
  for (int f = 0; f < motion.num_frames(); f += kFrameStride) {
    const absl::StatusOr<PosedBody> posed =
        PoseBody(model, retargeted->poses[f], Eigen::VectorXd());
    EXPECT_TRUE(posed.ok()) << posed.status();
    if (!posed.ok()) return figures;
    EXPECT_EQ(posed->vertices_m.cols(), model.num_vertices());
    EXPECT_TRUE(posed->vertices_m.allFinite()) << label << " frame " << f;
    figures.lowest_vertex_y_m =
        std::min(figures.lowest_vertex_y_m, posed->vertices_m.row(1).minCoeff());
    const SkeletonPose target = motion.CanonicalPose(f);
    for (const auto& [from, to] : kCheckedBones) {
      if (!target.valid[Index(from)] || !target.valid[Index(to)]) continue;
      const Eigen::Vector3d motion_bone =
          target.position_m[Index(to)] - target.position_m[Index(from)];
      if (motion_bone.norm() < 0.01) continue;
      const Eigen::Vector3d model_bone = posed->joints_m[Index(to)] - posed->joints_m[Index(from)];
      const double error_deg = AngleDeg(model_bone, motion_bone);
      figures.max_error_deg = std::max(figures.max_error_deg, error_deg);
      sum_deg += error_deg;
      ++figures.bones_checked;
    }
  }
  figures.mean_error_deg = figures.bones_checked ? sum_deg / figures.bones_checked : 0.0;
  std::printf(
      "%s: %d bones over every %dth frame, bone direction error max %.4f deg, mean %.4f deg; "
      "scale %.3f, lowest vertex %.1f mm\n",
      label.c_str(), figures.bones_checked, kFrameStride, figures.max_error_deg,
      figures.mean_error_deg, retargeted->scale, 1e3 * figures.lowest_vertex_y_m);
  return figures;
}

void ExpectClipReproduced(const ClipFigures& figures) {
  EXPECT_GE(figures.bones_checked, 100);
  EXPECT_LT(figures.max_error_deg, 5.0);
  EXPECT_LT(figures.mean_error_deg, 5.0);
  // Feet reach the floor but do not sink through it by more than 5 cm.
  EXPECT_GT(figures.lowest_vertex_y_m, -0.05);
  EXPECT_LT(figures.lowest_vertex_y_m, 0.10);
}

TEST(RetargetMotion, MakeHumanFollows0101Bvh) {
  REENACT_REQUIRE_TEST_FILE(Cmu("01_01.bvh"));
  ASSERT_NE(MakeHumanModel(), nullptr);
  const absl::StatusOr<Motion> motion = ReadBvh(Cmu("01_01.bvh"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  ExpectClipReproduced(CheckClip(*motion, *MakeHumanModel(), "makehuman 01_01.bvh"));
}

TEST(RetargetMotion, MakeHumanFollows13101Bvh) {
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  ASSERT_NE(MakeHumanModel(), nullptr);
  const absl::StatusOr<Motion> motion = ReadBvh(Cmu("131_01.bvh"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  ExpectClipReproduced(CheckClip(*motion, *MakeHumanModel(), "makehuman 131_01.bvh"));
}

TEST(RetargetMotion, MakeHumanFollows0705AsfAmc) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07_05-walk.amc"));
  ASSERT_NE(MakeHumanModel(), nullptr);
  const absl::StatusOr<Motion> motion = ReadAsfAmc(Cmu("07-walk.asf"), Cmu("07_05-walk.amc"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  ExpectClipReproduced(CheckClip(*motion, *MakeHumanModel(), "makehuman 07_05 asf/amc"));
}

TEST(RetargetMotion, ProceduralBodyFollows0705AsfAmc) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07_05-walk.amc"));
  const absl::StatusOr<BodyModel> model = BuildProceduralBody();
  ASSERT_TRUE(model.ok()) << model.status();
  const absl::StatusOr<Motion> motion = ReadAsfAmc(Cmu("07-walk.asf"), Cmu("07_05-walk.amc"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  ExpectClipReproduced(CheckClip(*motion, *model, "procedural 07_05 asf/amc"));
}

TEST(RetargetFrame, RootPathDoesNotDependOnFileUnits) {
  REENACT_REQUIRE_TEST_FILE(Cmu("scaled_131_01.bvh"));
  ASSERT_NE(MakeHumanModel(), nullptr);
  // The same walk in two length units: the leg-length scaling cancels the unit.
  const absl::StatusOr<Motion> original = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = 0.3});
  const absl::StatusOr<Motion> scaled = ReadBvh(Cmu("scaled_131_01.bvh"), {.metres_per_unit = 1.0});
  ASSERT_TRUE(original.ok()) << original.status();
  ASSERT_TRUE(scaled.ok()) << scaled.status();
  // The scaled copy has one extra frame at the end; frame f is frame f.
  const int num_frames = std::min(original->num_frames(), scaled->num_frames());
  ASSERT_GT(num_frames, 100);
  RetargetOptions options;
  options.floor_sample_stride = 1;
  double max_gap_mm = 0.0;
  for (int f = 0; f < num_frames; f += 4 * kFrameStride) {
    const auto a = RetargetFrame(*original, f, *MakeHumanModel(), Eigen::VectorXd(), options);
    const auto b = RetargetFrame(*scaled, f, *MakeHumanModel(), Eigen::VectorXd(), options);
    ASSERT_TRUE(a.ok() && b.ok());
    max_gap_mm = std::max(max_gap_mm, 1e3 * (a->root_translation_m - b->root_translation_m).norm());
  }
  std::printf("131_01 root path, two units: max gap %.3f mm\n", max_gap_mm);
  EXPECT_LT(max_gap_mm, 2.0);
}

TEST(RetargetFrame, RejectsBadFrameAndOptions) {
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  ASSERT_NE(MakeHumanModel(), nullptr);
  const absl::StatusOr<Motion> motion = ReadBvh(Cmu("131_01.bvh"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_EQ(RetargetFrame(*motion, motion->num_frames(), *MakeHumanModel(), Eigen::VectorXd())
                .status()
                .code(),
            absl::StatusCode::kOutOfRange);
  RetargetOptions options;
  options.floor_sample_stride = 0;
  EXPECT_EQ(
      RetargetFrame(*motion, 0, *MakeHumanModel(), Eigen::VectorXd(), options).status().code(),
      absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::body
