#include "common/tracking/skeleton_assembly.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

namespace reenact::tracking {
namespace {

using J = body::KinectV2Joint;
constexpr int kNumJoints = body::kNumKinectV2Joints;

// A standing person 2.5 m in front of the camera, facing it (camera axes:
// x right, y down; the person's left is the camera's +x), metres.
std::array<Eigen::Vector3f, kNumJoints> Standing() {
  std::array<Eigen::Vector3f, kNumJoints> p;
  const auto at = [&](J j, float x, float y, float z) { p[body::Index(j)] = {x, y, 2.5f + z}; };
  at(J::kSpineBase, 0, 0, 0);
  at(J::kSpineMid, 0, -0.21f, 0);
  at(J::kSpineShoulder, 0, -0.45f, 0);
  at(J::kNeck, 0, -0.53f, 0);
  at(J::kHead, 0, -0.65f, 0);
  for (int side : {1, -1}) {
    const bool left = side > 0;
    const float s = static_cast<float>(side);
    at(left ? J::kHipLeft : J::kHipRight, 0.09f * s, 0.03f, 0);
    at(left ? J::kKneeLeft : J::kKneeRight, 0.09f * s, 0.46f, 0);
    at(left ? J::kAnkleLeft : J::kAnkleRight, 0.09f * s, 0.88f, 0);
    at(left ? J::kFootLeft : J::kFootRight, 0.09f * s, 0.93f, -0.15f);
    at(left ? J::kShoulderLeft : J::kShoulderRight, 0.21f * s, -0.44f, 0);
    at(left ? J::kElbowLeft : J::kElbowRight, 0.24f * s, -0.13f, 0);
    at(left ? J::kWristLeft : J::kWristRight, 0.25f * s, 0.10f, 0);
    at(left ? J::kHandLeft : J::kHandRight, 0.25f * s, 0.175f, 0);
    at(left ? J::kHandTipLeft : J::kHandTipRight, 0.25f * s, 0.255f, 0);
    at(left ? J::kThumbLeft : J::kThumbRight, 0.22f * s, 0.16f, -0.04f);
  }
  return p;
}

J Mirror(J j) {
  for (auto [l, r] : {std::pair{J::kHipLeft, J::kHipRight},
                      {J::kKneeLeft, J::kKneeRight},
                      {J::kAnkleLeft, J::kAnkleRight},
                      {J::kFootLeft, J::kFootRight},
                      {J::kShoulderLeft, J::kShoulderRight},
                      {J::kElbowLeft, J::kElbowRight},
                      {J::kWristLeft, J::kWristRight},
                      {J::kHandLeft, J::kHandRight},
                      {J::kHandTipLeft, J::kHandTipRight},
                      {J::kThumbLeft, J::kThumbRight}}) {
    if (j == l) return r;
    if (j == r) return l;
  }
  return j;
}

// Evidence with the given modes; a joint's share near a point is that of
// its nearest mode within 5 cm.
JointEvidence Evidence(const std::array<std::vector<JointMode>, kNumJoints>& modes) {
  JointEvidence e;
  e.modes = modes;
  e.share_at = [modes](int joint, const Eigen::Vector3f& point) {
    float share = 0;
    for (const JointMode& m : modes[joint]) {
      if ((m.position_m - point).norm() < 0.05f) share = std::max(share, m.share);
    }
    return share;
  };
  return e;
}

double ErrorMm(const std::array<TrackedJoint, kNumJoints>& joints,
               const std::array<Eigen::Vector3f, kNumJoints>& truth, J j) {
  return (joints[body::Index(j)].position_in_camera_m - truth[body::Index(j)].cast<double>())
             .norm() *
         1e3;
}

TEST(AssembleSkeleton, TheDensestModesOfAConsistentSkeletonAreKept) {
  const auto truth = Standing();
  std::array<std::vector<JointMode>, kNumJoints> modes;
  for (int j = 0; j < kNumJoints; ++j) modes[j] = {{truth[j], 0.5f}};
  const auto joints = AssembleSkeleton(Evidence(modes), nullptr);
  for (int j = 0; j < kNumJoints; ++j) {
    EXPECT_LT(ErrorMm(joints, truth, static_cast<J>(j)), 1.0)
        << body::KinectV2JointName(static_cast<J>(j));
    EXPECT_EQ(joints[j].state, JointState::kInferred);
    EXPECT_NEAR(joints[j].confidence, 0.5, 0.1);
  }
}

// The forest took the legs for those of a person facing away: each knee,
// ankle and foot votes mostly for its mirror, a little for itself. The hips
// (and the shoulders, tied by the twist term) say which side is which.
TEST(AssembleSkeleton, LegsVotedForTheOtherSideAreSwappedBack) {
  const auto truth = Standing();
  std::array<std::vector<JointMode>, kNumJoints> modes;
  for (int j = 0; j < kNumJoints; ++j) modes[j] = {{truth[j], 0.5f}};
  for (J j : {J::kKneeLeft, J::kKneeRight, J::kAnkleLeft, J::kAnkleRight}) {
    modes[body::Index(j)] = {{truth[body::Index(Mirror(j))], 0.4f}, {truth[body::Index(j)], 0.3f}};
  }
  const auto joints = AssembleSkeleton(Evidence(modes), nullptr);
  for (J j : {J::kKneeLeft, J::kKneeRight, J::kAnkleLeft, J::kAnkleRight}) {
    const double mm = ErrorMm(joints, truth, j);
    std::printf("%s %.1f mm from the truth\n", std::string(body::KinectV2JointName(j)).c_str(), mm);
    EXPECT_LT(mm, 1.0) << body::KinectV2JointName(j);
  }
}

// A knee raised towards the camera: both knees' densest modes lie on the
// standing knee, the raised knee is the right knee's second mode.
TEST(AssembleSkeleton, AKneeCountedTwiceTakesItsSecondMode) {
  auto truth = Standing();
  truth[body::Index(J::kKneeRight)] =
      truth[body::Index(J::kHipRight)] + Eigen::Vector3f(0, 0, -0.43f);
  truth[body::Index(J::kAnkleRight)] =
      truth[body::Index(J::kKneeRight)] + Eigen::Vector3f(0, 0.42f, 0);
  truth[body::Index(J::kFootRight)] =
      truth[body::Index(J::kAnkleRight)] + Eigen::Vector3f(0, 0.05f, -0.15f);
  std::array<std::vector<JointMode>, kNumJoints> modes;
  for (int j = 0; j < kNumJoints; ++j) modes[j] = {{truth[j], 0.5f}};
  modes[body::Index(J::kKneeRight)] = {{truth[body::Index(J::kKneeLeft)], 0.5f},
                                       {truth[body::Index(J::kKneeRight)], 0.2f}};
  const auto joints = AssembleSkeleton(Evidence(modes), nullptr);
  const double mm = ErrorMm(joints, truth, J::kKneeRight);
  std::printf("raised knee %.1f mm from the truth\n", mm);
  EXPECT_LT(mm, 1.0);
  EXPECT_LT(ErrorMm(joints, truth, J::kKneeLeft), 1.0);
}

// A hidden hand whose votes went half a metre away is put at the
// continuation of its forearm, with little confidence.
TEST(AssembleSkeleton, AnImplausibleHandContinuesItsForearmWithLowConfidence) {
  const auto truth = Standing();
  std::array<std::vector<JointMode>, kNumJoints> modes;
  for (int j = 0; j < kNumJoints; ++j) modes[j] = {{truth[j], 0.5f}};
  modes[body::Index(J::kHandLeft)] = {
      {truth[body::Index(J::kWristLeft)] + Eigen::Vector3f(0.5f, 0, 0), 0.5f}};
  const auto joints = AssembleSkeleton(Evidence(modes), nullptr);
  const double mm = ErrorMm(joints, truth, J::kHandLeft);
  std::printf("hidden hand %.1f mm from the truth, confidence %.3f\n", mm,
              joints[body::Index(J::kHandLeft)].confidence);
  EXPECT_LT(mm, 20.0);
  EXPECT_LT(joints[body::Index(J::kHandLeft)].confidence, 0.05);
}

TEST(AssembleSkeleton, NoVotesGiveJointsNotTracked) {
  std::array<std::vector<JointMode>, kNumJoints> modes;
  const auto joints = AssembleSkeleton(Evidence(modes), nullptr);
  for (const TrackedJoint& j : joints) EXPECT_EQ(j.state, JointState::kNotTracked);
  SkeletonAssemblyOptions bad;
  bad.bone_sigma = 0;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.cap = std::nan("");
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace reenact::tracking
