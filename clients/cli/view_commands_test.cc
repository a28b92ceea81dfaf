// `reenact render` and `reenact eval` on local files: a synthetic take and
// the truth reenactment made from its ground truth (clients/view test helper).
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/commands.h"
#include "clients/view/truth_reenactment.h"
#include "common/body/procedural_body.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

struct Files {
  std::string dir, take, reenactment;
  std::string body_reenactment;  // The truth as a body-model reenactment.
};

// A 0.3 s two-sensor take at 480 x 270 and its truth reenactments (rigid
// parts, body model), once.
const Files& SharedFiles() {
  static const Files* files = [] {
    auto* f = new Files;
    f->dir = testing::MakeTempDir("cli_view");
    f->take = f->dir + "/take.mcap";
    f->reenactment = f->dir + "/truth.reen";
    std::ostringstream out, err;
    if (RunSynth({"--motion", "builtin:arm-raise", "--seconds", "0.3", "--sensors", "2",
                  "--color-width", "480", "--color-height", "270", "--out", f->take, "--quiet"},
                 out, err) != kExitOk) {
      ADD_FAILURE() << err.str();
      return f;
    }
    auto take = TakeReader::Open(f->take);
    auto model = body::BuildProceduralBody();
    if (!take.ok() || !model.ok()) {
      ADD_FAILURE() << take.status() << model.status();
      return f;
    }
    auto truth = view::testing::MakeTruthReenactment(**take, *model);
    if (!truth.ok()) {
      ADD_FAILURE() << truth.status();
      return f;
    }
    const absl::Status written = WriteReenactment(*truth, f->reenactment);
    if (!written.ok()) ADD_FAILURE() << written;
    auto body_truth = view::testing::MakeTruthBodyReenactment(**take, *model);
    if (!body_truth.ok()) {
      ADD_FAILURE() << body_truth.status();
      return f;
    }
    f->body_reenactment = f->dir + "/truth_body.reen";
    const absl::Status body_written = WriteReenactment(*body_truth, f->body_reenactment);
    if (!body_written.ok()) ADD_FAILURE() << body_written;
    return f;
  }();
  return *files;
}

TEST(RunEval, PrintsTheFiguresAsJson) {
  const Files& files = SharedFiles();
  std::ostringstream out, err;
  ASSERT_EQ(RunEval({"--in", files.reenactment, "--take", files.take, "--every", "4", "--json"},
                    out, err),
            kExitOk)
      << err.str();
  const nlohmann::json j = nlohmann::json::parse(out.str());
  EXPECT_EQ(j["frames_evaluated"].get<int>(), 3);  // Instants 0, 4, 8.
  EXPECT_LT(j["surface_mm"].get<double>(), 2.0);
  EXPECT_GT(j["psnr_db_90"].get<double>(), 18.0);
  EXPECT_GT(j["iou_90"].get<double>(), 0.97);
  EXPECT_LT(j["mpjpe_mm"].get<double>(), 1e-3);
  EXPECT_EQ(j["method"].get<std::string>(), "rigid-carved");
}

TEST(RunEval, MeasuresABodyReenactment) {
  const Files& files = SharedFiles();
  std::ostringstream out, err;
  ASSERT_EQ(
      RunEval({"--in", files.body_reenactment, "--take", files.take, "--every", "4", "--json"}, out,
              err),
      kExitOk)
      << err.str();
  const nlohmann::json j = nlohmann::json::parse(out.str());
  EXPECT_EQ(j["method"].get<std::string>(), "body");
  EXPECT_EQ(j["frames_evaluated"].get<int>(), 3);
  EXPECT_LT(j["surface_mm"].get<double>(), 0.01);  // The truth, up to float32 offsets.
  EXPECT_GT(j["iou_90"].get<double>(), 0.995);
  EXPECT_LT(j["mpjpe_mm"].get<double>(), 1e-3);
}

TEST(RunEval, UsageAndInputErrors) {
  const Files& files = SharedFiles();
  std::ostringstream out, err;
  EXPECT_EQ(RunEval({"--take", files.take}, out, err), kExitUsage);  // No reenactment.
  EXPECT_EQ(RunEval({"--in", files.reenactment, "--take", files.take, "--every", "0"}, out, err),
            kExitUsage);
  EXPECT_EQ(RunEval({"--in", files.dir + "/missing.reen", "--take", files.take}, out, err),
            kExitFailure);
  // The take's own file is no reenactment.
  EXPECT_NE(RunEval({"--in", files.take, "--take", files.take}, out, err), kExitOk);
}

TEST(RunRender, WritesOnePngPerFrame) {
  const Files& files = SharedFiles();
  for (const std::string camera : {"orbit:90", "sensor:1"}) {
    const std::string dir = files.dir + "/frames_" + camera.substr(0, 5);
    std::ostringstream out, err;
    ASSERT_EQ(RunRender({"--in", files.reenactment, "--camera", camera, "--out", dir, "--width",
                         "320", "--height", "180", "--frames", "2:5", "--quiet"},
                        out, err),
              kExitOk)
        << err.str();
    for (int f = 2; f < 5; ++f) {
      const std::string png = dir + "/frame_0000" + std::to_string(f) + ".png";
      EXPECT_TRUE(std::filesystem::exists(png)) << png;
    }
    EXPECT_FALSE(std::filesystem::exists(dir + "/frame_00005.png"));
  }
}

TEST(RunRender, RendersABodyReenactment) {
  const Files& files = SharedFiles();
  const std::string dir = files.dir + "/frames_body";
  std::ostringstream out, err;
  ASSERT_EQ(
      RunRender({"--in", files.body_reenactment, "--camera", "orbit:90", "--out", dir, "--width",
                 "320", "--height", "180", "--frames", "0:2", "--mode", "baked", "--quiet"},
                out, err),
      kExitOk)
      << err.str();
  EXPECT_TRUE(std::filesystem::exists(dir + "/frame_00001.png"));
}

TEST(RunRender, BadCameraFramesAndModeAreUsageErrors) {
  const Files& files = SharedFiles();
  std::ostringstream out, err;
  const std::string dir = files.dir + "/bad";
  EXPECT_EQ(RunRender({"--in", files.reenactment, "--camera", "sky", "--out", dir}, out, err),
            kExitUsage);
  EXPECT_EQ(RunRender({"--in", files.reenactment, "--camera", "sensor:7", "--out", dir}, out, err),
            kExitUsage);
  EXPECT_EQ(RunRender({"--in", files.reenactment, "--frames", "50:60", "--out", dir}, out, err),
            kExitUsage);
  EXPECT_EQ(RunRender({"--in", files.reenactment, "--mode", "fancy", "--out", dir}, out, err),
            kExitUsage);
  EXPECT_EQ(RunRender({"--in", files.reenactment}, out, err), kExitUsage);  // No --out.
}

}  // namespace
}  // namespace reenact::cli
