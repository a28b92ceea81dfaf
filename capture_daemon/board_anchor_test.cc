#include "capture_daemon/board_anchor.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <gtest/gtest.h>

#include "absl/strings/str_format.h"
#include "capture_daemon/daemon.h"
#include "capture_daemon/reenactd_cli.h"
#include "capture_daemon/testing/fake_ingest.h"
#include "capture_daemon/testing/synthetic_take.h"
#include "common/board/board_spec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

constexpr double kDegPerRad = 180.0 / M_PI;

Rigid3d Pose(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(angle_deg / kDegPerRad, axis.normalized())),
                 t);
}

TEST(CombineDetections, AveragesInliersAndDropsAFlippedPose) {
  const Eigen::Vector3d axis(0.3, 1.0, -0.2);
  const std::vector<std::pair<Rigid3d, double>> detections = {
      {Pose(30.0, axis, {1.000, 0.5, 2.0}), 0.40},
      {Pose(30.4, axis, {1.004, 0.5, 2.0}), 0.30},  // The reference (lowest RMS).
      {Pose(29.8, axis, {0.998, 0.5, 2.0}), 0.50},
      {Pose(-20.0, axis, {1.200, 0.5, 2.0}), 0.35},  // A flip: dropped.
  };
  auto combined = CombineDetections(detections);
  ASSERT_TRUE(combined.ok()) << combined.status();
  EXPECT_EQ(combined->detections, 3);
  EXPECT_NEAR(combined->rms_px, 0.4, 1e-9);  // px
  const double angle_deg =
      Eigen::AngleAxisd(combined->board_from_colour.rotation).angle() * kDegPerRad;
  EXPECT_NEAR(angle_deg, 30.0667, 0.01);                                     // deg
  EXPECT_NEAR(combined->board_from_colour.translation.x(), 1.000667, 1e-5);  // m
  EXPECT_TRUE(absl::IsNotFound(CombineDetections({}).status()));
}

TEST(AnchorCalibration, ComposesTheColourCameraWithColourFromDepth) {
  v1::SensorCalibration calibration;
  calibration.set_sensor_id("k0");
  *calibration.mutable_color_from_depth() =
      ToProto(Rigid3d(Eigen::Quaterniond::Identity(), {-0.052, 0, 0}));
  AnchorResult anchor;
  anchor.board_from_colour = Pose(90.0, Eigen::Vector3d::UnitX(), {0.0, 1.0, 0.0});
  anchor.rms_px = 0.25;
  auto anchored = AnchorCalibration(calibration, anchor, "board:x");
  ASSERT_TRUE(anchored.ok()) << anchored.status();
  auto world_from_depth = FromProto(anchored->world_from_depth());
  ASSERT_TRUE(world_from_depth.ok());
  // The depth origin sits 5.2 cm along the colour camera's -x: x is kept by
  // a rotation about X.
  EXPECT_NEAR((world_from_depth->translation - Eigen::Vector3d(-0.052, 1.0, 0.0)).norm(), 0.0,
              1e-12);
  EXPECT_EQ(anchored->world_anchor(), "board:x");
  EXPECT_EQ(anchored->world_anchor_rms_px(), 0.25);
}

TEST(AnchorOptions, ValidateNamesTheProblem) {
  AnchorOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.board_spec = "aruco:DICT_9X9_1:3x2:110:22";
  EXPECT_TRUE(absl::IsInvalidArgument(options.Validate()));
  options.board_spec = board::kDefaultBoardSpecText;
  options.frames = 0;
  EXPECT_TRUE(absl::IsInvalidArgument(options.Validate()));
  auto name = WorldAnchorName("aruco:dict_4x4_50:3x2:110:22");
  ASSERT_TRUE(name.ok()) << name.status();
  EXPECT_EQ(*name, "board:aruco:DICT_4X4_50:3x2:110:22");
}

TEST(ReenactdFlags, AnchorBoardWithOrWithoutSpec) {
  const std::string dir = reenact::testing::MakeTempDir("reenactd_anchor_flags");
  auto plain = ParseReenactdFlags({"--source", "playback:a.mcap", "--spool", dir});
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_FALSE(plain->anchor.enabled());
  auto board =
      ParseReenactdFlags({"--source", "playback:a.mcap", "--spool", dir, "--anchor", "board"});
  ASSERT_TRUE(board.ok()) << board.status();
  EXPECT_EQ(board->anchor.board_spec, board::kDefaultBoardSpecText);
  auto spec = ParseReenactdFlags({"--source", "playback:a.mcap", "--spool", dir, "--anchor",
                                  "board:aruco:DICT_5X5_100:4x3:80:16", "--anchor-timeout-s", "3"});
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->anchor.board_spec, "aruco:DICT_5X5_100:4x3:80:16");
  EXPECT_EQ(spec->anchor.timeout_s, 3.0);
  const std::string config = dir + "/reenactd.conf";
  std::ofstream(config) << R"({"source": ["playback:a.mcap"], "anchor": "board"})";
  auto configured = ParseReenactdFlags({"--config", config, "--spool", dir});
  ASSERT_TRUE(configured.ok()) << configured.status();
  EXPECT_EQ(configured->anchor.board_spec, board::kDefaultBoardSpecText);
  EXPECT_TRUE(absl::IsInvalidArgument(
      ParseReenactdFlags({"--source", "playback:a.mcap", "--spool", dir, "--anchor", "wall"})
          .status()));
  EXPECT_TRUE(absl::IsInvalidArgument(
      ParseReenactdFlags({"--source", "playback:a.mcap", "--spool", dir, "--anchor", "board:bad"})
          .status()));
}

