#include "clients/mirror/mirror_session.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/mirror/testing/mocap_learners.h"
#include "common/base/files.h"

namespace reenact::mirror {
namespace {

using body::SkeletonPose;

constexpr int64_t kFrameNs = 33'333'333;  // The learner's sensor at 30 fps.
constexpr double kTeacherFps = 30.0;

// CMU 131_01 at 30 fps, the first three seconds.
std::vector<SkeletonPose> Teacher() { return testing::LoadCmuTeacher(4, 90); }

// How the simulated learner behaves.
struct Learner {
  // Facing yaw relative to the sensor (turned about the vertical through
  // their SpineBase; positive = to their own left).
  double yaw_deg = 0.0;
  // Teacher frames the learner lags behind while playing.
  int lag_frames = 0;
  // Changes the learner's pose in a given repetition (1-based), if set.
  std::function<SkeletonPose(const SkeletonPose&, int repetition)> change = nullptr;
};

struct DriveLog {
  std::vector<MirrorFrame> frames;
  std::vector<MirrorState> states;  // Each state as it is entered.
};

// Drives `session` with a learner who copies the teacher: the start pose
// while the facing is read, then the teacher frame on screen (minus the
// lag). The sensor stands in front of the teacher's start pose.
DriveLog Drive(MirrorSession& session, const std::vector<SkeletonPose>& teacher,
               const Learner& learner, double max_s = 30.0) {
  const Eigen::Isometry3d sensor_from_world = testing::SensorInFrontOf(teacher[0]);
  DriveLog run;
  MirrorState state = session.state();
  int64_t play_start_ns = 0;
  int repetition = 1;
  for (int64_t stamp_ns = 0; stamp_ns < max_s * 1e9; stamp_ns += kFrameNs) {
    int shown = 0;
    if (state == MirrorState::kPlaying) {
      shown = static_cast<int>((stamp_ns - play_start_ns) * 1e-9 * kTeacherFps + 1e-6);
      shown = std::clamp(shown - learner.lag_frames, 0, static_cast<int>(teacher.size()) - 1);
    }
    SkeletonPose pose = testing::TurnAboutSpineBase(teacher[shown], learner.yaw_deg);
    if (learner.change) pose = learner.change(pose, repetition);
    absl::StatusOr<MirrorFrame> frame =
        session.Update(stamp_ns, TransformPose(sensor_from_world, pose));
    EXPECT_TRUE(frame.ok()) << frame.status();
    if (!frame.ok()) break;
    if (frame->state == MirrorState::kPlaying && state != MirrorState::kPlaying) {
      play_start_ns = stamp_ns;
    }
    if (run.states.empty() || frame->state != run.states.back()) {
      run.states.push_back(frame->state);
    }
    state = frame->state;
    repetition = frame->repetition;
    run.frames.push_back(*std::move(frame));
    if (state == MirrorState::kFinished) break;
  }
  return run;
}

MirrorSession MakeSession(const std::vector<SkeletonPose>& teacher,
                          const MirrorSessionOptions& options) {
  absl::StatusOr<MirrorSession> session = MirrorSession::Create(teacher, kTeacherFps, options);
  EXPECT_TRUE(session.ok()) << session.status();
  return *std::move(session);
}

const MirrorFrame* FirstPlayingFrame(const DriveLog& run) {
  for (const MirrorFrame& frame : run.frames) {
    if (frame.state == MirrorState::kPlaying) return &frame;
  }
  return nullptr;
}

TEST(MirrorSession, TwoRepetitionsGoThroughFacingPlayingAndReportsAndWriteFiles) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_EQ(teacher.size(), 90u);
  MirrorSessionOptions options;
  options.repetitions = 2;
  options.report_dir = reenact::testing::MakeTempDir("mirror_session") + "/reports";
  MirrorSession session = MakeSession(teacher, options);
  EXPECT_EQ(session.state(), MirrorState::kWaitingForLearner);
  const DriveLog run = Drive(session, teacher, Learner{});

