// Test helper of server/recon: a synthetic take made once for a test suite
// from a CMU clip of the test data (SetUpTestSuite), loaded, with the
// reason when it could not be (no clip, no GL for synthesis).
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "absl/status/status.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "server/recon/take_frames.h"

namespace reenact::recon::testing {

struct SuiteTake {
  std::string path;
  std::unique_ptr<TakeFrames> take;
  std::string skip;    // Why the suite is skipped (no clip, no GL).
  absl::Status error;  // Synthesis or loading failed otherwise.
};

// Two sensors at 15 fps with 640x360 colour, the sensors carrying the
// jittered true skeleton, of `seconds` of CMU clip `clip` (under the test
// data's mocap/cmu/) on a procedural body of shape `shape`, with the ground
// truth's meshes when `truth_meshes`; written into a temporary folder named
// `name`.
inline SuiteTake MakeSuiteTake(const std::string& name, const std::string& clip,
                               const std::string& shape, double seconds, bool truth_meshes = true) {
  SuiteTake made;
  const std::string motion = reenact::testing::TestDataPath("mocap/cmu/" + clip);
  if (!std::filesystem::exists(motion)) {
    made.skip = "no CMU clip " + clip + " under the test data";
    return made;
  }
  synth::SynthOptions options;
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.motion = motion;
  options.body = "procedural";
  options.shape = shape;
  options.num_sensors = 2;
  options.seconds = seconds;
  options.fps = 15.0;
  options.color_width = 640;
  options.color_height = 360;
  options.ground_truth_mesh = truth_meshes;
  made.path = reenact::testing::MakeTempDir(name) + "/take.mcap";
  auto summary = synth::SynthesizeTake(options, made.path);
  if (!summary.ok()) {
    if (summary.status().code() == absl::StatusCode::kUnavailable) {
      made.skip = std::string(summary.status().message());
    } else {
      made.error = summary.status();
    }
    return made;
  }
  auto take = TakeFrames::Load(made.path);
  if (!take.ok()) {
    made.error = take.status();
    return made;
  }
  made.take = std::move(*take);
  return made;
}

}  // namespace reenact::recon::testing

// In a fixture's SetUp: skips the test, or fails it, as `suite_take` says.
#define RECON_REQUIRE_SUITE_TAKE(suite_take)                                  \
  do {                                                                        \
    if (!(suite_take).skip.empty()) GTEST_SKIP() << (suite_take).skip;        \
    ASSERT_TRUE((suite_take).error.ok()) << (suite_take).error;               \
    ASSERT_NE((suite_take).take, nullptr) << "the suite's take was not made"; \
  } while (false)
