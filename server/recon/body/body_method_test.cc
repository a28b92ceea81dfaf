// The method "body" on synthetic takes against their ground truth: the
// procedural body (random shape) dancing a CMU clip, fitted with the
// procedural model from its mean shape (issue floor: MPJPE <= 15 mm).
#include "server/recon/body/body_method.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "common/io/video_reader.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "server/recon/methods.h"

namespace reenact::recon {
namespace {

struct Truth {
  std::map<int64_t, JointArray> joints;
  std::map<int64_t, Eigen::Matrix3Xd> vertices;
};

Truth ReadTruth(const std::string& path) {
  Truth truth;
  auto reader = TakeReader::Open(path);
  EXPECT_TRUE(reader.ok()) << reader.status();
  if (!reader.ok()) return truth;
  auto joints = (*reader)->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  EXPECT_TRUE(joints.ok());
  for (const v1::GroundTruthJoints& g : *joints) {
    JointArray j = MissingJoints();
    for (int i = 0; i < g.joint_names_size() && i < g.positions_in_world_m_size(); ++i) {
      if (auto id = body::KinectV2JointFromName(g.joint_names(i))) {
        j[body::Index(*id)] = FromProto(g.positions_in_world_m(i));
      }
    }
    truth.joints[g.frame_index()] = j;
  }
  auto meshes = (*reader)->ReadAll<v1::GroundTruthMesh>(kGroundTruthMeshTopic);
  EXPECT_TRUE(meshes.ok());
  for (const v1::GroundTruthMesh& m : *meshes) {
    auto floats = UnpackFloats(m.positions_in_world_m_f32());
    if (!floats.ok()) continue;
    Eigen::Matrix3Xd v(3, floats->size() / 3);
    for (size_t i = 0; i < floats->size(); ++i) v(i % 3, i / 3) = (*floats)[i];
    truth.vertices[m.frame_index()] = std::move(v);
  }
  return truth;
}

// Two sensors at 15 fps (640x360 colour) watching the procedural body of
// shape `shape` doing 2 s of `clip`; the sensors carry the jittered true
// skeleton (a device SDK stand-in).
synth::SynthOptions TwoSensorTake(const std::string& clip, const std::string& shape) {
  synth::SynthOptions options;
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.motion = clip;
  options.body = "procedural";
  options.shape = shape;
  options.num_sensors = 2;
  options.seconds = 2.0;
  options.fps = 15.0;
  options.color_width = 640;
  options.color_height = 360;
  return options;
}

// The take of `options` written to `path`, and its ground truth.
absl::StatusOr<Truth> SynthesiseWithTruth(const synth::SynthOptions& options,
                                          const std::string& path) {
  RETURN_IF_ERROR(synth::SynthesizeTake(options, path).status());
  return ReadTruth(path);
}

// A body job on `take_path` with `options` (atlas_px 128 added), written to
// `path`: its figures and frames, and each frame's mean joint error
// against `truth` (mm, by frame index).
struct BodyRun {
  std::map<std::string, double> figures;
  v1::ReenactmentInfo info;
  std::vector<v1::PartFrame> frames;
  std::map<int64_t, double> joint_error_mm;
  // The mean over the frames of `keep` (all by default).
  double MeanErrorMm(const std::function<bool(const v1::PartFrame&)>& keep = nullptr) const {
    double sum = 0.0;
    int n = 0;
    for (const v1::PartFrame& frame : frames) {
      const auto e = joint_error_mm.find(frame.frame_index());
      if (e == joint_error_mm.end() || (keep && !keep(frame))) continue;
      sum += e->second;
      ++n;
    }
    return sum / std::max(1, n);
  }
};

BodyRun RunBodyJob(const std::string& take_path, const std::string& path,
                   std::map<std::string, std::string> options, const Truth& truth) {
  BodyRun out;
  MethodInput input;
  input.take_path = take_path;
  input.method = "body";
  input.options = std::move(options);
  input.options.emplace("atlas_px", "128");
  auto result = RunMethod(input, path);
  EXPECT_TRUE(result.ok()) << result.status();
  if (!result.ok()) return out;
  out.figures = result->figures;
  auto data = ReadReenactmentFile(path);
  EXPECT_TRUE(data.ok()) << data.status();
  if (!data.ok()) return out;
  out.frames = data->frames;
  out.info = data->info;
  for (const v1::PartFrame& frame : out.frames) {
    const auto t = truth.joints.find(frame.frame_index());
    if (t == truth.joints.end()) continue;
    double sum = 0.0;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      sum += 1000.0 * (FromProto(frame.joints_in_world_m(j)) - t->second[j]).norm();
    }
    out.joint_error_mm[frame.frame_index()] = sum / body::kNumKinectV2Joints;
  }
  return out;
}

TEST(RunBody, ProceduralBodyFittedWithTheProceduralModelMeetsTheJointFloor) {
  const std::string dir = reenact::testing::MakeTempDir("body_method");
  const std::string clip = reenact::testing::TestDataPath("mocap/cmu/131_01.bvh");
  if (!std::filesystem::exists(clip)) GTEST_SKIP() << "no CMU clip at " << clip;
  const synth::SynthOptions options = TwoSensorTake(clip, "random:7");
  const std::string take_path = dir + "/take.mcap";
  auto summary = synth::SynthesizeTake(options, take_path);
  if (!summary.ok() && summary.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << summary.status();
  }
  ASSERT_TRUE(summary.ok()) << summary.status();

  MethodInput input;
  input.take_path = take_path;
  input.method = "body";
  input.options = {{"atlas_px", "256"}};
  const std::string out = dir + "/body.reen";
  auto result = RunMethod(input, out);
  ASSERT_TRUE(result.ok()) << result.status();
  auto data = ReadReenactmentFile(out);
  ASSERT_TRUE(data.ok()) << data.status();
  ASSERT_TRUE(data->is_body());
  auto mesh = DecodeBodyMesh(data->body.front());
  ASSERT_TRUE(mesh.ok());

  const Truth truth = ReadTruth(take_path);
  double joint_sum_mm = 0.0, vertex_sum_mm = 0.0;
  int joints = 0, vertex_frames = 0;
  for (const v1::PartFrame& frame : data->frames) {
    const auto t = truth.joints.find(frame.frame_index());
    ASSERT_NE(t, truth.joints.end());
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      joint_sum_mm += 1000.0 * (FromProto(frame.joints_in_world_m(j)) - t->second[j]).norm();
      ++joints;
    }
    auto posed = PoseBodyMesh(*mesh, frame.body());
    ASSERT_TRUE(posed.ok());
    const auto v = truth.vertices.find(frame.frame_index());
    if (v != truth.vertices.end() && v->second.cols() == posed->vertices_m.cols()) {
      vertex_sum_mm += 1000.0 * (posed->vertices_m - v->second).colwise().norm().mean();
      ++vertex_frames;
    }
  }
  const double mpjpe_mm = joint_sum_mm / joints;
  std::printf(
      "body (procedural on procedural, random shape, CMU 131_01, %d frames): MPJPE %.2f mm "
      "(floor 15), mean vertex-to-vertex error %.2f mm, fit %.1f ms per frame, point RMS "
      "%.2f mm\n",
      result->frames, mpjpe_mm, vertex_sum_mm / std::max(1, vertex_frames),
      result->figures["fit_ms_per_frame"], result->figures["point_rms_mm"]);
  EXPECT_LE(mpjpe_mm, 15.0);
  ASSERT_GT(vertex_frames, 0);
  EXPECT_LE(vertex_sum_mm / vertex_frames, 15.0);

