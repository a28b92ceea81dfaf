#include "common/body/motion.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iostream>
#include <string>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;

constexpr double kMm = 1e-3;
constexpr double kCm = 1e-2;
constexpr double kDegPerRad = 180.0 / M_PI;

// CMU's ASF unit: ":units length 0.45" -> 1 unit = 1/0.45 inch.
constexpr double kCmuMetresPerUnit = 0.0254 / 0.45;

std::string Cmu(const std::string& name) {
  return reenact::testing::TestDataPath("mocap/cmu/" + name);
}

const Eigen::Vector3d& At(const SkeletonPose& pose, J joint) {
  return pose.position_m[static_cast<size_t>(Index(joint))];
}

double Distance(const SkeletonPose& pose, J a, J b) { return (At(pose, a) - At(pose, b)).norm(); }

// Angle (degrees) between the segment a->b and the horizontal plane.
double ElevationDeg(const SkeletonPose& pose, J a, J b) {
  const Eigen::Vector3d d = (At(pose, b) - At(pose, a)).normalized();
  return std::asin(std::clamp(d.y(), -1.0, 1.0)) * kDegPerRad;
}

// Height (metres) from the lowest foot joint to the highest joint, end sites
// included (the top of the head).
double StandingHeightM(const Motion& motion, int frame) {
  const std::vector<Eigen::Isometry3d> world = motion.WorldFromJoints(frame);
  double top = -1e9;
  double bottom = 1e9;
  for (const Eigen::Isometry3d& x : world) {
    top = std::max(top, x.translation().y());
    bottom = std::min(bottom, x.translation().y());
  }
  return top - bottom;
}

std::string WriteTemp(const std::string& name, const std::string& contents) {
  const std::string dir = reenact::testing::MakeTempDir("motion");
  const std::string path = dir + "/" + name;
  std::ofstream(path) << contents;
  return path;
}

// A small BVH: root Hips at OFFSET (1, 2, 3) units, Chest 1 unit up with an
// end site 1 unit further; the other joints (no channels) only give it the
// 3dsMax names that joint-set detection needs.
std::string TinyBvh(const std::string& frames) {
  std::string text =
      "HIERARCHY\n"
      "ROOT Hips\n"
      "{\n"
      "  OFFSET 1 2 3\n"
      "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
      "  JOINT Chest\n"
      "  {\n"
      "    OFFSET 0 1 0\n"
      "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "    End Site\n"
      "    {\n"
      "      OFFSET 0 1 0\n"
      "    }\n"
      "  }\n";
  for (const char* name : {"LeftShoulder", "RightShoulder", "LeftElbow", "RightElbow", "LeftHip",
                           "RightHip", "LeftKnee", "RightKnee"}) {
    text += std::string("  JOINT ") + name + " { OFFSET 0 0 0 CHANNELS 0 }\n";
  }
  return text + "}\nMOTION\n" + frames;
}