  const std::vector<MirrorState> expected = {MirrorState::kReadingFacing, MirrorState::kPlaying,
                                             MirrorState::kReadingFacing, MirrorState::kPlaying,
                                             MirrorState::kFinished};
  EXPECT_EQ(run.states, expected);
  ASSERT_EQ(session.reports().size(), 2u);
  int reports_seen = 0;
  for (const MirrorFrame& frame : run.frames) {
    if (!frame.finished_report) continue;
    ++reports_seen;
    EXPECT_TRUE(frame.report_status.ok()) << frame.report_status;
    EXPECT_TRUE(frame.report_files);
  }
  EXPECT_EQ(reports_seen, 2);
  for (int r = 1; r <= 2; ++r) {
    const std::string stem = options.report_dir + "/" + RepetitionFileStem(r);
    for (const char* ext : {".csv", ".json", ".png"}) {
      EXPECT_TRUE(std::filesystem::exists(stem + ext)) << stem << ext;
    }
    const nlohmann::json json = nlohmann::json::parse(*ReadFileToString(stem + ".json"));
    for (const char* key : {"mean_error_deg", "parts", "learner_facing_yaw_deg", "view_yaw_deg",
                            "teacher_turn_yaw_deg", "dtw", "num_learner_frames",
                            "num_teacher_frames", "num_compared_frames"}) {
      EXPECT_TRUE(json.contains(key)) << key;
    }
    EXPECT_EQ(json["parts"].size(), static_cast<size_t>(kNumBodyParts));
    EXPECT_TRUE(json["parts"].contains("right_lower_arm"));
    EXPECT_EQ(json["num_teacher_frames"].get<int>(), 90);
    EXPECT_EQ(json["num_compared_frames"].get<int>(), 90);
    EXPECT_FALSE(json["dtw"].get<bool>());
    const double mean_deg = json["mean_error_deg"].get<double>();
    std::cout << "repetition " << r << ": mean error " << mean_deg << " deg over "
              << json["num_compared_frames"] << " frames, facing " << json["learner_facing_yaw_deg"]
              << " deg, turn " << json["teacher_turn_yaw_deg"] << " deg\n";
    EXPECT_LT(mean_deg, 1.0);
  }
  // The hold: playing starts 2 s after the learner appears.
  const MirrorFrame* playing = FirstPlayingFrame(run);
  ASSERT_NE(playing, nullptr);
  EXPECT_NEAR(playing->facing.held_s, 2.0, 0.05);
  EXPECT_EQ(playing->teacher_frame, 0);
}

TEST(MirrorSession, EachReportSaysWhatToCorrectWithTheHeatMapAndTheWorstMoments) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  MirrorSessionOptions options;
  options.repetitions = 2;
  options.report_dir = reenact::testing::MakeTempDir("mirror_session_grade") + "/reports";
  MirrorSession session = MakeSession(teacher, options);
  // The second repetition with the right forearm 40 degrees off.
  Learner learner;
  learner.change = [](const SkeletonPose& pose, int repetition) {
    return repetition == 2 ? testing::TurnRightForearm(pose, 40.0) : pose;
  };
  Drive(session, teacher, learner);
  ASSERT_EQ(session.reports().size(), 2u);
  const RepetitionReport& good = session.reports()[0];
  const RepetitionReport& off = session.reports()[1];
  ASSERT_TRUE(good.grade.has_value());
  ASSERT_TRUE(off.grade.has_value());
  EXPECT_TRUE(good.grade->corrections.empty());
  EXPECT_NEAR(good.grade->coverage, 1.0, 1e-9);
  ASSERT_FALSE(off.grade->corrections.empty());
  EXPECT_EQ(off.grade->corrections.front().part, BodyPart::kRightLowerArm);
  EXPECT_NEAR(off.grade->corrections.front().error_deg, 40.0, 4.0);
  EXPECT_NE(off.grade->corrections.front().text.find("right"), std::string::npos)
      << off.grade->corrections.front().text;
  std::cout << "repetition 2: " << off.grade->corrections.front().text << "\n";
  const std::string stem = options.report_dir + "/" + RepetitionFileStem(2);
  for (const char* file : {"-heatmap.png", "-worst.png"}) {
    EXPECT_GT(std::filesystem::file_size(stem + file), 1000u) << file;
  }
  const nlohmann::json json = nlohmann::json::parse(*ReadFileToString(stem + ".json"));
  ASSERT_TRUE(json.contains("grade"));
  EXPECT_EQ(json["grade"]["corrections"][0]["part"], "right_lower_arm");
  EXPECT_EQ(json["files"]["heatmap"], "rep-002-heatmap.png");
}