  // The per-frame appearance: one 512 px atlas per instant in a video that
  // decodes, each close to the static atlas (the same clothes) but not it
  // (what the sensors saw at that instant).
  ASSERT_FALSE(mesh->appearance_mp4.empty());
  EXPECT_EQ(mesh->appearance_frame_count, data->info.frame_count());
  auto video = VideoReader::Open(mesh->appearance_mp4);
  ASSERT_TRUE(video.ok()) << video.status();
  EXPECT_EQ((*video)->frame_count(), data->info.frame_count());
  EXPECT_EQ((*video)->width(), 512);
  auto atlas = DecodeJpeg(mesh->atlas_jpeg);
  ASSERT_TRUE(atlas.ok());
  double min_difference = 1e9, max_difference = 0.0;
  for (int k = 0; k < (*video)->frame_count(); k += 7) {
    auto frame = (*video)->Frame(k);
    ASSERT_TRUE(frame.ok()) << frame.status();
    // Mean absolute difference to the static atlas (256 px: every other
    // texel of the 512 px frame).
    double sum = 0.0;
    for (int y = 0; y < atlas->height; ++y) {
      for (int x = 0; x < atlas->width; ++x) {
        for (int c = 0; c < 3; ++c) {
          sum += std::abs(frame->at(2 * x, 2 * y, c) - atlas->at(x, y, c));
        }
      }
    }
    const double difference = sum / (3.0 * atlas->width * atlas->height);
    min_difference = std::min(min_difference, difference);
    max_difference = std::max(max_difference, difference);
  }
  const double bytes_per_s = result->figures["appearance_bytes_per_second"];
  std::printf(
      "appearance video: %zu bytes for %d frames (%.0f kB/s), %.1f s to bake; its frames differ "
      "from the static atlas by %.2f-%.2f levels on average\n",
      mesh->appearance_mp4.size(), (*video)->frame_count(), bytes_per_s / 1000.0,
      result->figures["appearance_seconds"], min_difference, max_difference);
  EXPECT_GT(min_difference, 0.3);
  EXPECT_LT(max_difference, 12.0);
  EXPECT_GT(bytes_per_s, 0.0);
  EXPECT_LT(bytes_per_s, 4e6);
}