// 1-based number of the first line of `text` that contains `needle`.
int LineOf(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

TEST(ReadBvh, RotationChannelsComposeInDeclaredOrder) {
  const std::string path =
      WriteTemp("tiny.bvh", TinyBvh("Frames: 1\nFrame Time: 0.5\n0 0 0 30 40 50 10 20 70\n"));
  auto motion = ReadBvh(path, {.metres_per_unit = 0.1});
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_DOUBLE_EQ(motion->fps(), 2.0);
  const auto rot = [](double deg, const Eigen::Vector3d& axis) {
    return Eigen::AngleAxisd(deg / kDegPerRad, axis).toRotationMatrix();
  };
  const Eigen::Matrix3d root = rot(30, Eigen::Vector3d::UnitZ()) *
                               rot(40, Eigen::Vector3d::UnitX()) *
                               rot(50, Eigen::Vector3d::UnitY());
  const Eigen::Matrix3d spine = rot(10, Eigen::Vector3d::UnitZ()) *
                                rot(20, Eigen::Vector3d::UnitX()) *
                                rot(70, Eigen::Vector3d::UnitY());
  const Eigen::Vector3d root_m(0.1, 0.2, 0.3);
  const Eigen::Vector3d end_expected_m =
      root_m + root * Eigen::Vector3d(0, 0.1, 0) + root * spine * Eigen::Vector3d(0, 0.1, 0);
  const std::vector<Eigen::Isometry3d> world = motion->WorldFromJoints(0);
  ASSERT_EQ(world.size(), 11u);
  EXPECT_EQ(motion->joints()[2].name, "Chest_end");
  EXPECT_LT((world[0].translation() - root_m).norm(), 1e-3 * kMm);
  EXPECT_LT((world[2].translation() - end_expected_m).norm(), 1e-3 * kMm);
}

TEST(ReadBvh, ScaledCopyAgreesWithinOneMillimetre) {
  // scaled_131_01.bvh is 131_01.bvh with every length multiplied by the CMU
  // unit, 0.0254 / 0.45 = 0.05644 m per unit (root OFFSETs and positions too),
  // and one extra frame appended at the end; frame f of one is frame f of the
  // other.
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  REENACT_REQUIRE_TEST_FILE(Cmu("scaled_131_01.bvh"));
  auto original = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = kCmuMetresPerUnit});
  auto scaled = ReadBvh(Cmu("scaled_131_01.bvh"), {.metres_per_unit = 1.0});
  ASSERT_TRUE(original.ok()) << original.status();
  ASSERT_TRUE(scaled.ok()) << scaled.status();
  EXPECT_EQ(original->info().unit_source, UnitSource::kGiven);
  EXPECT_EQ(original->info().joint_set, JointSetId::kCmuBvh3dsMax);
  ASSERT_EQ(scaled->num_frames(), original->num_frames() + 1);
  double worst_m = 0.0;
  for (int frame : {0, 1, 250, 500, 777, original->num_frames() - 1}) {
    const SkeletonPose a = original->CanonicalPose(frame);
    const SkeletonPose b = scaled->CanonicalPose(frame);
    for (int j = 0; j < kNumKinectV2Joints; ++j) {
      ASSERT_TRUE(a.valid[j] && b.valid[j]) << KinectV2JointName(static_cast<J>(j));
      worst_m = std::max(worst_m, (a.position_m[j] - b.position_m[j]).norm());
    }
  }
  std::cout << "131_01 vs scaled_131_01: worst joint difference " << worst_m / kMm << " mm\n";
  EXPECT_LT(worst_m, 1 * kMm);
}

// 131_01 written back as BVH (centimetres) and read again: the same
// joints, rate and frames, and every joint within 0.01 mm of where the
// original puts it.
TEST(WriteBvh, RoundTripThroughReadBvhKeepsEveryJoint) {
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  auto original = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = kCmuMetresPerUnit});
  ASSERT_TRUE(original.ok()) << original.status();
  const std::string path = reenact::testing::MakeTempDir("bvh_write") + "/131_01_cm.bvh";
  ASSERT_TRUE(WriteBvh(*original, path).ok());
  auto back = ReadBvh(path, {.metres_per_unit = 0.01});
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->joints().size(), original->joints().size());
  for (size_t j = 0; j < original->joints().size(); ++j) {
    EXPECT_EQ(back->joints()[j].name, original->joints()[j].name);
    EXPECT_EQ(back->joints()[j].parent, original->joints()[j].parent);
  }
  EXPECT_EQ(back->info().joint_set, original->info().joint_set);
  ASSERT_EQ(back->num_frames(), original->num_frames());
  EXPECT_NEAR(back->fps(), original->fps(), 1e-6);
  double worst_m = 0.0;
  for (int frame = 0; frame < original->num_frames(); frame += 37) {
    const std::vector<Eigen::Isometry3d> a = original->WorldFromJoints(frame);
    const std::vector<Eigen::Isometry3d> b = back->WorldFromJoints(frame);
    for (size_t j = 0; j < a.size(); ++j) {
      worst_m = std::max(worst_m, (a[j].translation() - b[j].translation()).norm());
    }
  }
  std::cout << "131_01 written and read back: worst joint difference " << worst_m / kMm << " mm\n";
  EXPECT_LT(worst_m, 0.01 * kMm);
}

