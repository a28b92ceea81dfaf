#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/commands.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

// The synthetic sensor skeleton is the truth plus Gaussian jitter per axis:
// sigma 10 mm for tracked joints, 30 mm for inferred ones. The mean length
// of such an error is sigma * sqrt(8 / pi): 15.96 mm tracked, 47.9 mm
// inferred (the RMS is sigma * sqrt(3): 17.3 mm tracked).
constexpr double kTrackedMeanMm = 10.0 * 1.5958;

// A two-sensor synthetic take of 0.5 s (15 frames) at 480x270 colour,
// without meshes, written once per test run.
const std::string& SmallTake() {
  static const std::string* path = [] {
    auto* p = new std::string(testing::MakeTempDir("take_skeletons") + "/take.mcap");
    synth::SynthOptions options;
    // The sensors carry the jittered true skeleton (a device SDK stand-in).
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = "builtin:arm-raise";
    options.seconds = 0.5;
    options.num_sensors = 2;
    options.color_width = 480;
    options.color_height = 270;
    options.ground_truth_mesh = false;
    absl::StatusOr<synth::SynthSummary> summary = synth::SynthesizeTake(options, *p);
    EXPECT_TRUE(summary.ok()) << summary.status();
    return p;
  }();
  return *path;
}

struct RunResult {
  int code = 0;
  std::string out, err;
};