// A 2-sensor take of Kinect v2 colour (1920x1080) with the default board on
// the floor beside the actor; made once per test binary.
const std::string& BoardTakePath() {
  static const std::string path = [] {
    const std::string file = reenact::testing::MakeTempDir("capture_board_take") + "/take.mcap";
    synth::SynthOptions options;
    // The sensors carry the jittered true skeleton (a device SDK stand-in).
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = "builtin:arm-raise";
    options.num_sensors = 2;
    options.seconds = 0.4;
    options.ground_truth_mesh = false;
    options.board = board::kDefaultBoardSpecText;
    auto summary = synth::SynthesizeTake(options, file);
    EXPECT_TRUE(summary.ok()) << summary.status();
    return file;
  }();
  return path;
}

// Runs a --once daemon with --anchor board over `take_path`; the take the
// fake server received.
testing::FakeTake RunAnchoredOnce(const std::string& name, const std::string& take_path,
                                  std::string* log_text) {
  testing::FakeIngestServer server;
  EXPECT_TRUE(server.ok());
  DaemonOptions options;
  options.server_address = server.address();
  options.sources = {{"playback", take_path}};
  options.control_address = "";
  options.spool_dir = reenact::testing::MakeTempDir(name) + "/spool";
  options.daemon_id = "test-daemon";
  options.drain_timeout_s = 5.0;
  options.once = true;
  // Real time (the takes last under 0.5 s): fast playback on a loaded
  // machine can starve one sensor's stream so long that the sync group
  // drops its instants.
  options.fast = false;
  options.anchor.board_spec = board::kDefaultBoardSpecText;
  std::ostringstream log;
  options.log = &log;
  auto daemon = Daemon::Create(options);
  EXPECT_TRUE(daemon.ok()) << daemon.status();
  if (!daemon.ok()) return {};
  const absl::Status result = (*daemon)->Run();
  EXPECT_TRUE(result.ok()) << result << "\n" << log.str();
  *log_text = log.str();
  const auto takes = server.service().takes();
  EXPECT_EQ(takes.size(), 1u);
  return takes.empty() ? testing::FakeTake{} : takes.begin()->second;
}

TEST(DaemonAnchor, BoardPutsEverySensorInTheBoardFrame) {
  auto source = TakeReader::Open(BoardTakePath());
  ASSERT_TRUE(source.ok()) << source.status();
  auto topology = (*source)->ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic);
  ASSERT_TRUE(topology.ok() && topology->size() == 1u);
  EXPECT_EQ(topology->front().board_spec(), board::kDefaultBoardSpecText);
  auto world_from_board = FromProto(topology->front().world_from_board());
  ASSERT_TRUE(world_from_board.ok());

  std::string log;
  const testing::FakeTake take = RunAnchoredOnce("daemon_anchor", BoardTakePath(), &log);
  std::cout << log;
  EXPECT_TRUE(take.closed);
  ASSERT_EQ(take.open.sensors_size(), 2);
  // Anchoring never holds the frame path: every instant arrives whole.
  const auto source_depth = testing::ReadDepth(BoardTakePath());
  EXPECT_EQ(take.sets.size(), source_depth.at("k0").size());
  for (const v1::FrameSet& set : take.sets) EXPECT_EQ(set.frames_size(), 2) << set.sequence();
  for (const v1::SensorCalibration& anchored : take.open.sensors()) {
    const v1::SensorCalibration& given = (*source)->sensors().at(anchored.sensor_id());
    auto world_from_depth = FromProto(given.world_from_depth());
    auto board_from_depth = FromProto(anchored.world_from_depth());
    ASSERT_TRUE(world_from_depth.ok() && board_from_depth.ok());
    // Truth: board_from_world (synthetic) * world_from_depth (synthetic).
    const Rigid3d truth = world_from_board->Inverse() * *world_from_depth;
    const double rotation_deg =
        truth.rotation.angularDistance(board_from_depth->rotation) * kDegPerRad;
    const double translation_mm = 1e3 * (truth.translation - board_from_depth->translation).norm();
    std::cout << absl::StrFormat(
        "sensor %s anchored on the board: rotation error %.3f deg, position error %.1f mm, "
        "RMS %.2f px, %s\n",
        anchored.sensor_id(), rotation_deg, translation_mm, anchored.world_anchor_rms_px(),
        anchored.world_anchor());
    EXPECT_EQ(anchored.world_anchor(), "board:aruco:DICT_4X4_50:3x2:110:22");
    EXPECT_LT(rotation_deg, 1.0);     // deg
    EXPECT_LT(translation_mm, 20.0);  // mm
    EXPECT_GT(anchored.world_anchor_rms_px(), 0.0);
    EXPECT_LT(anchored.world_anchor_rms_px(), 2.0);  // px
  }
}

TEST(DaemonAnchor, NoBoardInViewKeepsTheCalibrationsWithAWarning) {
  auto source = TakeReader::Open(testing::SyntheticTakePath());
  ASSERT_TRUE(source.ok()) << source.status();
  std::string log;
  const testing::FakeTake take =
      RunAnchoredOnce("daemon_anchor_none", testing::SyntheticTakePath(), &log);
  EXPECT_TRUE(take.closed);
  ASSERT_EQ(take.open.sensors_size(), 2);
  EXPECT_EQ(take.sets.size(), testing::ReadDepth(testing::SyntheticTakePath()).at("k0").size());
  for (const v1::SensorCalibration& sent : take.open.sensors()) {
    const v1::SensorCalibration& given = (*source)->sensors().at(sent.sensor_id());
    EXPECT_EQ(sent.world_anchor(), "");
    EXPECT_EQ(sent.world_from_depth().SerializeAsString(),
              given.world_from_depth().SerializeAsString());
    EXPECT_NE(log.find("sensor " + sent.sensor_id() + " is not anchored"), std::string::npos)
        << log;
  }
}

}  // namespace
}  // namespace reenact::capture
