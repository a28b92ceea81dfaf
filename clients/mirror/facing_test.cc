#include "clients/mirror/facing.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"

#include "clients/mirror/testing/mocap_learners.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;
using body::SkeletonPose;
using testing::Joint;
using testing::kRadPerDeg;

constexpr int64_t kFrameNs = 33'333'333;  // 30 fps.

// A person standing in a level sensor's OpenCV frame 2.5 m away, facing the
// sensor: their own left is at +x (image right before the mirror flip).
SkeletonPose PersonFacingSensor() {
  SkeletonPose pose;
  auto set = [&](KinectV2Joint j, double x, double y) {
    pose.position_m[body::Index(j)] = {x, y, 2.5};
    pose.valid[body::Index(j)] = true;
  };
  set(KinectV2Joint::kSpineBase, 0.0, 0.0);
  set(KinectV2Joint::kSpineShoulder, 0.0, -0.5);
  set(KinectV2Joint::kShoulderLeft, 0.18, -0.5);
  set(KinectV2Joint::kShoulderRight, -0.18, -0.5);
  set(KinectV2Joint::kHipLeft, 0.1, 0.0);
  set(KinectV2Joint::kHipRight, -0.1, 0.0);
  return pose;
}

// `pose` turned by yaw_deg about the sensor's up (-y) through its SpineBase.
SkeletonPose TurnInSensor(const SkeletonPose& pose, double yaw_deg) {
  const Eigen::Vector3d pivot = Joint(pose, KinectV2Joint::kSpineBase);
  return TransformPose(Eigen::Translation3d(pivot) *
                           Eigen::AngleAxisd(yaw_deg * kRadPerDeg, -Eigen::Vector3d::UnitY()) *
                           Eigen::Translation3d(-pivot),
                       pose);
}

TEST(WrapDeg180, WrapsIntoHalfOpenRange) {
  EXPECT_DOUBLE_EQ(WrapDeg180(190.0), -170.0);
  EXPECT_DOUBLE_EQ(WrapDeg180(-180.0), 180.0);
  EXPECT_DOUBLE_EQ(WrapDeg180(540.0), 180.0);
  EXPECT_DOUBLE_EQ(WrapDeg180(-725.0), -5.0);
  EXPECT_NEAR(*CircularMeanDeg({170.0, -170.0}), 180.0, 1e-9);
  EXPECT_NEAR(*CircularMeanDeg({-10.0, 30.0}), 10.0, 1e-9);
  EXPECT_FALSE(CircularMeanDeg({}));
  EXPECT_FALSE(CircularMeanDeg({0.0, 180.0}));
}

TEST(FacingYawInSensorDeg, SignIsPositiveForATurnToTheirOwnLeft) {
  const SkeletonPose facing = PersonFacingSensor();
  EXPECT_NEAR(*FacingYawInSensorDeg(facing), 0.0, 1e-9);
  // Turned to their own left: forward goes to +x, the sensor sees their right side.
  const SkeletonPose left = TurnInSensor(facing, 90.0);
  EXPECT_NEAR(HorizontalForward(left, LevelSensorUp())->x(), 1.0, 1e-9);
  EXPECT_NEAR(*FacingYawInSensorDeg(left), 90.0, 1e-9);
  EXPECT_LT(Joint(left, KinectV2Joint::kShoulderRight).z(),
            Joint(left, KinectV2Joint::kShoulderLeft).z());
  EXPECT_NEAR(*FacingYawInSensorDeg(TurnInSensor(facing, -60.0)), -60.0, 1e-9);
  EXPECT_NEAR(std::abs(*FacingYawInSensorDeg(TurnInSensor(facing, 180.0))), 180.0, 1e-9);
}

