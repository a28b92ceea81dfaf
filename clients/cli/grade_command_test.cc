// `reenact grade`: a perfect learner tracked from depth at several facings,
// the report files, the real-people figures on shared/data/rgbd-seq, and bad
// input.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "clients/cli/real_sequences.h"
#include "clients/mirror/repetitions.h"
#include "clients/view/truth_reenactment.h"
#include "common/body/procedural_body.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;

// Measured on this data (see the test that prints it), less a margin.
constexpr double kSdkRankingFloorPercent = 87.0;  // Measured 91.1 %.

struct Result {
  int code = 0;
  std::string out, err;
};

Result Grade(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  Result r;
  r.code = RunGrade(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

const std::string& Dir() {
  static const std::string dir = testing::MakeTempDir("grade_command");
  return dir;
}

// A 2 s take of the built-in front kick seen by one sensor with no skeleton
// stream (a depth camera: `reenact grade` tracks it as reenactd would), the
// person turned `yaw_deg` from the sensor; "" after a failure.
// The built-in front kick, 2 s, one small sensor.
synth::SynthOptions KickOptions(uint64_t seed) {
  synth::SynthOptions options;
  options.motion = "builtin:front-kick";
  options.num_sensors = 1;
  options.seconds = 2.0;
  options.color_width = 320;
  options.color_height = 180;
  options.seed = seed;
  return options;
}

std::string KickTake(double yaw_deg, uint64_t seed) {
  static std::map<std::pair<double, uint64_t>, std::string> made;
  if (auto it = made.find({yaw_deg, seed}); it != made.end()) return it->second;
  synth::SynthOptions options = KickOptions(seed);
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kNone;
  options.yaw_deg = yaw_deg;
  options.ground_truth_mesh = false;
  const std::string path = absl::StrCat(Dir(), "/kick_yaw", yaw_deg, "_seed", seed, ".mcap");
  const auto summary = synth::SynthesizeTake(options, path);
  if (!summary.ok()) {
    ADD_FAILURE() << summary.status();
    return "";
  }
  return made[{yaw_deg, seed}] = path;
}

// The teacher and a learner doing exactly the same kick, compared through
// the same pipeline (both tracked from depth by the capture daemon's
// tracker). The goal is <= 5 degrees at every facing with >= 80 % of the
// part-frames graded up to 60 degrees; the tracker on these synthetic bodies
// reaches it facing the sensor only (measured: 1.7 deg over 77 %), and
// turned it reads 7.5-9.6 deg over 11-45 % (its joints on a turned body are
// tens of millimetres off and mostly inferred). The bounds hold what is
// measured, so that a regression shows.
TEST(Grade, APerfectLearnerGradesNearZeroFacingTheSensor) {
  const std::string teacher = KickTake(0.0, 1);
  ASSERT_FALSE(teacher.empty());
  for (const double yaw : {0.0, 30.0, 60.0, 90.0}) {
    const std::string learner = KickTake(yaw, 2);
    ASSERT_FALSE(learner.empty());
    const Result r = Grade({"--teacher", teacher, "--learner", learner, "--json"});
    ASSERT_EQ(r.code, kExitOk) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j["mean_error_deg"].is_number()) << r.out;
    const double mean = j["mean_error_deg"], coverage = j["coverage"];
    std::printf(
        "perfect learner at yaw %2.0f: mean %.2f deg over %.0f %% of part-frames, %zu "
        "parts not graded, %zu corrections\n",
        yaw, mean, 100.0 * coverage, j["not_graded"].size(), j["corrections"].size());
    for (const auto& c : j["corrections"]) {
      std::printf("    %s\n", c["text"].get<std::string>().c_str());
    }
    if (yaw == 0.0) {
      EXPECT_LE(mean, 3.0);
      EXPECT_GE(coverage, 0.7);
      EXPECT_TRUE(j["corrections"].empty());
    } else {
      EXPECT_LE(mean, 12.0) << "yaw " << yaw;
      EXPECT_GE(coverage, 0.05) << "yaw " << yaw;
    }
    for (const auto& part : j["not_graded"]) {
      EXPECT_FALSE(part["reason"].get<std::string>().empty());
    }
  }
}

TEST(Grade, WritesTheReportAndPrintsCorrectionsInWords) {
  const std::string teacher = KickTake(0.0, 1);
  const std::string learner = KickTake(30.0, 2);
  ASSERT_FALSE(teacher.empty());
  ASSERT_FALSE(learner.empty());
  const std::string report = Dir() + "/report";
  const Result r = Grade({"--teacher", teacher, "--learner", learner, "--report", report});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  EXPECT_NE(r.out.find("mean error"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("left lower leg"), std::string::npos) << r.out;
  for (const char* name : {"grade.json", "heatmap.png", "worst-moments.png"}) {
    EXPECT_GT(fs::file_size(fs::path(report) / name), 1000u) << name;
  }
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(fs::path(report) / "grade.json"));
  EXPECT_EQ(j["pair_errors"].size(), j["pairs"].get<size_t>());
  EXPECT_LE(j["corrections"].size(), 3u);
  // One kick, one repetition.
  EXPECT_EQ(j["repetitions"]["count"], 1) << j["repetitions"].dump();
  EXPECT_NE(r.out.find("repetitions: 1 of the teacher's action"), std::string::npos) << r.out;
}

// The kick as a body reenactment file: the body model of a synthetic take's
// ground truth (its stored joints are the model's), the frames in
// `missing` stored without a skeleton; "" after a failure.
std::string KickReenactment(const std::string& name, int first_missing = 0, int end_missing = 0) {
  const synth::SynthOptions options = KickOptions(5);
  const std::string take_path = absl::StrCat(Dir(), "/", name, ".mcap");
  if (const auto made = synth::SynthesizeTake(options, take_path); !made.ok()) {
    ADD_FAILURE() << made.status();
    return "";
  }
  auto take = TakeReader::Open(take_path);
  auto model = body::BuildProceduralBody();
  if (!take.ok() || !model.ok()) {
    ADD_FAILURE() << "the take or the body model did not load";
    return "";
  }
  absl::StatusOr<Reenactment> data = view::testing::MakeTruthBodyReenactment(**take, *model);
  if (!data.ok()) {
    ADD_FAILURE() << data.status();
    return "";
  }
  // A frame without joints is how a reenactment stores a missing skeleton.
  for (int k = first_missing; k < end_missing && k < static_cast<int>(data->frames.size()); ++k) {
    data->frames[k].joints_in_world_m.clear();
  }
  const std::string reen = absl::StrCat(Dir(), "/", name, ".reen");
  if (const absl::Status written = WriteReenactment(*data, reen); !written.ok()) {
    ADD_FAILURE() << written;
    return "";
  }
  return reen;
}

// The same kick with a body reenactment as the teacher and learners tracked
// from depth at four facings. The reenactment's stored joints are the body
// model's, which are not the points our tracker reports: compared as
// stored, a perfect learner facing the sensor reads 13.7 degrees. With
// --teacher-joints tracked the teacher's joints are our tracker's on the
// teacher drawn as depth from the learner's side. Measured: 2.2, 5.2, 3.7
// and 5.3 degrees at 0, 30, 60 and 90 degrees over 82, 52, 48 and 42 % of
// the part-frames; the goal (5 degrees, 80 % graded at 0-60 degrees) is
// not reached at 30 degrees nor in coverage: turned away from its one
// sensor, the far arm is hidden behind the body and is rightly not graded.
TEST(Grade, AReenactmentTeacherIsTrackedLikeTheLearnerForAPerfectRepetition) {
  const std::string teacher = KickReenactment("kick_teacher");
  ASSERT_FALSE(teacher.empty());
  for (const double yaw : {0.0, 30.0, 60.0, 90.0}) {
    const std::string learner = KickTake(yaw, 2);
    ASSERT_FALSE(learner.empty());
    const Result r = Grade(
        {"--teacher", teacher, "--learner", learner, "--teacher-joints", "tracked", "--json"});
    ASSERT_EQ(r.code, kExitOk) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j["mean_error_deg"].is_number()) << r.out;
    const double mean = j["mean_error_deg"], coverage = j["coverage"];
    std::printf("reenactment teacher, perfect learner at yaw %2.0f: %.2f deg over %.0f %%\n", yaw,
                mean, 100.0 * coverage);
    EXPECT_NE(j["teacher"].get<std::string>().find("as the tracker finds them"), std::string::npos);
    EXPECT_LE(mean, 7.0) << "yaw " << yaw;
    EXPECT_GE(coverage, yaw < 80.0 ? 0.42 : 0.3) << "yaw " << yaw;
    if (yaw == 0.0) {
      EXPECT_LE(mean, 3.5);
      // The stored joints, for contrast.
      const Result stored = Grade({"--teacher", teacher, "--learner", learner, "--json"});
      ASSERT_EQ(stored.code, kExitOk) << stored.err;
      const double stored_mean = nlohmann::json::parse(stored.out)["mean_error_deg"];
      std::printf("  the same with the stored joints: %.2f deg\n", stored_mean);
      EXPECT_GT(stored_mean, mean + 5.0);
    }
  }
  EXPECT_EQ(
      Grade({"--teacher", teacher, "--learner", KickTake(0.0, 2), "--teacher-joints", "x"}).code,
      kExitUsage);
}