TEST(WriteBvh, BadInputIsAnErrorAndLeavesNoFile) {
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  auto original = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = kCmuMetresPerUnit});
  ASSERT_TRUE(original.ok()) << original.status();
  const std::string dir = reenact::testing::MakeTempDir("bvh_write_bad");
  EXPECT_EQ(WriteBvh(*original, dir + "/a.bvh", {.metres_per_unit = 0.0}).code(),
            absl::StatusCode::kInvalidArgument);
  std::vector<MotionJoint> joints = original->joints();
  std::vector<std::vector<Eigen::Quaterniond>> rotations = {original->local_rotations(0)};
  rotations[0][1] = Eigen::Quaterniond(std::nan(""), 0, 0, 0);
  const Motion broken(original->info(), joints, rotations, {original->root_translation_m(0)});
  EXPECT_EQ(WriteBvh(broken, dir + "/b.bvh").code(), absl::StatusCode::kInvalidArgument);
  joints[1].name = "two words";
  const Motion badly_named(original->info(), joints, {original->local_rotations(0)},
                           {original->root_translation_m(0)});
  EXPECT_EQ(WriteBvh(badly_named, dir + "/c.bvh").code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(WriteBvh(*original, dir + "/no/such/folder/d.bvh").ok());
  for (const char* name : {"a.bvh", "b.bvh", "c.bvh"}) {
    EXPECT_FALSE(std::ifstream(dir + "/" + name).good()) << name;
  }
}

TEST(ReadBvh, DetectedUnitScalesRestPoseToAssumedStature) {
  REENACT_REQUIRE_TEST_FILE(Cmu("131_01.bvh"));
  REENACT_REQUIRE_TEST_FILE(Cmu("scaled_131_01.bvh"));
  auto detected = ReadBvh(Cmu("131_01.bvh"));
  auto scaled = ReadBvh(Cmu("scaled_131_01.bvh"), {.metres_per_unit = 1.0});
  ASSERT_TRUE(detected.ok()) << detected.status();
  ASSERT_TRUE(scaled.ok()) << scaled.status();
  EXPECT_EQ(detected->info().unit_source, UnitSource::kDetectedFromStature);
  const std::vector<Eigen::Isometry3d> rest = detected->RestWorldFromJoints();
  double top = 0, bottom = 0;
  for (const auto& x : rest) {
    top = std::max(top, x.translation().y());
    bottom = std::min(bottom, x.translation().y());
  }
  EXPECT_NEAR(top - bottom, kAssumedStatureM, 1 * kMm);
  // Detected and true units differ by one factor: rescaled, the poses agree.
  const double factor = kCmuMetresPerUnit / detected->info().metres_per_unit;
  std::cout << "131_01: detected " << detected->info().metres_per_unit << " m/unit, true "
            << kCmuMetresPerUnit << " m/unit\n";
  double worst_m = 0.0;
  for (int frame : {0, 400, 993}) {
    const SkeletonPose a = detected->CanonicalPose(frame);
    const SkeletonPose b = scaled->CanonicalPose(frame);
    for (int j = 0; j < kNumKinectV2Joints; ++j) {
      worst_m = std::max(worst_m, (a.position_m[j] * factor - b.position_m[j]).norm());
    }
  }
  EXPECT_LT(worst_m, 1 * kMm);
}

