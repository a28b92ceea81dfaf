// Test support for the mirror app's tests: a synthetic teacher (a built-in
// motion, its reenactment made from the take's ground truth) and synthetic
// learners doing the same motion, made once per test process.
#pragma once

#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "clients/view/truth_reenactment.h"
#include "common/body/procedural_body.h"
#include "common/io/proto_convert.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "common/tracking/tracking_proto.h"

namespace reenact::mirror::testing {

inline constexpr char kMotion[] = "builtin:front-kick";
inline constexpr int kColorWidth = 480;
inline constexpr int kColorHeight = 270;

inline const std::string& TestDir() {
  static const std::string dir = reenact::testing::MakeTempDir("mirror_app");
  return dir;
}

// `sensor_skeleton`: the sensors carry the jittered true skeleton (a device
// SDK stand-in); otherwise none, as real depth cameras.
inline synth::SynthOptions TakeOptions(double seconds, double yaw_deg, uint64_t seed,
                                       bool sensor_skeleton = true) {
  synth::SynthOptions options;
  options.sensor_skeleton = sensor_skeleton ? synth::SynthOptions::SensorSkeleton::kTruth
                                            : synth::SynthOptions::SensorSkeleton::kNone;
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
// hidden), or without skeletons when `sensor_skeleton` is false (the mirror
// then tracks the learner in the depth); the path, or empty after a test
// failure.
inline std::string LearnerTake(double seconds, double yaw_deg, double jitter_m = 0.01,
                               bool sensor_skeleton = true) {
  static std::map<std::tuple<double, double, double, bool>, std::string> made;
  const auto key = std::make_tuple(seconds, yaw_deg, jitter_m, sensor_skeleton);
  if (auto it = made.find(key); it != made.end()) return it->second;
  const std::string path =
      absl::StrCat(TestDir(), "/learner_", seconds, "s_yaw", yaw_deg, "_jitter", jitter_m * 1e3,
                   sensor_skeleton ? "mm" : "mm_untracked", ".mcap");
  synth::SynthOptions options = TakeOptions(seconds, yaw_deg, 2, sensor_skeleton);
  options.ground_truth_mesh = false;
  options.skeleton_jitter_m = jitter_m;
  const auto summary = synth::SynthesizeTake(options, path);
  if (!summary.ok()) {
    ADD_FAILURE() << summary.status();
    return "";
  }
  return made[key] = path;
}

// The teacher's take: 2 s of the motion with its ground truth, its sensor
// with the jittered true skeleton or (`sensor_skeleton` false) none; the
// path, or empty after a test failure.
inline std::string TeacherTake(bool sensor_skeleton = true) {
  static std::map<bool, std::string> made;
  if (auto it = made.find(sensor_skeleton); it != made.end()) return it->second;
  const std::string path =
      TestDir() + (sensor_skeleton ? "/teacher.mcap" : "/teacher_untracked.mcap");
  const auto summary = synth::SynthesizeTake(TakeOptions(2.0, 0.0, 1, sensor_skeleton), path);
  if (!summary.ok()) {
    ADD_FAILURE() << summary.status();
    return "";
  }
  return made[sensor_skeleton] = path;
}

// The teacher as a reenactment of the take's ground truth written to a .reen
// file: the body model (`rigid` false) or 15 rigid parts textured from the
// take's colour images (VDTM); the path, or empty after a test failure.
// TeacherTake(sensor_skeleton) and its ground truth as a reenactment: the
// body model (`rigid` false) or 15 rigid parts textured from the take's
// colour images; nullopt after a test failure.
struct TruthTeacher {
  std::unique_ptr<TakeReader> take;
  Reenactment data;
};
inline std::optional<TruthTeacher> MakeTruthTeacher(bool rigid, bool sensor_skeleton) {
  const std::string take_path = TeacherTake(sensor_skeleton);
  if (take_path.empty()) return std::nullopt;
  auto take = TakeReader::Open(take_path);
  auto model = body::BuildProceduralBody();
  if (!take.ok() || !model.ok()) {
    ADD_FAILURE() << "teacher take or body model did not load";
    return std::nullopt;
  }
  auto data = rigid ? view::testing::MakeTruthReenactment(**take, *model)
                    : view::testing::MakeTruthBodyReenactment(**take, *model);
  if (!data.ok()) {
    ADD_FAILURE() << data.status();
    return std::nullopt;
  }
  return TruthTeacher{*std::move(take), *std::move(data)};
}

// Writes `data` to `path`: the path, or empty after a test failure.
inline std::string WriteTeacher(const Reenactment& data, const std::string& path) {
  if (absl::Status written = WriteReenactment(data, path); !written.ok()) {
    ADD_FAILURE() << written;
    return "";
  }
  return path;
}

// The teacher as a reenactment of the take's ground truth written to a .reen
// file (MakeTruthTeacher); the path, or empty after a test failure.
inline std::string TeacherReen(bool rigid = false) {
  static std::map<bool, std::string> made;
  if (auto it = made.find(rigid); it != made.end()) return it->second;
  std::optional<TruthTeacher> teacher = MakeTruthTeacher(rigid, /*sensor_skeleton=*/true);
  if (!teacher) return "";
  return made[rigid] = WriteTeacher(teacher->data,
                                    TestDir() + (rigid ? "/teacher_rigid.reen" : "/teacher.reen"));
}

// The teacher as the mirror gets it from a take of a sensor without skeleton:
// the body reenactment of TeacherTake(false)'s ground truth, its skeleton
// (PartFrame.joints_in_world_m) replaced by the one the body tracker finds in
// the sensor's depth (tracking::TrackTakeSensor, as reenactd tracks), moved
// to the world; a joint the tracker did not track is NaN (invalid). The
// path, or empty after a test failure.
inline std::string TrackedTeacherReen() {
  static std::string made;
  if (!made.empty()) return made;
  std::optional<TruthTeacher> teacher =
      MakeTruthTeacher(/*rigid=*/false, /*sensor_skeleton=*/false);
  if (!teacher) return "";
  auto& take = teacher->take;
  Reenactment* data = &teacher->data;
  auto tracked = tracking::TrackTakeSensor(*take, "k0");
  if (!tracked.ok()) {
    ADD_FAILURE() << tracked.status();
    return "";
  }
  auto world_from_depth = FromProto(take->sensors().at("k0").world_from_depth());
  if (!world_from_depth.ok()) {
    ADD_FAILURE() << world_from_depth.status();
    return "";
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  int with_skeleton = 0;
  for (ReenactmentFrame& frame : data->frames) {
    frame.joints_in_world_m.clear();
    const auto found = tracked->find(frame.frame_index);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      Eigen::Vector3d p(nan, nan, nan);
      if (found != tracked->end() && !found->second.empty()) {
        const v1::Joint& joint = found->second.front().joints(j);
        if (joint.tracking_state() != v1::TRACKING_STATE_NOT_TRACKED) {
          p = *world_from_depth * FromProto(joint.position_in_depth_m());
        }
      }
      frame.joints_in_world_m.push_back(p);
    }
    if (found != tracked->end()) ++with_skeleton;
  }
  if (with_skeleton < static_cast<int>(data->frames.size()) * 9 / 10) {
    ADD_FAILURE() << "the tracker found the teacher in " << with_skeleton << " of "
                  << data->frames.size() << " frames";
    return "";
  }
  return made = WriteTeacher(*data, TestDir() + "/teacher_tracked.reen");
}

}  // namespace reenact::mirror::testing
