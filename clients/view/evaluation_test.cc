#include "clients/view/evaluation.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include <gtest/gtest.h>

#include "clients/view/truth_reenactment.h"
#include "common/base/status_macros.h"
#include "common/body/procedural_body.h"
#include "common/io/take_convert.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::view {
namespace {

// The take's ground truth for `data` (the meshes it needs), then the
// evaluation.
absl::StatusOr<EvaluationResult> EvaluateAgainstTake(const Reenactment& data,
                                                     const TakeReader& take,
                                                     const EvaluationOptions& options = {}) {
  ASSIGN_OR_RETURN(const GroundTruth truth,
                   ReadGroundTruth(take, EvaluationMeshFrames(data, options)));
  return EvaluateReenactment(data, truth, options);
}

struct SharedTake {
  std::unique_ptr<TakeReader> reader;
  body::BodyModel model;
  Reenactment truth;       // The hand-made reenactment from the ground truth.
  Reenactment body_truth;  // The same as a body-model reenactment.
};

// A short two-sensor synthetic take (an arm raise, 0.5 s at 30 fps, colour
// 640 x 360) and its truth reenactment, made once per test process.
const SharedTake& Take() {
  static const SharedTake* take = [] {
    auto* t = new SharedTake;
    synth::SynthOptions options;
    // The sensors carry the jittered true skeleton (a device SDK stand-in).
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = "builtin:arm-raise";
    options.num_sensors = 2;
    options.seconds = 0.5;
    options.color_width = 640;
    options.color_height = 360;
    const std::string path = reenact::testing::MakeTempDir("view_eval") + "/take.mcap";
    auto summary = synth::SynthesizeTake(options, path);
    if (!summary.ok()) {
      ADD_FAILURE() << summary.status();
      return t;
    }
    auto reader = TakeReader::Open(path);
    auto model = body::BuildProceduralBody();
    if (!reader.ok() || !model.ok()) {
      ADD_FAILURE() << reader.status() << " " << model.status();
      return t;
    }
    t->reader = std::move(*reader);
    t->model = std::move(*model);
    auto truth = testing::MakeTruthReenactment(*t->reader, t->model);
    if (!truth.ok()) {
      ADD_FAILURE() << truth.status();
      return t;
    }
    t->truth = std::move(*truth);
    auto body_truth = testing::MakeTruthBodyReenactment(*t->reader, t->model);
    if (!body_truth.ok()) {
      ADD_FAILURE() << body_truth.status();
      return t;
    }
    t->body_truth = std::move(*body_truth);
    return t;
  }();
  return *take;
}

void Print(const std::string& what, const EvaluationResult& r) {
  std::printf(
      "%s: surface %.2f mm (accuracy %.2f, completeness %.2f), PSNR90 %.2f dB over %lld px, "
      "IoU90 %.3f, MPJPE %.2f mm, %d frames\n",
      what.c_str(), r.surface_mm, r.surface_accuracy_mm, r.surface_completeness_mm, r.psnr_db_90,
      static_cast<long long>(r.psnr_pixels), r.iou_90, r.mpjpe_mm, r.frames_evaluated);
}

// All three surface figures below `mm`.
void ExpectSurfaceWithin(const EvaluationResult& r, double mm) {
  EXPECT_LT(r.surface_mm, mm);
  EXPECT_LT(r.surface_accuracy_mm, mm);
  EXPECT_LT(r.surface_completeness_mm, mm);
}

TEST(EvaluateReenactment, TruthReenactmentScoresWellAndAPerturbedOneWorse) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  ASSERT_FALSE(take.truth.frames.empty());
  EvaluationOptions options;
  options.every = 2;
  auto truth = EvaluateAgainstTake(take.truth, *take.reader, options);
  ASSERT_TRUE(truth.ok()) << truth.status();
  Print("truth reenactment", *truth);
  EXPECT_EQ(truth->frames_evaluated, 8);  // Instants 0, 2, ..., 14.
  // Rigid parts cut from the truth: exact at instant 0, off only where the
  // skinning blends joints.
  ExpectSurfaceWithin(*truth, 2.0);
  // The side view: both sensors (front, back) saw it at grazing angles.
  EXPECT_GT(truth->psnr_db_90, 19.0);
  EXPECT_GT(truth->iou_90, 0.97);
  EXPECT_LT(truth->mpjpe_mm, 1e-3);