TEST(ReadAsfAmc, WalkerStandsAdultHeight) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07-walk.asf"));
  auto motion = ReadAsfAmc(Cmu("07-walk.asf"), Cmu("07_05-walk.amc"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_EQ(motion->info().unit_source, UnitSource::kAsfHeader);
  EXPECT_NEAR(motion->info().metres_per_unit, 0.05644, 0.00001);
  EXPECT_EQ(motion->info().joint_set, JointSetId::kCmuAsf);
  // The standing frame: the one where the ankles are closest together.
  int standing = 0;
  double closest_m = 1e9;
  for (int f = 0; f < motion->num_frames(); ++f) {
    const SkeletonPose pose = motion->CanonicalPose(f);
    const double d = Distance(pose, J::kAnkleLeft, J::kAnkleRight);
    if (d < closest_m) closest_m = d, standing = f;
  }
  const double height_m = StandingHeightM(*motion, standing);
  std::cout << "07_05 walk: height " << height_m << " m on frame " << standing << "\n";
  EXPECT_GT(height_m, 1.4);
  EXPECT_LT(height_m, 1.9);
}

TEST(ReadAsfAmc, KneeBendsAboutAnAxisPerpendicularToTheThigh) {
  // ltibia has one dof (rx) about an axis tilted 20 degrees by `axis 0 0 20`.
  // With L = C M C^-1 the hinge is perpendicular to the leg, so the angle
  // between thigh and shin equals the rotation angle in every frame.
  REENACT_REQUIRE_TEST_FILE(Cmu("07-walk.asf"));
  auto motion = ReadAsfAmc(Cmu("07-walk.asf"), Cmu("07_05-walk.amc"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  const int tibia = motion->canonical_to_source()[Index(J::kKneeLeft)];
  ASSERT_GE(tibia, 0);
  double worst_deg = 0.0;
  for (int f = 0; f < motion->num_frames(); f += 5) {
    const SkeletonPose pose = motion->CanonicalPose(f);
    const Eigen::Vector3d thigh = At(pose, J::kKneeLeft) - At(pose, J::kHipLeft);
    const Eigen::Vector3d shin = At(pose, J::kAnkleLeft) - At(pose, J::kKneeLeft);
    const double bend_deg =
        std::acos(std::clamp(thigh.normalized().dot(shin.normalized()), -1.0, 1.0)) * kDegPerRad;
    const double rotation_deg =
        Eigen::AngleAxisd(motion->local_rotations(f)[tibia]).angle() * kDegPerRad;
    worst_deg = std::max(worst_deg, std::abs(bend_deg - rotation_deg));
  }
  EXPECT_LT(worst_deg, 0.1);
}

TEST(ReadBvh, FirstFrameOf0101IsTPose) {
  REENACT_REQUIRE_TEST_FILE(Cmu("01_01.bvh"));
  auto motion = ReadBvh(Cmu("01_01.bvh"));
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_EQ(motion->info().joint_set, JointSetId::kCmuBvhCgspeed);
  const SkeletonPose pose = motion->CanonicalPose(0);
  const double upper_left = ElevationDeg(pose, J::kShoulderLeft, J::kElbowLeft);
  const double fore_left = ElevationDeg(pose, J::kElbowLeft, J::kWristLeft);
  const double upper_right = ElevationDeg(pose, J::kShoulderRight, J::kElbowRight);
  const double fore_right = ElevationDeg(pose, J::kElbowRight, J::kWristRight);
  const double thigh_left = ElevationDeg(pose, J::kHipLeft, J::kKneeLeft);
  const double shin_left = ElevationDeg(pose, J::kKneeLeft, J::kAnkleLeft);
  const double thigh_right = ElevationDeg(pose, J::kHipRight, J::kKneeRight);
  const double shin_right = ElevationDeg(pose, J::kKneeRight, J::kAnkleRight);
  std::cout << "01_01 frame 0 elevation (deg): upper arms " << upper_left << " " << upper_right
            << ", forearms " << fore_left << " " << fore_right << ", thighs " << thigh_left << " "
            << thigh_right << ", shins " << shin_left << " " << shin_right << "\n";
  for (double arm : {upper_left, fore_left, upper_right, fore_right}) EXPECT_LT(std::abs(arm), 10);
  for (double leg : {thigh_left, shin_left, thigh_right, shin_right}) EXPECT_LT(leg, -80);
  // Arms point outward, opposite each other.
  const Eigen::Vector3d left = At(pose, J::kWristLeft) - At(pose, J::kShoulderLeft);
  const Eigen::Vector3d right = At(pose, J::kWristRight) - At(pose, J::kShoulderRight);
  const double between_deg =
      std::acos(std::clamp(left.normalized().dot(right.normalized()), -1.0, 1.0)) * kDegPerRad;
  std::cout << "01_01 frame 0: angle between arms " << between_deg << " deg\n";
  EXPECT_GT(between_deg, 170);
  const Eigen::Vector3d across = At(pose, J::kShoulderLeft) - At(pose, J::kShoulderRight);
  EXPECT_GT(left.dot(across), 0);
  EXPECT_LT(right.dot(across), 0);
}

// Left/right segment lengths agree and joints sit in anatomical order.
void ExpectAnatomical(const SkeletonPose& pose, const std::string& what) {
  const std::vector<std::pair<J, J>> left = {{J::kShoulderLeft, J::kElbowLeft},
                                             {J::kElbowLeft, J::kWristLeft},
                                             {J::kHipLeft, J::kKneeLeft},
                                             {J::kKneeLeft, J::kAnkleLeft}};
  const std::vector<std::pair<J, J>> right = {{J::kShoulderRight, J::kElbowRight},
                                              {J::kElbowRight, J::kWristRight},
                                              {J::kHipRight, J::kKneeRight},
                                              {J::kKneeRight, J::kAnkleRight}};
  for (size_t s = 0; s < left.size(); ++s) {
    const double l = Distance(pose, left[s].first, left[s].second);
    const double r = Distance(pose, right[s].first, right[s].second);
    EXPECT_NEAR(l, r, 3 * kCm) << what << " segment " << s;
    EXPECT_GT(l, 15 * kCm) << what << " segment " << s;
    EXPECT_LT(l, 60 * kCm) << what << " segment " << s;
  }
  // Knee between hip and ankle, head above the neck above the spine base.
  for (auto [hip, knee, ankle] : {std::tuple{J::kHipLeft, J::kKneeLeft, J::kAnkleLeft},
                                  std::tuple{J::kHipRight, J::kKneeRight, J::kAnkleRight}}) {
    EXPECT_LT(At(pose, knee).y(), At(pose, hip).y()) << what;
    EXPECT_GT(At(pose, knee).y(), At(pose, ankle).y()) << what;
  }
  EXPECT_GT(At(pose, J::kHead).y(), At(pose, J::kNeck).y()) << what;
  EXPECT_GT(At(pose, J::kNeck).y(), At(pose, J::kSpineShoulder).y()) << what;
  EXPECT_GT(At(pose, J::kSpineShoulder).y(), At(pose, J::kSpineMid).y()) << what;
  EXPECT_GT(At(pose, J::kSpineMid).y(), At(pose, J::kSpineBase).y()) << what;
  // The left hip and shoulder lie on the same side of the body.
  const Eigen::Vector3d hips = At(pose, J::kHipLeft) - At(pose, J::kHipRight);
  const Eigen::Vector3d shoulders = At(pose, J::kShoulderLeft) - At(pose, J::kShoulderRight);
  EXPECT_GT(hips.normalized().dot(shoulders.normalized()), 0.5) << what;
}

TEST(CanonicalPose, AsfAmcAndBvhAreAnatomical) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07-walk.asf"));
  auto walk = ReadAsfAmc(Cmu("07-walk.asf"), Cmu("07_05-walk.amc"));
  auto jumps = ReadBvh(Cmu("01_01.bvh"));
  auto walk_bvh = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = kCmuMetresPerUnit});
  ASSERT_TRUE(walk.ok()) << walk.status();
  ASSERT_TRUE(jumps.ok()) << jumps.status();
  ASSERT_TRUE(walk_bvh.ok()) << walk_bvh.status();
  for (int f : {0, 100, 300})
    ExpectAnatomical(walk->CanonicalPose(f), "07_05 frame " + std::to_string(f));
  ExpectAnatomical(jumps->CanonicalPose(0), "01_01 frame 0");
  for (int f : {0, 500})
    ExpectAnatomical(walk_bvh->CanonicalPose(f), "131_01 frame " + std::to_string(f));
}