TEST(FacingYawInSensorDeg, FallsBackToTheHipsAndRejectsBadJoints) {
  SkeletonPose pose = TurnInSensor(PersonFacingSensor(), 30.0);
  pose.position_m[body::Index(KinectV2Joint::kShoulderLeft)].x() = std::nan("");
  EXPECT_NEAR(*FacingYawInSensorDeg(pose), 30.0, 1e-9);
  pose.valid[body::Index(KinectV2Joint::kHipRight)] = false;
  EXPECT_FALSE(FacingYawInSensorDeg(pose));
  EXPECT_FALSE(FacingYawInSensorDeg(SkeletonPose{}));
}

TEST(FacingYawInWorldDeg, ZeroFacesPlusZNinetyFacesPlusX) {
  // PersonFacingSensor rotated into world: sensor (x, y, z) -> world (x, -y, -z)
  // makes them face +Z with their left at +X.
  Eigen::Isometry3d world_from_sensor = Eigen::Isometry3d::Identity();
  world_from_sensor.linear() = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const SkeletonPose in_world = TransformPose(world_from_sensor, PersonFacingSensor());
  EXPECT_NEAR(*FacingYawInWorldDeg(in_world), 0.0, 1e-9);
  EXPECT_NEAR(*FacingYawInWorldDeg(testing::TurnAboutSpineBase(in_world, 90.0)), 90.0, 1e-9);
  EXPECT_NEAR(
      HorizontalForward(testing::TurnAboutSpineBase(in_world, 90.0), Eigen::Vector3d::UnitY())->x(),
      1.0, 1e-9);
}

TEST(FacingYawInSensorDeg, CmuLearnerTurnedNinetyDegreesReadsNinety) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = testing::LoadCmuTeacher(8);
  ASSERT_FALSE(teacher.empty());
  double worst_deg = 0.0;
  for (double yaw_deg : {90.0, -90.0, 45.0, 180.0}) {
    for (const SkeletonPose& pose : teacher) {
      const Eigen::Isometry3d sensor_from_world = testing::SensorInFrontOf(pose);
      const SkeletonPose learner_in_sensor =
          TransformPose(sensor_from_world, testing::TurnAboutSpineBase(pose, yaw_deg));
      const std::optional<double> read_deg = FacingYawInSensorDeg(learner_in_sensor);
      ASSERT_TRUE(read_deg);
      worst_deg = std::max(worst_deg, std::abs(WrapDeg180(*read_deg - yaw_deg)));
    }
  }
  std::cout << "CMU learner turned by 90, -90, 45, 180 deg (" << teacher.size()
            << " frames each): facing read within " << worst_deg << " deg\n";
  RecordProperty("facing_worst_error_deg", std::to_string(worst_deg));
  EXPECT_LT(worst_deg, 5.0);
}

TEST(FacingYawInSensorDeg, TiltedSensorWithItsUpVector) {
  const SkeletonPose level = TurnInSensor(PersonFacingSensor(), 90.0);
  // The same scene seen by a sensor pitched 20 degrees down.
  const Eigen::Isometry3d tilted_from_level(
      Eigen::AngleAxisd(20.0 * kRadPerDeg, Eigen::Vector3d::UnitX()));
  const SkeletonPose tilted = TransformPose(tilted_from_level, level);
  const Eigen::Vector3d up_in_tilted = tilted_from_level.linear() * LevelSensorUp();
  EXPECT_NEAR(*FacingYawInSensorDeg(tilted, up_in_tilted), 90.0, 1e-9);
}

SteadinessDetector MakeDetector() {
  // Raw facings, so that the timings below are exact.
  absl::StatusOr<SteadinessDetector> detector = SteadinessDetector::Create({.smoothing_s = 0.0});
  EXPECT_TRUE(detector.ok());
  return *std::move(detector);
}

TEST(SteadinessDetector, JitterWithinToleranceLocksAfterTheHoldTime) {
  SteadinessDetector detector = MakeDetector();
  std::optional<int> first_steady_frame;
  for (int f = 0; f <= 90 && !first_steady_frame; ++f) {
    const double jitter_deg = 6.0 * std::sin(f * 1.7);  // Within +-6 of 40.
    if (detector.Add(f * kFrameNs, 40.0 + jitter_deg).steady) first_steady_frame = f;
  }
  ASSERT_TRUE(first_steady_frame);
  const double locked_after_s = *first_steady_frame * kFrameNs * 1e-9;
  std::cout << "jitter +-6 deg at 30 fps: steady after " << locked_after_s << " s, locked yaw "
            << *detector.status().mean_yaw_deg << " deg (true 40)\n";
  EXPECT_NEAR(locked_after_s, 2.0, 0.05);
  EXPECT_NEAR(*detector.status().mean_yaw_deg, 40.0, 1.5);
}

