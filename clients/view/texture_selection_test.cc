#include "clients/view/texture_selection.h"

#include <cmath>

#include <gtest/gtest.h>

#include "clients/view/testing/vdtm_scenes.h"

namespace reenact::view {
namespace {

using testing::MakeFrame;
using testing::MakeSquareReenactment;
using testing::Rad;
using testing::SolidKeyframe;

constexpr double kDeg = 1e-6;  // Tolerance of angles, degrees.

double Deg(double rad) { return rad * 180.0 / std::numbers::pi; }

// Sensors at -40, 0 and +40 degrees, one keyframe each at frame 0.
Reenactment ThreeSensorScene() {
  Reenactment data =
      MakeSquareReenactment({MakeFrame(0, 0.0), MakeFrame(1, 40.0)}, {-40.0, 0.0, 40.0});
  data.keyframes = {SolidKeyframe(0, "s0", {255, 0, 0}), SolidKeyframe(0, "s1", {0, 255, 0}),
                    SolidKeyframe(0, "s2", {0, 0, 255})};
  return data;
}

Eigen::Isometry3d CameraFromWorld(double yaw_deg) {
  return testing::WorldFromCamera(yaw_deg).inverse();
}

TEST(RotationAngle, IsTheAxisAngleMagnitude) {
  for (double deg : {0.0, 1e-4, 10.0, 90.0, 179.0, 180.0}) {
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(Rad(deg), Eigen::Vector3d(1, 2, -0.5).normalized()).toRotationMatrix();
    EXPECT_NEAR(Deg(RotationAngle(r)), deg, kDeg);
  }
}

TEST(RankByRotation, PicksTheKeyframeWithTheSmallestEq313Angle) {
  const Reenactment data = ThreeSensorScene();
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  // Viewer at +30 degrees: 10 degrees from s2, 30 from s1, 70 from s0.
  std::vector<double> angles;
  EXPECT_EQ(model->RankByRotation(0, 0, CameraFromWorld(30.0), &angles),
            (std::vector<int>{2, 1, 0}));
  ASSERT_EQ(angles.size(), 3u);
  EXPECT_NEAR(Deg(angles[0]), 10.0, kDeg);
  EXPECT_NEAR(Deg(angles[1]), 30.0, kDeg);
  EXPECT_NEAR(Deg(angles[2]), 70.0, kDeg);
  // At frame 1 the part has turned +40 degrees: seen from 0 degrees it shows
  // the face that s0 (-40) saw head-on at frame 0.
  EXPECT_EQ(model->RankByRotation(1, 0, CameraFromWorld(0.0), &angles),
            (std::vector<int>{0, 1, 2}));
  EXPECT_NEAR(Deg(angles[0]), 0.0, kDeg);
  EXPECT_NEAR(Deg(angles[1]), 40.0, kDeg);
  EXPECT_NEAR(Deg(angles[2]), 80.0, kDeg);
}

TEST(RankByRotation, SkipsKeyframesWhoseInstantHasThePartUnposed) {
  Reenactment data = ThreeSensorScene();
  data.frames[1].parts[0].valid = false;
  data.keyframes.push_back(SolidKeyframe(1, "s2", {9, 9, 9}));
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  EXPECT_EQ(model->RankByRotation(0, 0, CameraFromWorld(40.0)), (std::vector<int>{2, 1, 0}));
}

TEST(AssignTriangles, OccludedTrianglesGoToTheNextBestKeyframe) {
  Reenactment data = ThreeSensorScene();
  // In the best keyframe (s2) the left half of the square is hidden.
  testing::HideVertices(&data.keyframes[2], -1e-6);
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  const std::vector<int> ranking = model->RankByRotation(0, 0, CameraFromWorld(30.0));
  int not_best = -1;
  const std::vector<int> chosen = model->AssignTriangles(0, ranking, &not_best);
  const PartMesh& part = model->part(0);
  int to_best = 0, to_next = 0;
  for (size_t t = 0; t < chosen.size(); ++t) {
    const Eigen::Vector3i& tri = part.triangles[t];
    const bool touches_hidden = part.positions_in_part_m(0, tri[0]) < -1e-6 ||
                                part.positions_in_part_m(0, tri[1]) < -1e-6 ||
                                part.positions_in_part_m(0, tri[2]) < -1e-6;
    EXPECT_EQ(chosen[t], touches_hidden ? 1 : 2) << "triangle " << t;
    (touches_hidden ? to_next : to_best) += 1;
  }
  // 8 x 8 quads: the 4 left columns touch hidden vertices, the right 4 not.
  EXPECT_EQ(to_next, 64);
  EXPECT_EQ(to_best, 64);
  EXPECT_EQ(not_best, 64);
  // Hidden everywhere: no keyframe.
  for (auto& k : data.keyframes) testing::HideVertices(&k, 1.0);
  auto hidden = VdtmModel::Create(data);
  ASSERT_TRUE(hidden.ok());
  for (int k : hidden->AssignTriangles(0, ranking)) EXPECT_EQ(k, -1);
}

// Joints of a stick figure in the world: the neck at `neck`, every other
// joint offset from it; `arm_raise` lifts the left hand.
std::vector<Eigen::Vector3d> Skeleton(const Eigen::Vector3d& neck, double arm_raise) {
  std::vector<Eigen::Vector3d> joints(kNumSkeletonJoints);
  for (int j = 0; j < kNumSkeletonJoints; ++j) {
    joints[j] = neck + Eigen::Vector3d(0.05 * (j % 5) - 0.1, -0.08 * (j / 5), 0.03 * (j % 3));
  }
  joints[kNeckJoint] = neck;
  joints[7] = neck + Eigen::Vector3d(0.5, -0.4 + arm_raise, 0.1);  // HandLeft.
  return joints;
}

TEST(RankByPose, PicksThePoseClosestKeyframeInTheViewersFrame) {
  // Frame 0: arm down; frame 1: arm raised and the actor 1 m away (Eq. 3.6
  // is neck-relative, so the move does not count).
  const Eigen::Vector3d neck(0, 1.5, 0);
  Reenactment data = MakeSquareReenactment(
      {MakeFrame(0, 0.0, 1.0, Skeleton(neck, 0.0)),
       MakeFrame(1, 0.0, 1.0, Skeleton(neck + Eigen::Vector3d(1.0, 0, 0.5), 0.6)),
       MakeFrame(2, 0.0, 1.0, Skeleton(neck + Eigen::Vector3d(-0.3, 0, 0), 0.55))},
      {0.0, 90.0}, "rigid-cylinders");
  data.keyframes = {SolidKeyframe(0, "s0", {1, 1, 1}), SolidKeyframe(1, "s0", {2, 2, 2}),
                    SolidKeyframe(0, "s1", {3, 3, 3})};
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  // A file from before texture_mode goes by its method; a recorded mode wins.
  EXPECT_EQ(SelectionForReenactment(data.info), TextureSelection::kPose);
  ReenactmentInfo recorded = data.info;
  recorded.texture_mode = methods::TextureMode::kRotationClosest;
  EXPECT_EQ(SelectionForReenactment(recorded), TextureSelection::kRotation);
  recorded.method = "a-new-method";
  recorded.texture_mode = methods::TextureMode::kPoseClosest;
  EXPECT_EQ(SelectionForReenactment(recorded), TextureSelection::kPose);
  std::vector<double> distances;
  // Frame 2 (arm nearly as raised as frame 1) seen from s0's place.
  EXPECT_EQ(model->RankByPose(2, CameraFromWorld(0.0), &distances)[0], 1);
  // Frame 0 from s0's place: keyframe 0 is the same pose from the same camera.
  const std::vector<int> ranking = model->RankByPose(0, CameraFromWorld(0.0), &distances);
  EXPECT_EQ(ranking[0], 0);
  EXPECT_NEAR(distances[0], 0.0, 1e-12);
  // Frame 0 seen from 85 degrees: the keyframe of the sensor at 90 degrees.
  EXPECT_EQ(model->RankByPose(0, CameraFromWorld(85.0))[0], 2);
}

TEST(RankByPose, KeyframesWithoutJointsRankLast) {
  Reenactment data = MakeSquareReenactment(
      {MakeFrame(0, 0.0), MakeFrame(1, 0.0, 1.0, Skeleton({0, 1.5, 0}, 0.0))}, {0.0});
  data.keyframes = {SolidKeyframe(0, "s0", {1, 1, 1}), SolidKeyframe(1, "s0", {2, 2, 2})};
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  std::vector<double> distances;
  EXPECT_EQ(model->RankByPose(1, CameraFromWorld(0.0), &distances), (std::vector<int>{1, 0}));
  EXPECT_TRUE(std::isinf(distances[1]));
}

TEST(KeyframeUv, ProjectsThroughTheKeyframesPoseCropAndScale) {
  Reenactment data = MakeSquareReenactment({MakeFrame(0, 25.0, 1.5)}, {10.0});
  data.keyframes = {SolidKeyframe(0, "s0", {1, 1, 1})};
  data.keyframes[0].crop_x_px = 10;
  data.keyframes[0].crop_y_px = 20;
  data.keyframes[0].crop_scale = 0.5f;
  auto model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  const Eigen::Vector3f x(0.1f, -0.05f, 0.0f);
  // By hand: Eq. 3.14 (scale 1.5, 25 degrees about Y, at kCentre), Eq. 3.15.
  const Eigen::Vector3d world =
      testing::kCentre +
      Eigen::AngleAxisd(Rad(25.0), Eigen::Vector3d::UnitY()) * (1.5 * x.cast<double>());
  const Eigen::Vector3d camera = testing::WorldFromCamera(10.0).inverse() * world;
  const double px = testing::kFocalPx * camera.x() / camera.z() + (testing::kImageWidth - 1) / 2.0;
  const double py = testing::kFocalPx * camera.y() / camera.z() + (testing::kImageHeight - 1) / 2.0;
  const int w = 40, h = 30;
  const Eigen::Vector2f uv = model->KeyframeUv(0, 0, x, w, h);
  EXPECT_NEAR(uv.x(), (px - 10 + 0.5) * 0.5 / w, 1e-6);
  EXPECT_NEAR(uv.y(), 1.0 - (py - 20 + 0.5) * 0.5 / h, 1e-6);
}

// A depth-only sensor (no colour camera) is drawn untextured, not refused;
// a keyframe from it is.
TEST(VdtmModel, ASensorWithoutAColourCameraTexturesNothing) {
  Reenactment data = ThreeSensorScene();
  SensorCalibration depth_only = data.info.sensors[0];
  depth_only.sensor_id = "depth-only";
  depth_only.color_intrinsics = CameraIntrinsics();
  data.info.sensors.push_back(depth_only);
  absl::StatusOr<VdtmModel> model = VdtmModel::Create(data);
  ASSERT_TRUE(model.ok()) << model.status();
  EXPECT_EQ(model->num_keyframes(), static_cast<int>(data.keyframes.size()));
  data.keyframes[0].sensor_id = "depth-only";
  EXPECT_EQ(VdtmModel::Create(data).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(VdtmModel, InvalidReenactmentIsInvalidArgument) {
  Reenactment data = ThreeSensorScene();
  data.keyframes[0].sensor_id = "nobody";
  EXPECT_EQ(VdtmModel::Create(data).status().code(), absl::StatusCode::kInvalidArgument);
  data = ThreeSensorScene();
  data.parts[0].triangles.emplace_back(0, 1, 100000);
  EXPECT_EQ(VdtmModel::Create(data).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::view