TEST(CanonicalPose, AsfAndBvhOfOneSubjectHaveEqualSegments) {
  // Subject 131's ASF skeleton and its 3dsMax BVH conversion describe one
  // body: thigh, shin, upper arm and forearm lengths agree within 1 cm.
  REENACT_REQUIRE_TEST_FILE(Cmu("131-dance.asf"));
  auto asf = ReadAsfAmc(Cmu("131-dance.asf"), Cmu("131_04-dance.amc"));
  auto bvh = ReadBvh(Cmu("131_01.bvh"), {.metres_per_unit = kCmuMetresPerUnit});
  ASSERT_TRUE(asf.ok()) << asf.status();
  ASSERT_TRUE(bvh.ok()) << bvh.status();
  const SkeletonPose a = asf->CanonicalPose(0);
  const SkeletonPose b = bvh->CanonicalPose(0);
  for (auto [from, to] : {std::pair{J::kHipLeft, J::kKneeLeft},
                          {J::kKneeLeft, J::kAnkleLeft},
                          {J::kHipRight, J::kKneeRight},
                          {J::kKneeRight, J::kAnkleRight},
                          {J::kShoulderLeft, J::kElbowLeft},
                          {J::kElbowLeft, J::kWristLeft},
                          {J::kShoulderRight, J::kElbowRight},
                          {J::kElbowRight, J::kWristRight}}) {
    EXPECT_NEAR(Distance(a, from, to), Distance(b, from, to), 1 * kCm)
        << KinectV2JointName(from) << "-" << KinectV2JointName(to);
  }
}