// The teacher as a reenactment file with five frames whose skeleton is
// missing, the learner a take of the same kick with the sensor's (jittered
// true) skeleton: graded near zero, one repetition, and nothing graded
// against the missing frames.
TEST(Grade, AReenactmentTeacherWithMissingFramesGradesTheRest) {
  const std::string reen = KickReenactment("teacher_missing", 20, 25);
  ASSERT_FALSE(reen.empty());
  synth::SynthOptions options = KickOptions(6);
  options.ground_truth_mesh = false;
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.skeleton_jitter_m = 0.005;
  const std::string learner = Dir() + "/reen_learner.mcap";
  ASSERT_TRUE(synth::SynthesizeTake(options, learner).ok());

  const Result r = Grade({"--teacher", reen, "--learner", learner, "--json", "--pairs"});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::printf("reenactment teacher with 5 missing frames: %.2f deg over %.0f %%, %d repetition\n",
              j["mean_error_deg"].get<double>(), 100.0 * j["coverage"].get<double>(),
              j["repetitions"]["count"].get<int>());
  EXPECT_LT(j["mean_error_deg"].get<double>(), 5.0);
  EXPECT_EQ(j["repetitions"]["count"], 1);
  EXPECT_NE(j["teacher"].get<std::string>().find("reenactment"), std::string::npos);
  // Every pair with a missing teacher frame is ungraded for that reason.
  int against_missing = 0;
  for (const nlohmann::json& pair : j["pair_errors"]) {
    const int t = pair["teacher_frame"];
    if (t < 20 || t >= 25) continue;
    ++against_missing;
    EXPECT_TRUE(pair["mean_error_deg"].is_null()) << pair.dump();
  }
  EXPECT_GT(against_missing, 0);
}