RunResult RunCommand(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  RunResult r;
  r.code = RunTakeSkeletons(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

nlohmann::json RunJson(const std::string& take, const std::string& truth) {
  const RunResult r = RunCommand({take, "--truth", truth, "--json"});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  return r.code == kExitOk ? nlohmann::json::parse(r.out) : nlohmann::json();
}

// A copy of `from`'s sensors and skeletons only, as a daemon would store it
// after anchoring the sensors on a board: every world_from_depth moved 1 m.
void WriteStoredTake(const std::string& from, const std::string& to) {
  auto source = TakeReader::Open(from);
  ASSERT_TRUE(source.ok()) << source.status();
  v1::TakeInfo info = (*source)->info();
  info.set_synthetic(false);
  auto writer = TakeWriter::Open(to, info);
  ASSERT_TRUE(writer.ok()) << writer.status();
  for (auto [id, calibration] : (*source)->sensors()) {
    calibration.mutable_world_from_depth()->mutable_translation_m()->set_x(
        calibration.world_from_depth().translation_m().x() + 1.0);
    calibration.set_world_anchor("board:test");
    ASSERT_TRUE((*writer)->AddSensor(calibration).ok());
    ASSERT_TRUE((*source)
                    ->ForEach<v1::Skeleton>(
                        SensorTopic(id, "skeleton"),
                        [&](const v1::Skeleton& s) { return (*writer)->WriteSkeleton(s); })
                    .ok());
  }
  ASSERT_TRUE((*writer)->Close().ok());
}

TEST(RunTakeSkeletons, SyntheticTakeMeetsItsJitterModel) {
  const nlohmann::json j = RunJson(SmallTake(), SmallTake());
  ASSERT_EQ(j["sensors"].size(), 2u);
  double best_sensor_mm = 1e9;
  for (const auto& s : j["sensors"]) {
    const double mpjpe = s["mpjpe_mm"].get<double>(), tracked = s["mpjpe_tracked_mm"].get<double>();
    const double pck = s["pck_10cm_percent"].get<double>();
    std::cout << s["id"].get<std::string>() << ": " << s["frames"] << " frames, MPJPE " << mpjpe
              << " mm (tracked " << tracked << " mm over " << s["joints_tracked"]
              << " joints, inferred " << s["mpjpe_inferred_mm"] << " mm over "
              << s["joints_inferred"] << "), PCK@10cm " << pck << " %\n";
    EXPECT_EQ(s["frames"].get<int>(), 15);
    EXPECT_EQ(s["calibration"].get<std::string>(), "truth");
    // About 350 tracked joint errors: the mean's standard error is 0.4 mm.
    EXPECT_NEAR(tracked, kTrackedMeanMm, 2.0);
    // Between all tracked (15.96 mm) and a quarter inferred (23.9 mm).
    EXPECT_GE(mpjpe, 14.0);
    EXPECT_LE(mpjpe, 26.0);
    EXPECT_GE(pck, 95.0);
    EXPECT_EQ(s["fusion_swapped_frames"].get<int>(), 0);
    best_sensor_mm = std::min(best_sensor_mm, mpjpe);
  }
  const nlohmann::json& fused = j["fused"];
  std::cout << "fused: MPJPE " << fused["mpjpe_mm"] << " mm, PCK@10cm " << fused["pck_10cm_percent"]
            << " %\n";
  EXPECT_EQ(fused["frames"].get<int>(), 15);
  EXPECT_LT(fused["mpjpe_mm"].get<double>(), best_sensor_mm);
  EXPECT_GE(fused["pck_10cm_percent"].get<double>(), 95.0);
  EXPECT_EQ(j["frames_without_truth"].get<int>(), 0);
  EXPECT_TRUE(fused["joint_mean_mm"]["HandLeft"].is_number());
}

TEST(RunTakeSkeletons, StoredTakeIsMeasuredInTheTruthsWorld) {
  const std::string stored = testing::MakeTempDir("take_skeletons_stored") + "/stored.mcap";
  WriteStoredTake(SmallTake(), stored);
  const nlohmann::json direct = RunJson(SmallTake(), SmallTake());
  const nlohmann::json via_stored = RunJson(stored, SmallTake());
  ASSERT_FALSE(via_stored.is_null());
  for (size_t s = 0; s < 2; ++s) {
    EXPECT_NEAR(via_stored["sensors"][s]["mpjpe_mm"].get<double>(),
                direct["sensors"][s]["mpjpe_mm"].get<double>(), 1e-9);
  }
  EXPECT_NEAR(via_stored["fused"]["mpjpe_mm"].get<double>(),
              direct["fused"]["mpjpe_mm"].get<double>(), 1e-9);
  // The stored take has no ground truth of its own.
  const RunResult r = RunCommand({stored, "--truth", stored});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find("no ground truth joints"), std::string::npos) << r.err;
}

TEST(RunTakeSkeletons, TextReportListsSensorsFusedAndJoints) {
  const RunResult r = RunCommand({SmallTake(), "--truth", SmallTake()});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  for (const char* text : {"MPJPE", "PCK@10cm", "k0", "k1", "fused", "HandTipRight"}) {
    EXPECT_NE(r.out.find(text), std::string::npos) << text << " in\n" << r.out;
  }
}

TEST(RunTakeSkeletons, TakeWithoutSkeletonsIsAClearError) {
  const std::string path = testing::MakeTempDir("take_skeletons_none") + "/empty.mcap";
  {
    auto source = TakeReader::Open(SmallTake());
    ASSERT_TRUE(source.ok());
    auto writer = TakeWriter::Open(path, (*source)->info());
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->AddSensor((*source)->sensors().begin()->second).ok());
    ASSERT_TRUE((*writer)->Close().ok());
  }
  const RunResult r = RunCommand({path, "--truth", SmallTake()});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find("no skeleton channel"), std::string::npos) << r.err;
}

TEST(RunTakeSkeletons, MissingFilesAndFlagsAreErrors) {
  const std::string missing = testing::MakeTempDir("take_skeletons_missing") + "/none.mcap";
  RunResult r = RunCommand({missing, "--truth", SmallTake()});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  r = RunCommand({SmallTake(), "--truth", missing});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  EXPECT_EQ(RunCommand({SmallTake()}).code, kExitUsage);
  EXPECT_EQ(RunCommand({"--truth", SmallTake()}).code, kExitUsage);
}

}  // namespace
}  // namespace reenact::cli
