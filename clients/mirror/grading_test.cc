#include "clients/mirror/grading.h"

#include <cmath>
#include <limits>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "clients/mirror/testing/mocap_learners.h"
#include "common/testing/test_data.h"

namespace reenact::mirror {
namespace {

using testing::Joint;
using testing::LoadCmuTeacher;
using testing::TurnAboutSpineBase;

constexpr double kFps = 30.0;

std::vector<GradeFrame> Frames(const std::vector<body::SkeletonPose>& poses, double fps,
                               int repeat = 1) {
  std::vector<GradeFrame> frames;
  for (const body::SkeletonPose& pose : poses) {
    for (int r = 0; r < repeat; ++r) {
      GradeFrame f;
      f.time_s = static_cast<double>(frames.size()) / fps;
      f.pose = pose;
      MarkValidJointsSeen(f);
      frames.push_back(std::move(f));
    }
  }
  return frames;
}

// The right forearm (wrist and beyond) rotated about the elbow in the plane
// of the arm, bending the elbow `deg` more.
body::SkeletonPose BendRightElbow(const body::SkeletonPose& pose, double deg) {
  using body::KinectV2Joint;
  const Eigen::Vector3d shoulder = Joint(pose, KinectV2Joint::kShoulderRight);
  const Eigen::Vector3d elbow = Joint(pose, KinectV2Joint::kElbowRight);
  const Eigen::Vector3d wrist = Joint(pose, KinectV2Joint::kWristRight);
  Eigen::Vector3d axis = (elbow - shoulder).cross(wrist - elbow);
  if (axis.norm() < 1e-4) {
    axis = (elbow - shoulder)
               .cross(Joint(pose, KinectV2Joint::kHipLeft) - Joint(pose, KinectV2Joint::kHipRight));
  }
  const Eigen::AngleAxisd rotation(deg * testing::kRadPerDeg, axis.normalized());
  body::SkeletonPose bent = pose;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!testing::IsAtOrBelow(static_cast<KinectV2Joint>(j), KinectV2Joint::kWristRight)) continue;
    bent.position_m[j] = elbow + rotation * (pose.position_m[j] - elbow);
  }
  return bent;
}

class GradingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
    // 131_01 at 120 fps, every 4th frame: 30 fps, 4 s.
    teacher_poses_ = LoadCmuTeacher(4, 120);
    ASSERT_EQ(teacher_poses_.size(), 120u);
    teacher_ = Frames(teacher_poses_, kFps);
  }
  std::vector<body::SkeletonPose> teacher_poses_;
  std::vector<GradeFrame> teacher_;
};

TEST_F(GradingTest, TheSameMotionTurnedAndSlowerGradesNearZero) {
  for (const double yaw : {0.0, 30.0, 60.0, 90.0}) {
    std::vector<body::SkeletonPose> turned;
    for (const auto& pose : teacher_poses_) turned.push_back(TurnAboutSpineBase(pose, yaw));
    // At half the teacher's speed: every frame twice.
    const auto grade = GradeSequences(teacher_, Frames(turned, kFps, 2));
    ASSERT_TRUE(grade.ok()) << grade.status();
    ASSERT_TRUE(grade->mean_error_deg.has_value());
    EXPECT_LT(*grade->mean_error_deg, 0.5) << "yaw " << yaw;
    EXPECT_NEAR(grade->coverage, 1.0, 1e-9);
    EXPECT_TRUE(grade->corrections.empty());
    EXPECT_EQ(grade->num_learner_frames, 240);
  }
}

TEST_F(GradingTest, APartTheSensorDidNotSeeIsNotGradedHoweverWrongItsGuess) {
  std::vector<GradeFrame> learner = Frames(teacher_poses_, kFps);
  for (GradeFrame& f : learner) {
    // The tracker's guess for the hidden left arm: 0.5 m off.
    for (const auto j : {body::KinectV2Joint::kElbowLeft, body::KinectV2Joint::kWristLeft}) {
      f.pose->position_m[body::Index(j)] += Eigen::Vector3d(0.0, 0.5, -0.3);
      f.seen[body::Index(j)] = false;
    }
  }
  const auto grade = GradeSequences(teacher_, learner);
  ASSERT_TRUE(grade.ok()) << grade.status();
  EXPECT_LT(*grade->mean_error_deg, 0.5);
  EXPECT_NEAR(grade->coverage, 11.0 / 13.0, 1e-9);
  for (const BodyPart part : {BodyPart::kLeftUpperArm, BodyPart::kLeftLowerArm}) {
    const PartGrade& pg = grade->parts[Index(part)];
    EXPECT_FALSE(pg.graded);
    EXPECT_EQ(pg.graded_pairs, 0);
    EXPECT_EQ(pg.not_graded_reason, "hidden from the sensor");
  }
  const nlohmann::json j = nlohmann::json::parse(GradeJson(*grade));
  ASSERT_EQ(j["not_graded"].size(), 2u);
  EXPECT_EQ(j["not_graded"][0]["part"], "left_upper_arm");
  EXPECT_FALSE(j["parts"]["left_lower_arm"]["graded"].get<bool>());
}