// Depth-only recordings of real people (imported from rgbd-seq folders, no
// colour, no skeleton) are tracked and graded like any take: subject 3's
// wave against subject 1's is one repetition and grades well below subject
// 3's clap against the same wave, which is no repetition.
TEST(Grade, DepthOnlyImportsOfRealPeopleAreTrackedAndGraded) {
  const std::string dir = testing::TestDataPath("rgbd-seq");
  REENACT_REQUIRE_TEST_FILE(dir + "/index.csv");
  auto import = [&](const std::string& name) {
    const std::string out_path = Dir() + "/" + name + ".mcap";
    std::ostringstream out, err;
    EXPECT_EQ(RunImport({dir + "/" + name, "--out", out_path}, out, err), kExitOk) << err.str();
    return out_path;
  };
  const std::string teacher = import("utd-kinect2-a01-s1-t1");
  const std::string wave = import("utd-kinect2-a01-s3-t1");
  const std::string clap = import("utd-kinect2-a10-s3-t1");
  const Result same = Grade({"--teacher", teacher, "--learner", wave, "--json"});
  const Result other = Grade({"--teacher", teacher, "--learner", clap, "--json"});
  ASSERT_EQ(same.code, kExitOk) << same.err;
  ASSERT_EQ(other.code, kExitOk) << other.err;
  const nlohmann::json s = nlohmann::json::parse(same.out);
  const nlohmann::json o = nlohmann::json::parse(other.out);
  const double same_deg = s["action_error_deg"], other_deg = o["action_error_deg"];
  std::printf(
      "depth-only real takes, tracked: wave vs wave %.1f deg over %.0f %% (%d repetition), "
      "clap vs wave %.1f deg (%d repetitions)\n",
      same_deg, 100.0 * s["coverage"].get<double>(), s["repetitions"]["count"].get<int>(),
      other_deg, o["repetitions"]["count"].get<int>());
  EXPECT_EQ(s["repetitions"]["count"], 1);
  EXPECT_EQ(o["repetitions"]["count"], 0);
  EXPECT_TRUE(o["repetitions"]["whole_take"].get<bool>());
  EXPECT_LT(same_deg + 10.0, other_deg);
  EXPECT_GT(s["coverage"].get<double>(), 0.6);
}