// The tracker made worse on purpose (issue figures): 80 mm of noise on the
// limbs, the arms swapped in a tenth of the frames and the left leg lost
// for half a second, the same in both sensors' skeletons. Where the sensors
// see the body the points outvote the skeleton: the body job started from
// several poses stays near the truth, the one that follows the skeleton
// alone does not. A motion (CMU 131_03, a hop) and shape (random:41) the
// fit was not tuned on.
TEST(RunBody, APerturbedTrackerIsOutvotedByThePoints) {
  const std::string dir = reenact::testing::MakeTempDir("body_perturbed");
  const std::string clip = reenact::testing::TestDataPath("mocap/cmu/131_03.bvh");
  if (!std::filesystem::exists(clip)) GTEST_SKIP() << "no CMU clip at " << clip;
  synth::SynthOptions options = TwoSensorTake(clip, "random:41");
  options.skeleton_errors.limb_noise_m = 0.08;
  options.skeleton_errors.arm_swap_fraction = 0.1;
  options.skeleton_errors.leg_drop_s = 0.5;
  const std::string take_path = dir + "/take.mcap";
  const absl::StatusOr<Truth> synthesised = SynthesiseWithTruth(options, take_path);
  if (synthesised.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << synthesised.status();
  }
  ASSERT_TRUE(synthesised.ok()) << synthesised.status();
  const Truth& truth = *synthesised;

  const BodyRun alone =
      RunBodyJob(take_path, dir + "/alone.reen", {{"hypotheses", "false"}}, truth);
  const BodyRun voting =
      RunBodyJob(take_path, dir + "/voting.reen", {{"hypotheses", "true"}}, truth);
  std::printf(
      "body on a perturbed tracker (80 mm limb noise, arms swapped in 10%% of frames, a leg lost "
      "for 0.5 s; CMU 131_03, random:41): MPJPE %.1f mm following the skeleton, %.1f mm with "
      "hypotheses (%.0f%% of points explained, %.0f frames from the arms swapped, %.0f from the "
      "previous fit, %.0f unexplained); fit %.1f ms per frame (%.1f without)\n",
      alone.MeanErrorMm(), voting.MeanErrorMm(), 100.0 * voting.figures.at("explained_fraction"),
      voting.figures.at("hypothesis_arms_swapped"), voting.figures.at("hypothesis_previous"),
      voting.figures.at("unexplained_frames"), voting.figures.at("fit_ms_per_frame"),
      alone.figures.at("fit_ms_per_frame"));
  EXPECT_LE(voting.MeanErrorMm(), 30.0);
  EXPECT_LT(voting.MeanErrorMm(), alone.MeanErrorMm());
  EXPECT_GT(voting.figures.at("explained_fraction"), 0.9);
}