TEST_F(GradingTest, AnElbowBentTooFarIsCorrectedInWordsAtTheRightTime) {
  // Between 1.5 and 2.5 s the learner bends the right elbow 30 degrees more.
  std::vector<body::SkeletonPose> learner = teacher_poses_;
  for (int i = 45; i < 75; ++i) learner[i] = BendRightElbow(learner[i], 30.0);
  GradeOptions options;
  options.use_dtw = false;
  const auto grade = GradeSequences(teacher_, Frames(learner, kFps), options);
  ASSERT_TRUE(grade.ok()) << grade.status();
  ASSERT_FALSE(grade->corrections.empty());
  const Correction& c = grade->corrections.front();
  EXPECT_EQ(c.part, BodyPart::kRightLowerArm);
  EXPECT_NEAR(c.error_deg, 30.0, 3.0);
  EXPECT_GE(c.time_s, 1.5);
  EXPECT_LE(c.time_s, 2.5);
  EXPECT_TRUE(std::regex_search(
      c.text, std::regex("^right elbow: straighten about (25|30|35) degrees at [12]\\.[0-9] s$")))
      << c.text;
  EXPECT_LE(grade->corrections.size(), 3u);
  // The one wrong part: nothing else is worth a correction.
  EXPECT_EQ(grade->corrections.size(), 1u);
  ASSERT_FALSE(grade->worst_moments.empty());
  EXPECT_EQ(grade->worst_moments.front().part, BodyPart::kRightLowerArm);
  EXPECT_GE(grade->worst_moments.front().time_s, 1.5);
  EXPECT_LE(grade->worst_moments.front().time_s, 2.5);
  for (size_t a = 0; a < grade->worst_moments.size(); ++a) {
    for (size_t b = a + 1; b < grade->worst_moments.size(); ++b) {
      EXPECT_GE(std::abs(grade->worst_moments[a].time_s - grade->worst_moments[b].time_s), 0.5);
    }
  }
  // Over the whole take: the part's mean is a quarter of 30 degrees.
  EXPECT_NEAR(*grade->parts[Index(BodyPart::kRightLowerArm)].mean_error_deg, 30.0 * 30 / 120, 1.0);

  const auto heat = GradeHeatMapPng(*grade);
  ASSERT_TRUE(heat.ok()) << heat.status();
  const cv::Mat heat_image = cv::imdecode(
      cv::Mat(1, static_cast<int>(heat->size()), CV_8U, const_cast<char*>(heat->data())),
      cv::IMREAD_COLOR);
  EXPECT_EQ(heat_image.cols, 1160);
  EXPECT_GT(heat_image.rows, 13 * 26);
  const auto worst = WorstMomentsPng(*grade, teacher_, Frames(learner, kFps));
  ASSERT_TRUE(worst.ok()) << worst.status();
  const cv::Mat worst_image = cv::imdecode(
      cv::Mat(1, static_cast<int>(worst->size()), CV_8U, const_cast<char*>(worst->data())),
      cv::IMREAD_COLOR);
  EXPECT_EQ(worst_image.rows, static_cast<int>(grade->worst_moments.size()) * 330);
}

TEST_F(GradingTest, FramesWithoutTheLearnerAreLeftOutNotCountedWrong) {
  std::vector<GradeFrame> learner = Frames(teacher_poses_, kFps);
  // The learner leaves the frame for a second; another second has NaN joints.
  for (int i = 30; i < 60; ++i) learner[i].pose.reset();
  for (int i = 60; i < 90; ++i) {
    learner[i].pose->position_m.fill(Eigen::Vector3d::Constant(std::nan("")));
  }
  const auto grade = GradeSequences(teacher_, learner);
  ASSERT_TRUE(grade.ok()) << grade.status();
  EXPECT_LT(*grade->mean_error_deg, 0.5);
  EXPECT_EQ(grade->learner_frames_without_skeleton, 30);
  EXPECT_LT(grade->coverage, 0.55);
  EXPECT_GT(grade->coverage, 0.3);
  for (const GradedPair& pair : grade->pairs) {
    if (pair.learner_frame >= 30 && pair.learner_frame < 60) {
      EXPECT_EQ(pair.status[0], PartStatus::kNoLearner);
      EXPECT_FALSE(pair.mean_error_deg.has_value());
    }
  }
}