// The real-people figures: every pair of two different people of the
// Kinect v2 set, graded from the stored Kinect SDK skeletons. A same-action
// pair must grade lower than a different-action pair for the same learner.
TEST(GradeReal, SameActionGradesLowerThanDifferentActionOnSdkSkeletons) {
  const std::string dir = testing::TestDataPath("rgbd-seq");
  REENACT_REQUIRE_TEST_FILE(dir + "/index.csv");
  const Result r = Grade({"--real", dir, "--sequences", "utd-kinect2", "--json"});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const nlohmann::json& sdk = j["overall"]["sdk"];
  const double share = sdk["same_action_lower_percent"];
  std::printf(
      "Kinect v2, SDK skeletons: %d pairs, same action lower in %.1f %% of %lld "
      "comparisons (%.1f %% by the plain mean; action-weighted %.1f deg same action, %.1f deg "
      "different)\n",
      sdk["pairs"].get<int>(), share, sdk["comparisons"].get<long long>(),
      sdk["same_action_lower_percent_plain_mean"].get<double>(),
      sdk["mean_same_action_deg"].get<double>(), sdk["mean_different_action_deg"].get<double>());
  EXPECT_EQ(sdk["pairs"].get<int>(), 30 * 20);
  EXPECT_EQ(sdk["pairs_not_graded"].get<int>(), 0);
  EXPECT_GE(share, kSdkRankingFloorPercent);
  EXPECT_LT(sdk["mean_same_action_deg"].get<double>(),
            sdk["mean_different_action_deg"].get<double>());

  // Repetitions: each recording holds one. Measured: counted once in 85.0 %
  // of the same-action pairs, none in 63.5 % of the different-action ones
  // (all of this set's actions are gestures of the right hand).
  const nlohmann::json& reps = j["overall"]["repetitions_sdk"];
  std::printf("Kinect v2, SDK skeletons: %s\n", reps.dump().c_str());
  EXPECT_GE(reps["same_action_counted_once_percent"].get<double>(), 80.0);
  EXPECT_GE(reps["different_action_counted_none_percent"].get<double>(), 55.0);
}

// Our tracker's grades against the SDK's on the same pairs, the learners
// being the Kinect v2 subject the tracker's network never trained on
// (models/tracker/README.md). Goal: per-part correlation >= 0.8 and mean
// absolute difference <= 8 degrees.
TEST(GradeReal, TrackedGradesAgreeWithTheSdksOnAHeldOutSubject) {
  const std::string dir = testing::TestDataPath("rgbd-seq");
  REENACT_REQUIRE_TEST_FILE(dir + "/index.csv");
  const Result r = Grade({"--real", dir, "--sequences", "utd-kinect2", "--learners",
                          "utd-kinect2-*-s3-*", "--tracked", "--json"});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const nlohmann::json& agree = j["overall"]["tracked_vs_sdk"];
  const nlohmann::json& tracked = j["overall"]["tracked"];
  const double correlation = agree["correlation"], mad = agree["mean_abs_difference_deg"];
  std::printf(
      "Kinect v2 held-out learners, tracked vs SDK: %d pairs, %d part grades, correlation "
      "%.3f, mean absolute difference %.1f deg, tracked coverage %.0f %%; same action "
      "lower %.1f %% (tracked), %.1f %% (SDK)\n",
      agree["pairs"].get<int>(), agree["part_values"].get<int>(), correlation, mad,
      100.0 * agree["mean_tracked_coverage"].get<double>(),
      tracked["same_action_lower_percent"].get<double>(),
      j["overall"]["sdk"]["same_action_lower_percent"].get<double>());
  EXPECT_EQ(agree["pairs"].get<int>(), 10 * 20);
  EXPECT_GE(correlation, 0.8);
  EXPECT_LE(mad, 8.0);
  EXPECT_GE(agree["mean_tracked_coverage"].get<double>(), 0.6);
  EXPECT_GE(tracked["same_action_lower_percent"].get<double>(), 88.0);  // Measured 93.3 %.
}