// A tracker that finds the body only after a second (no joint tracked
// before): the forward pass has nothing to start from there, so those
// frames get the first fit's pose, marked invalid. The look-ahead fits them
// backwards from the frames after them, where the points hold the body.
TEST(RunBody, TheLookAheadFitsTheFramesBeforeTheTrackerFoundTheBody) {
  const std::string dir = reenact::testing::MakeTempDir("body_look_ahead");
  const std::string clip = reenact::testing::TestDataPath("mocap/cmu/131_03.bvh");
  if (!std::filesystem::exists(clip)) GTEST_SKIP() << "no CMU clip at " << clip;
  synth::SynthOptions options = TwoSensorTake(clip, "random:29");
  options.skeleton_errors.lock_on_s = 1.0;
  const std::string take_path = dir + "/take.mcap";
  const absl::StatusOr<Truth> synthesised = SynthesiseWithTruth(options, take_path);
  if (synthesised.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << synthesised.status();
  }
  ASSERT_TRUE(synthesised.ok()) << synthesised.status();
  const Truth& truth = *synthesised;
  const int lock_on_frames = static_cast<int>(options.fps * options.skeleton_errors.lock_on_s);

  const BodyRun causal =
      RunBodyJob(take_path, dir + "/causal.reen", {{"look_ahead", "false"}}, truth);
  const BodyRun ahead = RunBodyJob(take_path, dir + "/ahead.reen", {{"look_ahead", "true"}}, truth);
  const auto early = [&](const v1::PartFrame& frame) {
    return frame.frame_index() < lock_on_frames;
  };
  const auto valid_early = [&](const BodyRun& run) {
    return std::count_if(run.frames.begin(), run.frames.end(), [&](const v1::PartFrame& frame) {
      return early(frame) && frame.body().valid();
    });
  };
  std::printf(
      "body with a tracker that finds the body after %.1f s (CMU 131_03, random:29, %d frames "
      "before): %d of them fitted and MPJPE %.1f mm over them forward only, %d and %.1f mm with "
      "the look-ahead; whole take %.1f mm and %.1f mm\n",
      options.skeleton_errors.lock_on_s, lock_on_frames, static_cast<int>(valid_early(causal)),
      causal.MeanErrorMm(early), static_cast<int>(valid_early(ahead)), ahead.MeanErrorMm(early),
      causal.MeanErrorMm(), ahead.MeanErrorMm());
  EXPECT_EQ(valid_early(causal), 0);
  EXPECT_GE(valid_early(ahead), lock_on_frames - 1);
  EXPECT_LE(ahead.MeanErrorMm(early), 30.0);
  EXPECT_LT(ahead.MeanErrorMm(), causal.MeanErrorMm());
}

// The lowest per-frame figure of any sensor over the frames of `run`.
struct SensorFitRange {
  double explained = 1.0;
  double seen = 1.0;
  int frames_with_both = 0;  // Frames with a fit of each of two sensors.
};
SensorFitRange LowestSensorFits(const BodyRun& run) {
  SensorFitRange out;
  for (const v1::PartFrame& frame : run.frames) {
    if (!frame.body().valid()) continue;
    out.frames_with_both += frame.body().sensor_fits_size() == 2 ? 1 : 0;
    for (const v1::SensorFit& fit : frame.body().sensor_fits()) {
      out.explained = std::min<double>(out.explained, fit.explained_fraction());
      out.seen = std::min<double>(out.seen, fit.surface_seen_fraction());
    }
  }
  return out;
}