TEST(SteadinessDetector, ATurnResetsTheHold) {
  SteadinessDetector detector = MakeDetector();
  int f = 0;
  for (; f < 90; ++f) detector.Add(f * kFrameNs, 0.0);
  ASSERT_TRUE(detector.status().steady);
  detector.Add(f * kFrameNs, 45.0);  // Turned.
  EXPECT_FALSE(detector.status().steady);
  EXPECT_NEAR(detector.status().held_s, 0.0, 1e-9);
  const int turn_frame = f;
  for (++f; !detector.status().steady; ++f) detector.Add(f * kFrameNs, 45.0);
  const double relock_s = (f - 1 - turn_frame) * kFrameNs * 1e-9;
  std::cout << "after a 45 deg turn the facing locks again " << relock_s << " s later at "
            << *detector.status().mean_yaw_deg << " deg\n";
  EXPECT_NEAR(relock_s, 2.0, 0.05);
  EXPECT_NEAR(*detector.status().mean_yaw_deg, 45.0, 1e-9);
  // A lost learner restarts it too.
  detector.Add(f * kFrameNs, std::nullopt);
  EXPECT_FALSE(detector.status().steady);
  // So does a stamp that goes back.
  for (int g = 0; g < 70; ++g) detector.Add((f + g) * kFrameNs, 45.0);
  ASSERT_TRUE(detector.status().steady);
  detector.Add(0, 45.0);
  EXPECT_FALSE(detector.status().steady);
}

TEST(SteadinessDetector, WrapsAroundOneHundredEighty) {
  SteadinessDetector detector = MakeDetector();
  for (int f = 0; f <= 61; ++f) {
    detector.Add(f * kFrameNs, (f % 2 == 0) ? 176.0 : -174.0);  // Straddles +-180.
  }
  ASSERT_TRUE(detector.status().steady);
  std::cout << "yaw alternating 176 / -174 deg: locked at " << *detector.status().mean_yaw_deg
            << " deg\n";
  EXPECT_NEAR(std::abs(WrapDeg180(*detector.status().mean_yaw_deg - 181.0)), 0.0, 0.5);
}

TEST(SteadinessDetector, SmoothingLocksAJitteryFacingSideOn) {
  // A facing of 90 degrees with a side-on tracker's jitter: 7 degrees per
  // frame (3 cm on each end of a 35 cm shoulder line), 30 frames/s.
  std::mt19937 rng(11);
  std::normal_distribution<double> jitter_deg(0.0, 7.0);
  std::vector<double> yaws_deg;
  for (int f = 0; f < 150; ++f) yaws_deg.push_back(90.0 + jitter_deg(rng));
  std::optional<double> steady_after_s[2];
  double locked_deg = 0.0;
  for (const double smoothing_s : {0.0, 0.5}) {
    absl::StatusOr<SteadinessDetector> detector =
        SteadinessDetector::Create({.smoothing_s = smoothing_s});
    ASSERT_TRUE(detector.ok());
    for (int f = 0; f < 150; ++f) {
      if (detector->Add(f * kFrameNs, yaws_deg[f]).steady) {
        steady_after_s[smoothing_s > 0] = f * kFrameNs * 1e-9;
        locked_deg = *detector->status().mean_yaw_deg;
        break;
      }
    }
  }
  std::cout << "90 deg +- 7 deg jitter over 5 s: raw facings "
            << (steady_after_s[0] ? absl::StrCat("steady after ", *steady_after_s[0], " s")
                                  : std::string("never steady"))
            << "; smoothed over 0.5 s steady after " << steady_after_s[1].value_or(-1)
            << " s, locked at " << locked_deg << " deg\n";
  EXPECT_FALSE(steady_after_s[0].has_value());
  ASSERT_TRUE(steady_after_s[1].has_value());
  EXPECT_NEAR(*steady_after_s[1], 2.0, 0.5);  // s
  EXPECT_NEAR(locked_deg, 90.0, 3.0);         // deg
}