TEST_F(GradingTest, ATeacherWithoutSomeJointsHasThosePartsNeutral) {
  std::vector<GradeFrame> teacher = teacher_;
  for (GradeFrame& f : teacher) {
    f.pose->valid[body::Index(body::KinectV2Joint::kNeck)] = false;  // Kinect v1 has no neck.
  }
  const auto grade = GradeSequences(teacher, Frames(teacher_poses_, kFps));
  ASSERT_TRUE(grade.ok()) << grade.status();
  EXPECT_FALSE(grade->parts[Index(BodyPart::kHead)].graded);
  EXPECT_EQ(grade->parts[Index(BodyPart::kHead)].not_graded_reason, "teacher has no such joints");
  EXPECT_NEAR(grade->coverage, 12.0 / 13.0, 1e-9);
}

TEST_F(GradingTest, TheActionWeightedErrorCountsThePartsTheTeacherMoves) {
  // A learner whose left lower leg is 30 degrees off throughout.
  std::vector<body::SkeletonPose> learner = teacher_poses_;
  const auto knee = body::KinectV2Joint::kKneeLeft;
  for (body::SkeletonPose& pose : learner) {
    const Eigen::Vector3d k = Joint(pose, knee);
    const Eigen::Vector3d shin = Joint(pose, body::KinectV2Joint::kAnkleLeft) - k;
    const Eigen::AngleAxisd turn(30.0 * testing::kRadPerDeg,
                                 shin.cross(Eigen::Vector3d::UnitX()).normalized());
    for (const auto j : {body::KinectV2Joint::kAnkleLeft, body::KinectV2Joint::kFootLeft}) {
      pose.position_m[body::Index(j)] = k + turn * (Joint(pose, j) - k);
    }
  }
  GradeOptions options;
  options.use_dtw = false;
  const auto grade = GradeSequences(teacher_, Frames(learner, kFps), options);
  ASSERT_TRUE(grade.ok()) << grade.status();
  // The weights are the teacher's motion plus the floor.
  double num = 0, den = 0;
  for (const PartGrade& part : grade->parts) {
    ASSERT_TRUE(part.graded);
    EXPECT_TRUE(std::isfinite(part.teacher_motion_deg));
    EXPECT_GE(part.teacher_motion_deg, 0.0);
    EXPECT_LE(part.teacher_motion_deg, 90.0);
    num += (part.teacher_motion_deg + options.motion_weight_floor_deg) * *part.mean_error_deg;
    den += part.teacher_motion_deg + options.motion_weight_floor_deg;
  }
  ASSERT_TRUE(grade->action_error_deg.has_value());
  EXPECT_NEAR(*grade->action_error_deg, num / den, 1e-9);
  EXPECT_NEAR(*grade->parts[Index(BodyPart::kLeftLowerLeg)].mean_error_deg, 30.0, 0.5);
  // A teacher who holds one pose moves nothing: every part weighs the floor.
  std::vector<GradeFrame> frozen =
      Frames(std::vector<body::SkeletonPose>(teacher_poses_.size(), teacher_poses_.front()), kFps);
  const auto still = GradeSequences(frozen, frozen, options);
  ASSERT_TRUE(still.ok()) << still.status();
  for (const PartGrade& part : still->parts) EXPECT_NEAR(part.teacher_motion_deg, 0.0, 1e-6);
  EXPECT_NEAR(*still->action_error_deg, 0.0, 1e-6);
}

TEST_F(GradingTest, BadInputIsRefusedWithAMessage) {
  EXPECT_EQ(GradeSequences({}, teacher_).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(GradeSequences(teacher_, {}).status().code(), absl::StatusCode::kInvalidArgument);
  std::vector<GradeFrame> nobody(10);
  const auto none = GradeSequences(teacher_, nobody);
  EXPECT_EQ(none.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(none.status().message().find("learner"), std::string::npos);
  const auto no_teacher = GradeSequences(nobody, teacher_);
  EXPECT_NE(no_teacher.status().message().find("teacher"), std::string::npos);
  GradeOptions bad;
  bad.smoothing_s = std::numeric_limits<double>::infinity();
  EXPECT_EQ(GradeSequences(teacher_, teacher_, bad).status().code(),
            absl::StatusCode::kInvalidArgument);
  bad = {};
  bad.motion_weight_floor_deg = -1.0;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.max_corrections = 14;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.dtw.max_cells = 100;  // Too small for 120 x 120.
  EXPECT_FALSE(GradeSequences(teacher_, teacher_, bad).ok());
}

}  // namespace
}  // namespace reenact::mirror
