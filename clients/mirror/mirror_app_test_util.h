// Test support for the mirror app's tests: a synthetic teacher (a built-in
// motion, its reenactment made from the take's ground truth) and synthetic
// learners doing the same motion, made once per test process.
#pragma once

#include <map>
#include <string>
#include <tuple>
#include <utility>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "clients/view/truth_reenactment.h"
#include "common/body/procedural_body.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::mirror::testing {

inline constexpr char kMotion[] = "builtin:front-kick";
inline constexpr int kColorWidth = 480;
inline constexpr int kColorHeight = 270;

inline const std::string& TestDir() {
  static const std::string dir = reenact::testing::MakeTempDir("mirror_app");
  return dir;
}

inline synth::SynthOptions TakeOptions(double seconds, double yaw_deg, uint64_t seed) {
  synth::SynthOptions options;
  // The sensors carry the jittered true skeleton (a device SDK stand-in).
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.motion = kMotion;
  options.num_sensors = 1;
  options.seconds = seconds;
  options.color_width = kColorWidth;
  options.color_height = kColorHeight;
  options.yaw_deg = yaw_deg;
  options.seed = seed;
  return options;
}

// A learner take of the motion, `seconds` long, turned by `yaw_deg`, its
// skeleton channel jittered by `jitter_m` per axis (3x where a joint is
// hidden); the path, or empty after a test failure.
inline std::string LearnerTake(double seconds, double yaw_deg, double jitter_m = 0.01) {
  static std::map<std::tuple<double, double, double>, std::string> made;
  const auto key = std::make_tuple(seconds, yaw_deg, jitter_m);
  if (auto it = made.find(key); it != made.end()) return it->second;
  const std::string path = absl::StrCat(TestDir(), "/learner_", seconds, "s_yaw", yaw_deg,
                                        "_jitter", jitter_m * 1e3, "mm.mcap");
  synth::SynthOptions options = TakeOptions(seconds, yaw_deg, 2);
  options.ground_truth_mesh = false;
  options.skeleton_jitter_m = jitter_m;
  const auto summary = synth::SynthesizeTake(options, path);
  if (!summary.ok()) {
    ADD_FAILURE() << summary.status();
    return "";
  }
  return made[key] = path;
}

// The teacher's take: 2 s of the motion with its ground truth; the path, or
// empty after a test failure.
inline std::string TeacherTake() {
  static std::string made;
  if (!made.empty()) return made;
  const std::string path = TestDir() + "/teacher.mcap";
  const auto summary = synth::SynthesizeTake(TakeOptions(2.0, 0.0, 1), path);
  if (!summary.ok()) {
    ADD_FAILURE() << summary.status();
    return "";
  }
  return made = path;
}

// The teacher as a reenactment of the take's ground truth written to a .reen
// file: the body model (`rigid` false) or 15 rigid parts textured from the
// take's colour images (VDTM); the path, or empty after a test failure.
inline std::string TeacherReen(bool rigid = false) {
  static std::map<bool, std::string> made;
  if (auto it = made.find(rigid); it != made.end()) return it->second;
  const std::string take_path = TeacherTake();
  if (take_path.empty()) return "";
  auto take = TakeReader::Open(take_path);
  auto model = body::BuildProceduralBody();
  if (!take.ok() || !model.ok()) {
    ADD_FAILURE() << "teacher take or body model did not load";
    return "";
  }
  auto data = rigid ? view::testing::MakeTruthReenactment(**take, *model)
                    : view::testing::MakeTruthBodyReenactment(**take, *model);
  if (!data.ok()) {
    ADD_FAILURE() << data.status();
    return "";
  }
  const std::string path = TestDir() + (rigid ? "/teacher_rigid.reen" : "/teacher.reen");
  if (absl::Status written = WriteReenactmentFile(*data, path); !written.ok()) {
    ADD_FAILURE() << written;
    return "";
  }
  return made[rigid] = path;
}

}  // namespace reenact::mirror::testing
