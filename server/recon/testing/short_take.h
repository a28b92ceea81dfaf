// Test helpers of server/recon: one short synthetic take per test process.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::recon::testing {

// Options of the shared take: the arm raise (arms from hanging to about
// horizontal over the take), two sensors, 1.5 s at 15 fps, 640x360 colour.
inline synth::SynthOptions SharedTakeOptions() {
  synth::SynthOptions options;
  // The sensors carry the jittered true skeleton (a device SDK stand-in).
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.motion = "builtin:arm-raise";
  options.num_sensors = 2;
  options.seconds = 1.5;
  options.fps = 15.0;
  options.color_width = 640;
  options.color_height = 360;
  options.ground_truth_mesh = true;
  return options;
}

struct SharedTake {
  std::string path;
  synth::SynthSummary summary;
  std::string error;  // Non-empty when synthesis failed.
};

// Synthesises the shared take once (a few seconds of CPU). ctest runs every
// test in its own process, so the take is cached in the temp folder under a
// name that changes with each build of the test binary (its mtime); the
// take is synthesised under a per-process name and renamed into place, so
// concurrent processes never see a partial file.
inline const SharedTake& GetSharedTake() {
  static const SharedTake* take = [] {
    namespace fs = std::filesystem;
    auto* t = new SharedTake;
    std::error_code ec;
    const auto stamp = fs::last_write_time("/proc/self/exe", ec).time_since_epoch().count();
    // One folder per test executable: each clears only its own older takes
    // (another executable's take may be in use or being written).
    const fs::path dir = fs::temp_directory_path() / "reenact_recon_test_takes" /
                         fs::read_symlink("/proc/self/exe", ec).filename();
    fs::create_directories(dir, ec);
    const std::string name = "arm_raise_" + std::to_string(stamp) + ".mcap";
    t->path = (dir / name).string();
    const fs::path summary_path = dir / (name + ".frames");
    if (fs::exists(t->path, ec) && fs::exists(summary_path, ec)) {
      std::ifstream in(summary_path);
      in >> t->summary.frames;
      if (t->summary.frames > 0) return t;
    }
    // Older builds' takes go.
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      if (entry.path().filename().string().rfind(name, 0) != 0) fs::remove(entry.path(), ec);
    }
    // Per-process name first (concurrent ctest processes), then in place.
    const std::string mine = t->path + "." + std::to_string(::getpid());
    auto summary = synth::SynthesizeTake(SharedTakeOptions(), mine);
    if (summary.ok()) fs::rename(mine, t->path, ec);
    if (summary.ok() && ec) summary = absl::InternalError("cannot rename " + mine);
    if (summary.ok()) {
      t->summary = *summary;
      const std::string tmp = summary_path.string() + ".tmp" + std::to_string(::getpid());
      std::ofstream(tmp) << summary->frames << "\n";
      fs::rename(tmp, summary_path, ec);
    } else {
      t->error = std::string(summary.status().message());
    }
    return t;
  }();
  return *take;
}

}  // namespace reenact::recon::testing

// Fails the test when the shared take could not be made.
#define RECON_REQUIRE_SHARED_TAKE()                                     \
  ASSERT_TRUE(::reenact::recon::testing::GetSharedTake().error.empty()) \
      << "synthesis failed: " << ::reenact::recon::testing::GetSharedTake().error