// Expects `status` to be an error whose message names `path` and `line`.
void ExpectErrorAt(const absl::Status& status, const std::string& path, int line,
                   const std::string& words) {
  ASSERT_FALSE(status.ok());
  const std::string message(status.message());
  EXPECT_NE(message.find(path + ":" + std::to_string(line) + ":"), std::string::npos) << message;
  EXPECT_NE(message.find(words), std::string::npos) << message;
}

TEST(ReadBvh, MalformedFilesNameFileAndLine) {
  const std::string text = TinyBvh("Frames: 1\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0\n");
  // Missing closing brace of the root: the parser reaches MOTION first.
  std::string no_brace = text;
  no_brace.erase(no_brace.find("}\nMOTION"), 2);
  std::string path = WriteTemp("no_brace.bvh", no_brace);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(no_brace, "MOTION"), "missing '}'");

  std::string bad_offset = text;
  bad_offset.replace(bad_offset.find("OFFSET 0 1 0"), 12, "OFFSET 0 x1 0");
  path = WriteTemp("bad_offset.bvh", bad_offset);
  ExpectErrorAt(ReadBvh(path).status(), path, 8, "bad number 'x1'");

  const std::string nan = TinyBvh("Frames: 1\nFrame Time: 0.1\n0 0 0 0 nan 0 0 0 0\n");
  path = WriteTemp("nan.bvh", nan);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(nan, "nan"), "bad number 'nan'");

  // Finite, but posed joints would overflow to infinity.
  const std::string huge = TinyBvh("Frames: 1\nFrame Time: 0.1\n1e308 0 0 0 0 0 0 0 0\n");
  path = WriteTemp("huge.bvh", huge);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(huge, "1e308"), "out of range");
  std::string huge_offset = text;
  huge_offset.replace(huge_offset.find("OFFSET 0 1 0"), 12, "OFFSET 0 1e300 0");
  path = WriteTemp("huge_offset.bvh", huge_offset);
  ExpectErrorAt(ReadBvh(path).status(), path, 8, "out of range");

  const std::string short_line = TinyBvh("Frames: 2\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0\n0 0 0\n");
  path = WriteTemp("short_line.bvh", short_line);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(short_line, "0 0 0\n") + 1,
                "frame 1 has 3 values");

  // Three frames declared, one present: the error points at the last line.
  const std::string truncated = TinyBvh("Frames: 3\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0\n");
  path = WriteTemp("truncated.bvh", truncated);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(truncated, "0 0 0 0 0 0 0 0 0"),
                "truncated motion");

  const std::string missing = reenact::testing::MakeTempDir("motion_missing") + "/absent.bvh";
  const absl::Status status = ReadBvh(missing).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_NE(std::string(status.message()).find(missing), std::string::npos) << status;
}