TEST(MirrorSession, LearnerFacingNinetyDegreesTurnsTheTeacherNinetyDegrees) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  for (double camera_offset_deg : {0.0, 60.0}) {
    MirrorSessionOptions options;
    options.repetitions = 1;
    if (camera_offset_deg != 0.0) {
      absl::StatusOr<TeacherFacing> facing = MeasureTeacherFacing(teacher, kTeacherFps, 0.5);
      ASSERT_TRUE(facing.ok());
      options.world_from_virtual_camera = *PlaceVirtualCamera(
          facing->pivot_in_world, facing->facing_yaw_world_deg + camera_offset_deg, 3.0, 1.6);
    }
    MirrorSession session = MakeSession(teacher, options);
    const DriveLog run = Drive(session, teacher, Learner{.yaw_deg = 90.0});
    const MirrorFrame* playing = FirstPlayingFrame(run);
    ASSERT_NE(playing, nullptr);
    ASSERT_TRUE(playing->learner_facing_yaw_deg);
    // The teacher's start facing is the circular mean over its first
    // teacher_facing_window_s (0.5 s = 15 frames); read the turned teacher's
    // facing relative to the virtual camera the same way.
    std::vector<double> relative_deg_per_frame;
    for (int f = 0; f < 15; ++f) {
      relative_deg_per_frame.push_back(testing::FacingRelativeToCamera(
          TransformPose(playing->teacher_turn.turned_from_original, teacher[f]),
          session.world_from_virtual_camera()));
    }
    const double relative_deg = CircularMeanDeg(relative_deg_per_frame).value_or(1e9);
    std::cout << "learner turned 90 deg, camera bearing +" << camera_offset_deg << ": facing read "
              << *playing->learner_facing_yaw_deg << " deg, teacher turn "
              << playing->teacher_turn.turn_yaw_deg
              << " deg, teacher facing relative to the virtual camera " << relative_deg
              << " deg over its first 0.5 s (frame 0: " << relative_deg_per_frame[0] << " deg)\n";
    RecordProperty("teacher_relative_facing_deg", std::to_string(relative_deg));
    EXPECT_NEAR(*playing->learner_facing_yaw_deg, 90.0, 5.0);
    EXPECT_NEAR(relative_deg, 90.0, 5.0);
    if (camera_offset_deg == 0.0) {
      EXPECT_NEAR(playing->teacher_turn.turn_yaw_deg, 90.0, 5.0);
    }
    ASSERT_EQ(session.reports().size(), 1u);
    EXPECT_LT(*session.reports()[0].mean_error_deg, 1.0);  // Spine-normalised.
  }
}

TEST(MirrorSession, DtwForgivesALaggingLearner) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  double mean_deg[2] = {0.0, 0.0};
  for (bool use_dtw : {false, true}) {
    MirrorSessionOptions options;
    options.repetitions = 1;
    options.use_dtw = use_dtw;
    options.report_dir = reenact::testing::MakeTempDir(use_dtw ? "mirror_lag_dtw" : "mirror_lag");
    MirrorSession session = MakeSession(teacher, options);
    Drive(session, teacher, Learner{.lag_frames = 6});
    ASSERT_EQ(session.reports().size(), 1u);
    EXPECT_EQ(session.reports()[0].used_dtw, use_dtw);
    const nlohmann::json json =
        nlohmann::json::parse(*ReadFileToString(options.report_dir + "/rep-001.json"));
    EXPECT_EQ(json["dtw"].get<bool>(), use_dtw);
    mean_deg[use_dtw] = *session.reports()[0].mean_error_deg;
  }
  std::cout << "learner 0.2 s behind: one to one " << mean_deg[0] << " deg, DTW " << mean_deg[1]
            << " deg\n";
  EXPECT_LT(mean_deg[1], mean_deg[0]);
}