TEST(SteadinessOptions, RejectsBadValues) {
  EXPECT_FALSE(SteadinessDetector::Create({.tolerance_deg = 0.0}).ok());
  EXPECT_FALSE(SteadinessDetector::Create({.tolerance_deg = 10.0, .hold_s = -1.0}).ok());
  EXPECT_TRUE(SteadinessDetector::Create({.tolerance_deg = 5.0, .hold_s = 0.0}).ok());
  EXPECT_FALSE(SteadinessDetector::Create({.smoothing_s = -0.1}).ok());
}

TEST(ComputeTeacherTurn, TeacherFacesTheVirtualCameraAsRequested) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = testing::LoadCmuTeacher(4, 60);
  ASSERT_FALSE(teacher.empty());
  absl::StatusOr<TeacherFacing> facing = MeasureTeacherFacing(teacher, 30.0, 0.2);
  ASSERT_TRUE(facing.ok()) << facing.status();
  // A camera in front of the teacher turns it by the view yaw itself; a camera
  // off to one side (bearing +70, pitched down) needs a different turn.
  for (double bearing_offset_deg : {0.0, 70.0}) {
    absl::StatusOr<Eigen::Isometry3d> camera = PlaceVirtualCamera(
        facing->pivot_in_world, facing->facing_yaw_world_deg + bearing_offset_deg, 3.0, 1.8);
    ASSERT_TRUE(camera.ok());
    for (double view_deg : {0.0, 90.0, -90.0, 180.0}) {
      absl::StatusOr<TeacherTurn> turn = ComputeTeacherTurn(*facing, view_deg, *camera);
      ASSERT_TRUE(turn.ok());
      const SkeletonPose turned = TransformPose(turn->turned_from_original, teacher[0]);
      const double relative_deg = testing::FacingRelativeToCamera(turned, *camera);
      const double unturned_deg = testing::FacingRelativeToCamera(teacher[0], *camera);
      std::cout << "camera bearing +" << bearing_offset_deg << ", view " << view_deg << ": turn "
                << turn->turn_yaw_deg << " deg, teacher faces the camera at " << relative_deg
                << " deg\n";
      // Frame 0 against the mean over the first 0.2 s: close.
      EXPECT_NEAR(WrapDeg180(relative_deg - view_deg), 0.0, 5.0);
      EXPECT_NEAR(WrapDeg180(relative_deg - unturned_deg - turn->turn_yaw_deg), 0.0, 1e-6);
      if (bearing_offset_deg == 0.0) {
        EXPECT_NEAR(WrapDeg180(turn->turn_yaw_deg - view_deg), 0.0, 1e-9);
      }
      // The pivot stays put.
      EXPECT_LT(
          (turn->turned_from_original * facing->pivot_in_world - facing->pivot_in_world).norm(),
          1e-9);
    }
  }
}

TEST(ComputeTeacherTurn, RejectsACameraLookingStraightDown) {
  Eigen::Isometry3d looking_down = Eigen::Isometry3d::Identity();
  looking_down.linear() << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // z_camera = -Y world.
  EXPECT_FALSE(ComputeTeacherTurn({}, 0.0, looking_down).ok());
  EXPECT_FALSE(PlaceVirtualCamera(Eigen::Vector3d::Zero(), 0.0, 0.0, 1.0).ok());
  EXPECT_FALSE(MeasureTeacherFacing({}, 30.0, 1.0).ok());
  EXPECT_FALSE(MeasureTeacherFacing({SkeletonPose{}}, 30.0, 1.0).ok());
}

}  // namespace
}  // namespace reenact::mirror
