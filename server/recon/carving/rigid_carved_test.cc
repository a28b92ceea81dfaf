#include "server/recon/carving/rigid_carved.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/reenactment_file.h"
#include "server/recon/body_parts.h"
#include "server/recon/carving/carving_eval.h"
#include "server/recon/methods.h"
#include "server/recon/testing/short_take.h"

namespace reenact::recon {
namespace {

using recon::testing::GetSharedTake;

// The shared synthetic take (arm raise, 2 sensors, 1.5 s at 15 fps, 640x360
// colour), loaded once.
const TakeFrames& SharedFrames() {
  static const TakeFrames* frames = [] {
    auto loaded = TakeFrames::Load(GetSharedTake().path);
    EXPECT_TRUE(loaded.ok()) << loaded.status();
    return loaded.ok() ? loaded->release() : nullptr;
  }();
  return *frames;
}

const carving::testing::Truth& SharedTruth() {
  static const carving::testing::Truth* truth = [] {
    auto read = carving::testing::ReadTruth(GetSharedTake().path);
    EXPECT_TRUE(read.ok()) << read.status();
    return new carving::testing::Truth(read.ok() ? std::move(*read) : carving::testing::Truth());
  }();
  return *truth;
}

// The method's options without baked textures (the tests measure shape).
RigidCarvedOptions NoBake() {
  RigidCarvedOptions options;
  options.texturing.bake = false;
  return options;
}

// Measured on the shared take (2026-11, this machine): carved vertices lie
// 3.9 mm from the true surface on average (90 % within 8.4 mm), the true
// surface 8.2 mm from the carved one, and the registered part frames 10.8 mm
// from the true joints where the fused sensor skeleton is 12.1 mm off. The
// bounds leave margin for other noise seeds and platforms.
TEST(RunRigidCarved, CarvedPartsLieOnTheTrueSurface) {
  RECON_REQUIRE_SHARED_TAKE();
  std::vector<std::string> stages;
  MethodContext context;
  context.progress = [&](const Progress& p) {
    if (stages.empty() || stages.back() != p.stage) stages.push_back(p.stage);
    return true;
  };
  auto data = RunRigidCarved(SharedFrames(), NoBake(), context);
  ASSERT_TRUE(data.ok()) << data.status();
  EXPECT_EQ(stages, (std::vector<std::string>{"register", "fuse", "mesh", "texture"}));

  auto accuracy = carving::testing::Evaluate(*data, SharedTruth(), 3);
  ASSERT_TRUE(accuracy.ok()) << accuracy.status();
  RecordProperty("mean_um", static_cast<int>(1e3 * accuracy->mean_mm));
  RecordProperty("p90_um", static_cast<int>(1e3 * accuracy->p90_mm));
  RecordProperty("truth_to_carved_um", static_cast<int>(1e3 * accuracy->truth_to_carved_mm));
  RecordProperty("joint_error_um", static_cast<int>(1e3 * accuracy->joint_error_mm));
  RecordProperty("skeleton_joint_error_um",
                 static_cast<int>(1e3 * accuracy->skeleton_joint_error_mm));
  EXPECT_GE(accuracy->frames, 5);
  EXPECT_LT(accuracy->mean_mm, 6.0) << "mean distance of carved vertices to the true surface";
  EXPECT_LT(accuracy->p90_mm, 13.0);
  EXPECT_LT(accuracy->truth_to_carved_mm, 12.0) << "the carved parts miss part of the body";
  for (int p = 0; p < kNumBodyParts; ++p) {
    EXPECT_LT(accuracy->part_mean_mm[p], 20.0) << BodyParts()[p].name;
  }
  // Registration must not drift away from the skeleton it starts from.
  EXPECT_LT(accuracy->joint_error_mm, accuracy->skeleton_joint_error_mm + 1.0);

  const auto& figures = data->info.figures;
  for (const char* figure : {"registration_rms_mm", "mean_iterations", "voxels", "triangles",
                             "carve_instants_per_second", "keyframes"}) {
    EXPECT_TRUE(figures.contains(figure)) << figure;
  }
  EXPECT_GT(figures.at("mean_iterations"), 1.0);
  EXPECT_LT(figures.at("registration_rms_mm"), 10.0);
  EXPECT_EQ(figures.at("parts_fallback"), 0.0);
  EXPECT_EQ(figures.at("part_restarts"), 0.0) << "a slow arm raise needs no restart";
  RecordProperty("carve_instants_per_second",
                 static_cast<int>(figures.at("carve_instants_per_second")));
  ASSERT_EQ(data->parts.size(), static_cast<size_t>(kNumBodyParts));
  for (int p = 0; p < kNumBodyParts; ++p) {
    EXPECT_EQ(data->parts[p].part, p);
    EXPECT_EQ(data->parts[p].radius_rate, 0.0f);
    EXPECT_GT(data->parts[p].reference_length_m, 0.05f);
  }
  ASSERT_EQ(data->frames.size(), static_cast<size_t>(SharedFrames().num_instants()));
  for (const ReenactmentFrame& frame : data->frames) {
    ASSERT_EQ(frame.parts.size(), static_cast<size_t>(kNumBodyParts));
    for (const reenact::PartPose& pose : frame.parts) {
      EXPECT_TRUE(pose.valid);
      EXPECT_EQ(pose.scale, 1.0);
    }
  }
}

// With the two facing sensors the sides of limbs are seen edge-on; where
// the background returns no depth (the synthetic take has no walls), only
// the actor mask says those rays are empty. Carving them as free space
// (carve_no_return, the default) closes the sides: the true surface must lie
// nearer to the carved one than without it. Measured (2026-11, this
// machine): 6.37 mm with, 7.11 mm without.
TEST(RunRigidCarved, NoReturnRaysOffTheActorCloseLimbSides) {
  RECON_REQUIRE_SHARED_TAKE();
  RigidCarvedOptions no_return = NoBake();
  no_return.carve_no_return = false;
  auto with = RunRigidCarved(SharedFrames(), NoBake());
  auto without = RunRigidCarved(SharedFrames(), no_return);
  ASSERT_TRUE(with.ok()) << with.status();
  ASSERT_TRUE(without.ok()) << without.status();
  auto closed = carving::testing::Evaluate(*with, SharedTruth(), 3);
  auto open = carving::testing::Evaluate(*without, SharedTruth(), 3);
  ASSERT_TRUE(closed.ok() && open.ok());
  RecordProperty("truth_to_carved_um", static_cast<int>(1e3 * closed->truth_to_carved_mm));
  RecordProperty("truth_to_carved_without_um", static_cast<int>(1e3 * open->truth_to_carved_mm));
  std::printf("truth to carved: %.2f mm with no-return carving, %.2f mm without\n",
              closed->truth_to_carved_mm, open->truth_to_carved_mm);
  EXPECT_LT(closed->truth_to_carved_mm, open->truth_to_carved_mm - 0.3);
  EXPECT_LT(closed->mean_mm, 6.0);
}

// The thesis' skeleton weight (w_s = half the voxels of V_b) lets the noisy
// tracker skeleton dictate the poses, which blurs the fused shapes: the
// tuned default must do better (this is what fixed the default).
TEST(RunRigidCarved, TunedSkeletonWeightBeatsTheThesisWeight) {
  RECON_REQUIRE_SHARED_TAKE();
  RigidCarvedOptions tuned_options = NoBake();
  tuned_options.texturing.keyframe_stride = 1000;
  RigidCarvedOptions thesis_options = tuned_options;
  thesis_options.w_s_per_voxel = 0.5;
  auto tuned = RunRigidCarved(SharedFrames(), tuned_options);
  auto thesis = RunRigidCarved(SharedFrames(), thesis_options);
  ASSERT_TRUE(tuned.ok()) << tuned.status();
  ASSERT_TRUE(thesis.ok()) << thesis.status();
  auto tuned_accuracy = carving::testing::Evaluate(*tuned, SharedTruth(), 3);
  auto thesis_accuracy = carving::testing::Evaluate(*thesis, SharedTruth(), 3);
  ASSERT_TRUE(tuned_accuracy.ok() && thesis_accuracy.ok());
  RecordProperty("thesis_mean_um", static_cast<int>(1e3 * thesis_accuracy->mean_mm));
  EXPECT_LT(tuned_accuracy->mean_mm, thesis_accuracy->mean_mm - 1.0);
}

// A part whose registered joints leave the skeleton's by more than
// max_drift_mm restarts from the skeleton's pose. With a bound below the
// registration's own scatter every part restarts at every instant, so the
// part frames are the skeleton's: their joint error is the skeleton's (within
// 2 mm: a part frame puts its distal joint at the part's reference length,
// not at the skeleton's bone end; measured 13.5 vs 12.1 mm).
TEST(RunRigidCarved, APartThatDriftsFromTheSkeletonRestartsFromIt) {
  RECON_REQUIRE_SHARED_TAKE();
  RigidCarvedOptions strict = NoBake();
  strict.texturing.keyframe_stride = 1000;
  strict.max_drift_mm = 0.01;
  auto data = RunRigidCarved(SharedFrames(), strict);
  ASSERT_TRUE(data.ok()) << data.status();
  const double registrations = data->info.figures.at("registrations");
  const double restarts = data->info.figures.at("part_restarts");
  std::printf("max_drift_mm 0.01: %.0f restarts, %.0f registrations kept\n", restarts,
              registrations);
  EXPECT_GT(restarts, 10.0 * std::max(1.0, registrations));
  auto accuracy = carving::testing::Evaluate(*data, SharedTruth(), 3);
  ASSERT_TRUE(accuracy.ok()) << accuracy.status();
  EXPECT_NEAR(accuracy->joint_error_mm, accuracy->skeleton_joint_error_mm, 2.0);
}

TEST(RunRigidCarved, RejectsUnknownAndMalformedOptions) {
  RECON_REQUIRE_SHARED_TAKE();
  for (const auto& options :
       std::vector<std::map<std::string, std::string>>{{{"no_such_option", "1"}},
                                                       {{"voxel_mm", "0"}},
                                                       {{"voxel_mm", "abc"}},
                                                       {{"mu_mm", "5"}, {"voxel_mm", "8"}},
                                                       {{"use_flow", "perhaps"}},
                                                       {{"color_scale", "3"}}}) {
    // Through the registry, as a job's options arrive.
    auto result = RigidCarvedMethod().Run(SharedFrames(), options, {});
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument)
        << options.begin()->first << ": " << result.status();
  }
  // Typed options that fail Validate() are refused the same way.
  RigidCarvedOptions thin;
  thin.voxel_mm = 8.0;
  thin.mu_mm = 5.0;
  EXPECT_EQ(RunRigidCarved(SharedFrames(), thin).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(RunRigidCarved, CancelsFromProgress) {
  RECON_REQUIRE_SHARED_TAKE();
  MethodContext context;
  context.progress = [](const Progress& p) { return p.stage != "fuse"; };
  auto result = RunRigidCarved(SharedFrames(), {}, context);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kCancelled) << result.status();
}

TEST(RunMethod, RigidCarvedWritesAValidReenactment) {
  RECON_REQUIRE_SHARED_TAKE();
  MethodInput input;
  input.take_path = GetSharedTake().path;
  input.method = "rigid-carved";
  input.reenactment_id = "r-carved";
  input.take_id = "t-carved";
  input.job_id = "j-carved";
  input.options = {{"keyframe_stride", "3"}, {"mu_mm", "24"}};
  const std::string out = reenact::testing::MakeTempDir("carved_run") + "/r.reen";
  auto result = RunMethod(input, out);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->frames, GetSharedTake().summary.frames);
  EXPECT_GT(result->keyframes, 0);
  auto data = ReadReenactmentFile(out);
  ASSERT_TRUE(data.ok()) << data.status();
  EXPECT_EQ(data->info.method(), "rigid-carved");
  EXPECT_EQ(data->info.options().at("mu_mm"), "24");
  EXPECT_TRUE(data->info.figures().contains("registration_rms_mm"));
  ASSERT_EQ(data->parts.size(), static_cast<size_t>(kNumBodyParts));
  for (const v1::PartMesh& part : data->parts) {
    EXPECT_FALSE(part.baked_texture_jpeg().empty()) << part.name();
    EXPECT_GT(part.triangle_indices_size(), 30) << part.name();
  }
}

}  // namespace
}  // namespace reenact::recon