TEST(MirrorSession, RepetitionCutShortGetsAnIncompleteReportOverThePlayedFrames) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_EQ(teacher.size(), 90u);
  for (bool use_dtw : {false, true}) {
    MirrorSessionOptions options;
    options.repetitions = 1;
    options.use_dtw = use_dtw;
    options.report_dir =
        reenact::testing::MakeTempDir(use_dtw ? "mirror_short_dtw" : "mirror_short");
    MirrorSession session = MakeSession(teacher, options);
    // Nothing plays yet: nothing to end.
    EXPECT_FALSE(session.EndEarly(0).has_value());
    // The 2 s hold, then 1.5 s of the 3 s action: the learner stops at 3.5 s.
    const DriveLog run = Drive(session, teacher, Learner{}, /*max_s=*/3.5);
    ASSERT_EQ(session.state(), MirrorState::kPlaying);
    const int64_t last_ns = (static_cast<int64_t>(run.frames.size()) - 1) * kFrameNs;
    const std::optional<MirrorFrame> ended = session.EndEarly(last_ns);
    ASSERT_TRUE(ended.has_value());
    EXPECT_EQ(ended->state, MirrorState::kFinished);
    ASSERT_TRUE(ended->finished_report.has_value());
    EXPECT_TRUE(ended->report_status.ok()) << ended->report_status;
    const RepetitionReport& report = *ended->finished_report;
    EXPECT_FALSE(report.complete);
    EXPECT_EQ(report.used_dtw, use_dtw);
    EXPECT_NEAR(report.teacher_frames_played, 45, 2);
    EXPECT_EQ(report.num_teacher_frames, 90);
    ASSERT_TRUE(report.mean_error_deg.has_value());
    std::cout << (use_dtw ? "DTW" : "one to one") << ": cut short after "
              << report.teacher_frames_played << " of 90 teacher frames, " << report.frames.size()
              << " pairs, mean error " << *report.mean_error_deg << " deg\n";
    // The learner copies the teacher: aligned with the played part only, the
    // error stays near zero (DTW against all 90 frames would pull the last
    // learner frame to teacher frame 89).
    EXPECT_LT(*report.mean_error_deg, 1.0);  // deg
    int max_teacher_frame = 0;
    for (const ComparedFrame& frame : report.frames) {
      max_teacher_frame = std::max(max_teacher_frame, frame.teacher_frame);
    }
    EXPECT_LT(max_teacher_frame, report.teacher_frames_played);
    const nlohmann::json json =
        nlohmann::json::parse(*ReadFileToString(options.report_dir + "/rep-001.json"));
    EXPECT_FALSE(json["complete"].get<bool>());
    EXPECT_EQ(json["teacher_frames_played"].get<int>(), report.teacher_frames_played);
    // Ended: nothing more to end.
    EXPECT_FALSE(session.EndEarly(last_ns + kFrameNs).has_value());
  }
}

TEST(MirrorSession, ChallengeCycleShowsTheListedViews) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  MirrorSessionOptions options;
  options.repetitions = 3;
  options.challenge = ChallengeMode::kCycle;
  options.challenge_view_yaws_deg = {0.0, 90.0};
  MirrorSession session = MakeSession(teacher, options);
  Drive(session, teacher, Learner{.yaw_deg = 30.0});
  ASSERT_EQ(session.reports().size(), 3u);
  const double views[3] = {0.0, 90.0, 0.0};
  for (int r = 0; r < 3; ++r) {
    const RepetitionReport& report = session.reports()[r];
    EXPECT_TRUE(report.challenge);
    EXPECT_NEAR(report.view_yaw_deg, views[r], 1e-9);
    EXPECT_NEAR(report.teacher_turn_yaw_deg, views[r], 1e-9);  // Camera in front.
    EXPECT_NEAR(*report.learner_facing_yaw_deg, 30.0, 5.0);
  }
}