TEST(ReadAsfAmc, MalformedFilesNameFileAndLine) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07-walk.asf"));
  const std::string asf = Cmu("07-walk.asf");
  const std::string header = ":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\n";
  std::string amc = WriteTemp("unknown.amc", header + "lknee 10\n");
  ExpectErrorAt(ReadAsfAmc(asf, amc).status(), amc, 5, "bone 'lknee' is not in the skeleton");

  amc = WriteTemp("count.amc", header + "ltibia 10 20\n");
  ExpectErrorAt(ReadAsfAmc(asf, amc).status(), amc, 5, "has 2 values");

  amc = WriteTemp("inf.amc", header + "ltibia inf\n");
  ExpectErrorAt(ReadAsfAmc(asf, amc).status(), amc, 5, "bad number 'inf'");

  // A frame cut short: the last frame lacks most bones.
  amc = WriteTemp("truncated.amc", header + "lowerback 1 2 3\n");
  ExpectErrorAt(ReadAsfAmc(asf, amc).status(), amc, 3, "truncated");

  std::ifstream in(asf);
  std::string asf_text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  asf_text.replace(asf_text.find("length 6.92462"), 14, "length 6.9x");
  const std::string bad_asf = WriteTemp("bad.asf", asf_text);
  ExpectErrorAt(ReadAsfAmc(bad_asf, Cmu("07_05-walk.amc")).status(), bad_asf, 29, "bad number");
}

TEST(ReadAsfAmc, FrameNumbersNearIntMaxDoNotWrap) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07_05-walk.amc"));
  // The walk's first frame, numbered INT_MAX, then a frame numbered INT_MIN:
  // in 32-bit arithmetic INT_MAX + 1 would wrap round to it.
  std::ifstream in(Cmu("07_05-walk.amc"));
  std::string line;
  std::string amc_text;
  int frame_numbers = 0;
  while (std::getline(in, line)) {
    const bool frame_number = !line.empty() && std::all_of(line.begin(), line.end(), [](char c) {
      return c == '\r' || std::isdigit(c);
    });
    if (frame_number && ++frame_numbers == 2) break;
    amc_text += (frame_number ? std::string("2147483647") : line) + "\n";
  }
  const std::string first_frame = amc_text.substr(amc_text.find("2147483647\n") + 11);
  amc_text += "-2147483648\n" + first_frame;
  const std::string amc = WriteTemp("int_max.amc", amc_text);
  ExpectErrorAt(ReadAsfAmc(Cmu("07-walk.asf"), amc).status(), amc, LineOf(amc_text, "-2147483648"),
                "frame number -2147483648 out of sequence");
}

TEST(ReadAsfAmc, DeeplyNestedBonesAreAnError) {
  // 300 bones, each the child of the one before: refused (the skeleton walk
  // is recursive), not a stack overflow.
  std::string asf =
      ":units\n  length 0.45\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n"
      "  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n";
  std::string hierarchy = ":hierarchy\n  begin\n    root b0\n";
  for (int b = 0; b < 300; ++b) {
    asf += "  begin\n    name b" + std::to_string(b) +
           "\n    direction 0 1 0\n    length 1\n    axis 0 0 0 XYZ\n  end\n";
    if (b > 0) hierarchy += "    b" + std::to_string(b - 1) + " b" + std::to_string(b) + "\n";
  }
  const std::string dir = reenact::testing::MakeTempDir("motion_deep");
  std::ofstream(dir + "/deep.asf") << asf << hierarchy << "  end\n";
  std::ofstream(dir + "/deep.amc") << "";
  const absl::Status status = ReadAsfAmc(dir + "/deep.asf", dir + "/deep.amc").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_NE(std::string(status.message()).find("nested more than 256 bones deep"),
            std::string::npos)
      << status;
}