// Every fitted frame says how well it explains each sensor's view. Where
// the sensors agree with the fit no frame is doubtful; when the last
// sensor's calibration is 20 cm off (a rig knocked after calibration), its
// points lie beside the body the other sensor sees: the job still
// finishes, and the frames that sensor contradicts are marked, with the
// sensor named.
TEST(RunBody, EachFrameSaysHowWellItExplainsEachSensorAndAKnockedSensorIsNamed) {
  const std::string dir = reenact::testing::MakeTempDir("body_diagnosis");
  const std::string clip = reenact::testing::TestDataPath("mocap/cmu/131_03.bvh");
  if (!std::filesystem::exists(clip)) GTEST_SKIP() << "no CMU clip at " << clip;
  synth::SynthOptions options = TwoSensorTake(clip, "random:17");
  options.seconds = 1.4;
  const absl::StatusOr<Truth> synthesised = SynthesiseWithTruth(options, dir + "/take.mcap");
  if (synthesised.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << synthesised.status();
  }
  ASSERT_TRUE(synthesised.ok()) << synthesised.status();
  options.calibration_error_m = 0.2;
  const absl::StatusOr<Truth> knocked_truth = SynthesiseWithTruth(options, dir + "/knocked.mcap");
  ASSERT_TRUE(knocked_truth.ok()) << knocked_truth.status();

  const BodyRun clean = RunBodyJob(dir + "/take.mcap", dir + "/clean.reen", {}, *synthesised);
  const BodyRun knocked =
      RunBodyJob(dir + "/knocked.mcap", dir + "/knocked.reen", {}, *knocked_truth);
  const SensorFitRange c = LowestSensorFits(clean);
  const SensorFitRange k = LowestSensorFits(knocked);
  std::printf(
      "body fit diagnosis (CMU 131_03, random:17, %zu frames): sensors agree: lowest explained "
      "%.1f %%, lowest surface seen %.1f %%, %g doubtful frames, MPJPE %.1f mm; last sensor "
      "20 cm off: lowest explained %.1f %%, surface seen %.1f %%, %g doubtful frames in %d "
      "spans, MPJPE %.1f mm\n",
      clean.frames.size(), 100.0 * c.explained, 100.0 * c.seen, clean.figures.at("doubtful_frames"),
      clean.MeanErrorMm(), 100.0 * k.explained, 100.0 * k.seen,
      knocked.figures.at("doubtful_frames"), knocked.info.doubtful_spans_size(),
      knocked.MeanErrorMm());
  for (const v1::DoubtfulSpan& span : knocked.info.doubtful_spans()) {
    std::printf("  doubtful %.2f-%.2f s (frames %d-%d): %s\n", span.start_s(), span.end_s(),
                span.first_frame(), span.last_frame(), span.reason().c_str());
  }
  ASSERT_FALSE(clean.frames.empty());
  EXPECT_EQ(c.frames_with_both, static_cast<int>(clean.frames.size()));
  EXPECT_GE(c.explained, 0.85);
  EXPECT_GE(c.seen, 0.7);
  EXPECT_EQ(clean.figures.at("doubtful_frames"), 0);
  EXPECT_EQ(clean.info.doubtful_spans_size(), 0);
  EXPECT_GT(clean.figures.at("sensor.k0.explained_fraction"), 0.9);

  ASSERT_FALSE(knocked.frames.empty());
  EXPECT_GE(knocked.figures.at("doubtful_frames"),
            0.5 * static_cast<double>(knocked.frames.size()));
  ASSERT_GT(knocked.info.doubtful_spans_size(), 0);
  EXPECT_NE(knocked.info.doubtful_spans(0).reason().find("sensor k"), std::string::npos)
      << knocked.info.doubtful_spans(0).reason();
  EXPECT_LT(std::min(knocked.figures.at("sensor.k0.explained_fraction"),
                     knocked.figures.at("sensor.k1.explained_fraction")),
            0.9);
}

TEST(RunBody, BadOptionsAreRejectedBeforeLoading) {
  MethodInput input;
  input.take_path = "/nonexistent/take.mcap";
  input.method = "body";
  input.options = {{"model", "smpl"}};
  EXPECT_EQ(RunMethod(input, "/tmp/never.reen").status().code(),
            absl::StatusCode::kInvalidArgument);
  input.options = {{"visibility_m", "-1"}};
  EXPECT_EQ(RunMethod(input, "/tmp/never.reen").status().code(),
            absl::StatusCode::kInvalidArgument);
  input.options = {{"look_ahead", "maybe"}};
  EXPECT_EQ(RunMethod(input, "/tmp/never.reen").status().code(),
            absl::StatusCode::kInvalidArgument);
  input.options = {{"no_such_option", "1"}};
  EXPECT_EQ(RunMethod(input, "/tmp/never.reen").status().code(),
            absl::StatusCode::kInvalidArgument);
  // A path is never a model: only asset names under the server's roots.
  for (const char* model : {"makehuman:/etc", "makehuman:../..", "makehuman:a/b", "makehuman:.x"}) {
    input.options = {{"model", model}};
    EXPECT_EQ(RunMethod(input, "/tmp/never.reen").status().code(),
              absl::StatusCode::kInvalidArgument)
        << model;
  }
}

}  // namespace
}  // namespace reenact::recon