// Repetitions counted in real people's recordings: a learner's take made of
// three real recordings in a row (a wave by subject 1, a clap by the same, a
// wave by subject 3), graded against subject 2's wave from the stored Kinect
// SDK skeletons. Exactly the two waves are repetitions, each found where it
// was put. (Subject 2 waves twice as long as the others; the other way
// round, subject 2's wave as a learner's is 24 degrees from subject 1's and
// is not counted at the default 18: the statistics over every pair are in
// SameActionGradesLowerThanDifferentActionOnSdkSkeletons.)
TEST(GradeReal, CountsTheRepetitionsInARealTakeAndLeavesTheOtherActionOut) {
  const std::string dir = testing::TestDataPath("rgbd-seq");
  REENACT_REQUIRE_TEST_FILE(dir + "/index.csv");
  auto frames = [&](const std::string& name) {
    const absl::StatusOr<RefSequence> seq = ReadRefSequence(fs::path(dir) / name);
    EXPECT_TRUE(seq.ok()) << seq.status();
    return seq.ok() ? SdkGradeFrames(*seq) : std::vector<mirror::GradeFrame>{};
  };
  const std::vector<mirror::GradeFrame> teacher = frames("utd-kinect2-a01-s2-t1");
  std::vector<mirror::GradeFrame> learner;
  std::vector<std::pair<double, double>> placed;  // Each recording's span.
  for (const char* name :
       {"utd-kinect2-a01-s1-t1", "utd-kinect2-a10-s1-t1", "utd-kinect2-a01-s3-t1"}) {
    const double start = static_cast<double>(learner.size()) / 30.0;
    for (mirror::GradeFrame f : frames(name)) {
      f.time_s = static_cast<double>(learner.size()) / 30.0;
      learner.push_back(std::move(f));
    }
    placed.emplace_back(start, static_cast<double>(learner.size() - 1) / 30.0);
  }
  ASSERT_FALSE(teacher.empty());
  const absl::StatusOr<mirror::TakeGrade> take = mirror::GradeTake(teacher, learner);
  ASSERT_TRUE(take.ok()) << take.status();
  for (const mirror::Repetition& r : take->repetitions) {
    std::printf("repetition %.2f .. %.2f s, %.1f deg from the teacher's wave\n", r.start_s, r.end_s,
                r.distance_deg);
  }
  ASSERT_EQ(take->repetitions.size(), 2u);
  // Each inside its own recording (a person waving rests first and last, so
  // a repetition may start later and end sooner than the recording).
  for (int k = 0; k < 2; ++k) {
    const auto& [start, end] = placed[k == 0 ? 0 : 2];
    EXPECT_GE(take->repetitions[k].start_s, start - 0.05);
    EXPECT_LE(take->repetitions[k].end_s, end + 0.05);
    // And most of it: at least half of the recording.
    EXPECT_GE(take->repetitions[k].end_s - take->repetitions[k].start_s, 0.5 * (end - start));
  }
  EXPECT_FALSE(take->whole_take);
}

TEST(GradeReal, BadFoldersAndFlags) {
  EXPECT_EQ(Grade({"--real", Dir() + "/none"}).code, kExitFailure);
  EXPECT_EQ(Grade({"--real", Dir(), "--teacher", "x"}).code, kExitUsage);
  EXPECT_EQ(Grade({"--teacher", "x.mcap"}).code, kExitUsage);
  EXPECT_EQ(
      Grade({"--teacher", Dir() + "/missing.mcap", "--learner", Dir() + "/missing.mcap"}).code,
      kExitFailure);
  const std::string dir = testing::TestDataPath("rgbd-seq");
  REENACT_REQUIRE_TEST_FILE(dir + "/index.csv");
  // One recording: no pair of two people.
  const Result one = Grade({"--real", dir, "--sequences", "utd-kinect2-a01-s1-t1"});
  EXPECT_EQ(one.code, kExitFailure);
  EXPECT_NE(one.err.find("no pair"), std::string::npos) << one.err;
}

}  // namespace
}  // namespace reenact::cli