TEST(ReadBvh, FrameCountBeyondTheJointPoseBudgetIsRefusedBeforeAllocating) {
  // "Frames: 2147483647" over 11 joints: 23.6 G joint poses, about 1 TB once
  // parsed. Refused at the Frames line, not a bad_alloc.
  const std::string text = TinyBvh("Frames: 2147483647\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0\n");
  const std::string path = WriteTemp("huge_frames.bvh", text);
  ExpectErrorAt(ReadBvh(path).status(), path, LineOf(text, "Frames:"), "joint poses");
}

TEST(ReadAsfAmc, FramesBeyondTheJointPoseBudgetAreRefused) {
  // 1000 bones without degrees of freedom cost no AMC text but a rotation
  // each per frame: 17,000 two-line frames (about 300 KB) would be 17 M joint
  // poses, past kMaxMotionJointFrames.
  std::string asf =
      ":units\n  length 0.45\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n"
      "  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n";
  std::string children;
  for (int b = 0; b < 1000; ++b) {
    asf += "  begin\n    name b" + std::to_string(b) +
           "\n    direction 0 1 0\n    length 1\n    axis 0 0 0 XYZ\n  end\n";
    children += " b" + std::to_string(b);
  }
  asf += ":hierarchy\n  begin\n    root" + children + "\n  end\n";
  std::string amc = ":FULLY-SPECIFIED\n:DEGREES\n";
  for (int f = 1; f <= 17000; ++f) amc += std::to_string(f) + "\nroot 0 0 0 0 0 0\n";
  const std::string dir = reenact::testing::MakeTempDir("motion_many_bones");
  const std::string asf_path = dir + "/many_bones.asf";
  const std::string amc_path = dir + "/many_frames.amc";
  std::ofstream(asf_path) << asf;
  std::ofstream(amc_path) << amc;
  // The core joints named by a map, so that the skeleton is accepted and
  // the motion is read.
  AsfAmcOptions options;
  const KinectV2Joint core[] = {
      KinectV2Joint::kSpineMid,  KinectV2Joint::kShoulderLeft, KinectV2Joint::kShoulderRight,
      KinectV2Joint::kElbowLeft, KinectV2Joint::kElbowRight,   KinectV2Joint::kHipLeft,
      KinectV2Joint::kHipRight,  KinectV2Joint::kKneeLeft,     KinectV2Joint::kKneeRight};
  for (int b = 0; b < 9; ++b) options.joint_map.push_back({"b" + std::to_string(b), core[b]});
  // Joints: the root, 1000 bones and an end joint for each.
  const uint64_t frames_allowed = kMaxMotionJointFrames / 2001;
  ExpectErrorAt(ReadAsfAmc(asf_path, amc_path, options).status(), amc_path,
                LineOf(amc, "\n" + std::to_string(frames_allowed + 1) + "\n") + 1, "joint poses");
}

TEST(ReadMotion, DispatchesOnExtension) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07_05-walk.amc"));
  auto amc = ReadMotion(Cmu("07_05-walk.amc"), Cmu("07-walk.asf"));
  ASSERT_TRUE(amc.ok()) << amc.status();
  EXPECT_EQ(amc->info().format, "asf/amc");
  EXPECT_FALSE(ReadMotion(Cmu("07_05-walk.amc")).ok());
  EXPECT_FALSE(ReadMotion(Cmu("cmu-mocap-index.csv")).ok());
}

}  // namespace
}  // namespace reenact::body