  Reenactment perturbed = take.truth;
  testing::PerturbPoses(&perturbed, Eigen::Vector3d(0.03, 0.0, 0.02), 8.0);
  for (ReenactmentFrame& frame : perturbed.frames) {
    for (Eigen::Vector3d& joint : frame.joints_in_world_m) joint.x() += 0.03;
  }
  auto worse = EvaluateAgainstTake(perturbed, *take.reader, options);
  ASSERT_TRUE(worse.ok()) << worse.status();
  Print("perturbed (3.6 cm, 8 deg)", *worse);
  EXPECT_GT(worse->surface_mm, truth->surface_mm + 10.0);
  EXPECT_LT(worse->psnr_db_90, truth->psnr_db_90 - 1.0);
  EXPECT_LT(worse->iou_90, truth->iou_90 - 0.05);
  EXPECT_NEAR(worse->mpjpe_mm, 30.0, 1e-3);
}

// The body-model reenactment of the truth (the synthesizer's model, true
// shape and pose, offsets onto the true mesh) is the truth: its surface
// differs by float rounding only and its silhouette matches; moved by a few
// centimetres it scores worse.
TEST(EvaluateReenactment, TruthBodyReenactmentIsTheTruthAndAMovedOneIsNot) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  ASSERT_TRUE(take.body_truth.is_body());
  EvaluationOptions options;
  options.every = 2;
  auto truth = EvaluateAgainstTake(take.body_truth, *take.reader, options);
  ASSERT_TRUE(truth.ok()) << truth.status();
  Print("truth body reenactment", *truth);
  std::printf("truth body reenactment: surface %.6f mm, IoU90 %.5f\n", truth->surface_mm,
              truth->iou_90);
  EXPECT_EQ(truth->frames_evaluated, 8);
  EXPECT_EQ(truth->surface_frames, 8);
  // Offsets are float32 (about 1e-7 m of rounding); the same triangles
  // rasterise to the same silhouette.
  ExpectSurfaceWithin(*truth, 0.01);
  EXPECT_GT(truth->iou_90, 0.995);
  EXPECT_LT(truth->mpjpe_mm, 1e-3);
  EXPECT_EQ(truth->mpjpe_joints, 8 * 25);
  // The atlas is the truth's albedo drawn unlit; the truth is lit.
  EXPECT_GT(truth->psnr_pixels, 1000);

  Reenactment moved = take.body_truth;
  for (ReenactmentFrame& frame : moved.frames) {
    Eigen::Vector3d& t = frame.body->pose.root_translation_m;
    t.x() += 0.03;
    t.z() += 0.02;
  }
  auto worse = EvaluateAgainstTake(moved, *take.reader, options);
  ASSERT_TRUE(worse.ok()) << worse.status();
  Print("truth body reenactment moved by 3.6 cm", *worse);
  EXPECT_GT(worse->surface_mm, truth->surface_mm + 10.0);
  EXPECT_LT(worse->iou_90, truth->iou_90 - 0.05);
  EXPECT_LT(worse->mpjpe_mm, 1e-3);  // The frames' joints were left alone.
  // SSIM on the same pixels as PSNR: high for the truth, lower when moved.
  std::printf("SSIM90: truth body %.4f, moved %.4f\n", truth->ssim_90, worse->ssim_90);
  EXPECT_GT(truth->ssim_90, 0.8);
  EXPECT_LE(truth->ssim_90, 1.0);
  EXPECT_LT(worse->ssim_90, truth->ssim_90);
  EXPECT_EQ(truth->Figures().count("ssim_90"), 1u);
}