TEST(MirrorSession, ChallengeHardestViewRepeatsTheWorstView) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  MirrorSessionOptions options;
  options.repetitions = 3;
  options.challenge = ChallengeMode::kHardestView;
  options.challenge_view_yaws_deg = {0.0, 90.0};
  MirrorSession session = MakeSession(teacher, options);
  Learner learner;
  learner.change = [](const SkeletonPose& pose, int repetition) {
    return repetition == 2 ? testing::TurnRightForearm(pose, 30.0) : pose;
  };
  Drive(session, teacher, learner);
  ASSERT_EQ(session.reports().size(), 3u);
  EXPECT_NEAR(session.reports()[0].view_yaw_deg, 0.0, 1e-9);
  EXPECT_NEAR(session.reports()[1].view_yaw_deg, 90.0, 1e-9);
  EXPECT_GT(*session.reports()[1].mean_error_deg, *session.reports()[0].mean_error_deg);
  EXPECT_NEAR(session.reports()[2].view_yaw_deg, 90.0, 1e-9);
}

TEST(MirrorSession, LostLearnerAndBadStampsAndOptions) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  MirrorSession session = MakeSession(teacher, {});
  const SkeletonPose learner = TransformPose(testing::SensorInFrontOf(teacher[0]), teacher[0]);
  EXPECT_EQ(session.Update(0, std::nullopt)->state, MirrorState::kWaitingForLearner);
  absl::StatusOr<MirrorFrame> reading = session.Update(kFrameNs, learner);
  ASSERT_TRUE(reading.ok());
  EXPECT_EQ(reading->state, MirrorState::kReadingFacing);
  EXPECT_EQ(reading->comparison.num_parts_compared, kNumBodyParts);  // Start-pose feedback.
  EXPECT_EQ(reading->joint_color[body::Index(body::KinectV2Joint::kElbowRight)],
            ErrorColorOptions().green_color);
  EXPECT_EQ(session.Update(2 * kFrameNs, std::nullopt)->state, MirrorState::kWaitingForLearner);
  SkeletonPose nan_learner = learner;
  for (auto& p : nan_learner.position_m) p.x() = std::nan("");
  absl::StatusOr<MirrorFrame> nan_frame = session.Update(3 * kFrameNs, nan_learner);
  ASSERT_TRUE(nan_frame.ok());
  EXPECT_EQ(nan_frame->state, MirrorState::kWaitingForLearner);
  EXPECT_EQ(nan_frame->comparison.num_parts_compared, 0);
  EXPECT_EQ(nan_frame->part_color[0], ErrorColorOptions().missing_color);
  EXPECT_FALSE(session.Update(kFrameNs, learner).ok());  // Earlier stamp.

  EXPECT_FALSE(MirrorSession::Create({}, 30.0, {}).ok());
  EXPECT_FALSE(MirrorSession::Create(teacher, 0.0, {}).ok());
  MirrorSessionOptions bad;
  bad.playback_speed = 0.0;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.challenge = ChallengeMode::kCycle;
  bad.challenge_view_yaws_deg.clear();
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.repetitions = -1;
  EXPECT_FALSE(bad.Validate().ok());
  bad = {};
  bad.up_in_sensor.setZero();
  EXPECT_FALSE(bad.Validate().ok());
}

