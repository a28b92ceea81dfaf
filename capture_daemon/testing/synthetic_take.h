// Test-only: one small synthetic take (common/synth) per test binary, made
// on first use: 2 sensors, 0.5 s at 30 fps, 320x180 colour, no mesh.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::capture::testing {

inline const std::string& SyntheticTakePath() {
  static const std::string path = [] {
    const std::string dir = reenact::testing::MakeTempDir("capture_synthetic_take");
    const std::string file = dir + "/take.mcap";
    synth::SynthOptions options;
    // The sensors carry the jittered true skeleton (a device SDK stand-in).
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = "builtin:arm-raise";
    options.num_sensors = 2;
    options.seconds = 0.5;
    options.fps = 30.0;
    options.color_width = 320;
    options.color_height = 180;
    options.ground_truth_mesh = false;
    auto summary = synth::SynthesizeTake(options, file);
    EXPECT_TRUE(summary.ok()) << summary.status();
    return file;
  }();
  return path;
}

// The take's depth messages by sensor id, in file order.
inline std::map<std::string, std::vector<v1::DepthImage>> ReadDepth(const std::string& path) {
  std::map<std::string, std::vector<v1::DepthImage>> out;
  auto reader = TakeReader::Open(path);
  EXPECT_TRUE(reader.ok()) << reader.status();
  if (!reader.ok()) return out;
  for (const auto& [id, calibration] : (*reader)->sensors()) {
    auto depth = (*reader)->ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    EXPECT_TRUE(depth.ok()) << depth.status();
    if (depth.ok()) out[id] = std::move(*depth);
  }
  return out;
}

}  // namespace reenact::capture::testing