TEST(EvaluateReenactment, FromSensor0sOwnViewTheTruthReenactmentMatchesTheTruth) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  EvaluationOptions options;
  options.every = 7;
  options.surface = false;
  options.novel_angle_deg = 0.0;  // Sensor 0's colour camera, at its own size.
  options.novel_width = 640;
  options.novel_height = 360;
  options.image_dir = reenact::testing::MakeTempDir("view_eval_images");
  auto result = EvaluateAgainstTake(take.truth, *take.reader, options);
  ASSERT_TRUE(result.ok()) << result.status();
  Print("truth reenactment from sensor 0", *result);
  // What is left is the take's colour noise (2 levels), JPEG and the
  // silhouette's edge pixels.
  EXPECT_GT(result->psnr_db_90, 28.0);
  EXPECT_GT(result->iou_90, 0.97);
  for (const char* name : {"novel_00000.png", "novel_00007.png", "novel_00014.png"}) {
    EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(options.image_dir) / name)) << name;
  }
  // The same by Eq. 3.6 (rigid-cylinders): the pose-closest keyframe from
  // sensor 0's place is the instant's own image.
  Reenactment cylinders = take.truth;
  cylinders.info.method = "rigid-cylinders";
  options.image_dir.clear();
  auto by_pose = EvaluateAgainstTake(cylinders, *take.reader, options);
  ASSERT_TRUE(by_pose.ok()) << by_pose.status();
  Print("truth reenactment from sensor 0, Eq. 3.6", *by_pose);
  EXPECT_GT(by_pose->psnr_db_90, 28.0);
}

TEST(EvaluateReenactment, BakedFallbackAndOptions) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  EvaluationOptions options;
  options.every = 5;
  options.surface = false;
  options.novel_width = 320;
  options.novel_height = 180;
  options.mode = TextureMode::kBaked;  // No baked texture: flat grey, lit.
  auto result = EvaluateAgainstTake(take.truth, *take.reader, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->frames_evaluated, 3);
  EXPECT_TRUE(std::isnan(result->surface_mm));
  EXPECT_GT(result->iou_90, 0.9);  // The shape is the truth's whatever the texture.
  options.every = 0;
  EXPECT_EQ(EvaluateAgainstTake(take.truth, *take.reader, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(EvaluateReenactment, TakeWithoutGroundTruthIsFailedPrecondition) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const std::string path = reenact::testing::MakeTempDir("view_eval_nogt") + "/take.mcap";
  v1::TakeInfo info;
  info.set_name("plain");
  auto writer = TakeWriter::Open(path, info);
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE((*writer)->Close().ok());
  auto plain = TakeReader::Open(path);
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_EQ(EvaluateAgainstTake(take.truth, **plain).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

// A w x h image of a horizontal ramp with a vertical stripe pattern.
RgbImage Pattern(int w, int h) {
  RgbImage image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      image.at(x, y, 0) = static_cast<uint8_t>(4 * x);
      image.at(x, y, 1) = (x / 3) % 2 ? 200 : 40;
      image.at(x, y, 2) = static_cast<uint8_t>(3 * y);
    }
  }
  return image;
}

TEST(MaskedSsim, IsOneForEqualImagesAndIgnoresPixelsOutsideTheMask) {
  const int w = 48, h = 40;
  const RgbImage a = Pattern(w, h);
  std::vector<uint8_t> mask(w * h, 0);
  for (int y = 8; y < 32; ++y) {
    for (int x = 10; x < 40; ++x) mask[y * w + x] = 1;
  }
  RgbImage b = a;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!mask[y * w + x]) b.at(x, y, 1) = 255 - b.at(x, y, 1);  // Outside: no effect.
    }
  }
  const SsimSums same = MaskedSsim(a, b, mask);
  EXPECT_EQ(same.pixels, 24 * 30);
  EXPECT_NEAR(same.sum / same.pixels, 1.0, 1e-9);
  // Shifting the stripes by one pixel inside the mask lowers it.
  RgbImage shifted = a;
  for (int y = 0; y < h; ++y) {
    for (int x = 1; x < w; ++x) shifted.at(x, y, 1) = a.at(x - 1, y, 1);
  }
  const SsimSums worse = MaskedSsim(a, shifted, mask);
  EXPECT_LT(worse.sum / worse.pixels, 0.9);
  EXPECT_GT(worse.sum / worse.pixels, 0.0);
  // Sizes that differ give nothing.
  EXPECT_EQ(MaskedSsim(a, Pattern(w, h + 1), mask).pixels, 0);
}

TEST(PsnrDb, OfKnownErrors) {
  EXPECT_NEAR(PsnrDb(100.0 * 100, 100), 20.0 * std::log10(255.0 / 10.0), 1e-9);
  EXPECT_TRUE(std::isinf(PsnrDb(0.0, 10)));
  EXPECT_TRUE(std::isnan(PsnrDb(0.0, 0)));
}

}  // namespace
}  // namespace reenact::view