// Bad input while a repetition plays: the learner out of view for half a
// second, two people in view for a while, and a teacher whose reenactment
// lacks ten frames. None is graded; the report counts each and says so.
TEST(MirrorSession, BadInputIsLeftUngradedAndSaidInTheReport) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_GE(teacher.size(), 60u);
  for (int f = 30; f < 40; ++f) teacher[f].valid.fill(false);
  MirrorSessionOptions options;
  options.repetitions = 1;
  options.facing.hold_s = 0.2;
  options.report_dir = reenact::testing::MakeTempDir("mirror_session_bad_input");
  MirrorSession session = MakeSession(teacher, options);
  const Eigen::Isometry3d sensor_from_world = testing::SensorInFrontOf(teacher[0]);
  std::optional<int64_t> play_start_ns;
  int missing = 0, crowded = 0;
  for (int64_t stamp_ns = 0; stamp_ns < 10e9 && session.state() != MirrorState::kFinished;
       stamp_ns += kFrameNs) {
    int shown = 0;
    double played_s = -1.0;
    if (play_start_ns) {
      played_s = (stamp_ns - *play_start_ns) * 1e-9;
      shown = std::min(static_cast<int>(played_s * kTeacherFps + 1e-6),
                       static_cast<int>(teacher.size()) - 1);
      if (!teacher[shown].valid[0]) shown = 29;  // The learner goes on from the last pose.
    }
    const bool gone = played_s >= 0.4 && played_s < 0.9;
    const int people = played_s >= 1.5 && played_s < 1.8 ? 2 : 1;
    if (play_start_ns && session.state() == MirrorState::kPlaying) {
      missing += gone;
      crowded += people > 1;
    }
    std::optional<SkeletonPose> pose;
    if (!gone) pose = TransformPose(sensor_from_world, teacher[shown]);
    absl::StatusOr<MirrorFrame> frame = session.Update(stamp_ns, pose, nullptr, people);
    ASSERT_TRUE(frame.ok()) << frame.status();
    if (frame->state == MirrorState::kPlaying && !play_start_ns) {
      play_start_ns = stamp_ns;
      // This first playing frame was already fed as not gone, one person.
    }
  }
  ASSERT_EQ(session.reports().size(), 1u);
  const RepetitionReport& report = session.reports()[0];
  EXPECT_EQ(report.frames_without_learner, missing);
  EXPECT_GE(report.frames_without_learner, 14);  // 0.5 s at 30 frames/s.
  EXPECT_EQ(report.frames_with_several_people, crowded);
  EXPECT_GE(report.frames_with_several_people, 8);
  EXPECT_EQ(report.teacher_frames_without_skeleton, 10);
  EXPECT_FALSE(session.TeacherFrameHasSkeleton(35));
  EXPECT_TRUE(session.TeacherFrameHasSkeleton(29));
  EXPECT_FALSE(session.TeacherFrameHasSkeleton(-1));
  const std::vector<std::string> problems = InputProblems(report);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_NE(problems[0].find("not seen in"), std::string::npos) << problems[0];
  EXPECT_NE(problems[1].find("more than one person"), std::string::npos) << problems[1];
  EXPECT_NE(problems[2].find("teacher has no skeleton in 10 of"), std::string::npos) << problems[2];
  // The graded pairs are the seen ones against teacher frames that have a
  // skeleton: an identical learner still grades near zero.
  ASSERT_TRUE(report.mean_error_deg.has_value());
  EXPECT_LT(*report.mean_error_deg, 1.0);
  const nlohmann::json json = nlohmann::json::parse(
      *ReadFileToString(options.report_dir + "/" + RepetitionFileStem(1) + ".json"));
  EXPECT_EQ(json["input_problems"].size(), 3u);
  EXPECT_EQ(json["frames_without_learner"], missing);
}

TEST(MirrorSession, UnwritableReportFolderIsReportedNotFatal) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = Teacher();
  ASSERT_FALSE(teacher.empty());
  const std::string dir = reenact::testing::MakeTempDir("mirror_session_bad");
  ASSERT_TRUE(WriteFileAtomically(dir + "/a_file", "x").ok());
  MirrorSessionOptions options;
  options.repetitions = 1;
  options.report_dir = dir + "/a_file/reports";
  MirrorSession session = MakeSession(teacher, options);
  const DriveLog run = Drive(session, teacher, Learner{});
  EXPECT_EQ(run.states.back(), MirrorState::kFinished);
  bool saw_error = false;
  for (const MirrorFrame& frame : run.frames) saw_error |= !frame.report_status.ok();
  EXPECT_TRUE(saw_error);
  EXPECT_EQ(session.reports().size(), 1u);
}

}  // namespace
}  // namespace reenact::mirror
