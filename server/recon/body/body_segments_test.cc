// One take split across workers (PrepareBody, FitBodySegment, StitchBody)
// against the same take run whole (RunBody), on a synthetic take whose
// motion and shape the method was not tuned on: the segmented result must
// equal the whole one within 1 mm of joints and surface, and its atlas
// within 0.2 dB of the whole one's against the truth (here: the whole
// atlas itself, so the PSNR between the two bounds any difference).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "reenact/v1/segments.pb.h"
#include "server/recon/body/body_method.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {
namespace {

class BodySegments : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const std::string clip = reenact::testing::TestDataPath("mocap/cmu/131_03.bvh");
    if (!std::filesystem::exists(clip)) return;
    const std::string dir = reenact::testing::MakeTempDir("body_segments");
    synth::SynthOptions options;
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
    options.motion = clip;
    options.body = "procedural";
    options.shape = "random:11";
    options.num_sensors = 2;
    options.seconds = 4.0;
    options.fps = 15.0;
    options.color_width = 640;
    options.color_height = 360;
    path_ = new std::string(dir + "/take.mcap");
    auto summary = synth::SynthesizeTake(options, *path_);
    if (!summary.ok()) {
      status_ = new absl::Status(summary.status());
      return;
    }
    auto take = TakeFrames::Load(*path_);
    if (!take.ok()) {
      status_ = new absl::Status(take.status());
      return;
    }
    take_ = take->release();
  }
  static void TearDownTestSuite() {
    delete take_;
    take_ = nullptr;
  }

  void SetUp() override {
    if (path_ == nullptr) GTEST_SKIP() << "no CMU clip 131_03 under the test data";
    if (status_ != nullptr && status_->code() == absl::StatusCode::kUnavailable) {
      GTEST_SKIP() << *status_;
    }
    ASSERT_EQ(status_, nullptr) << *status_;
  }

  static BodyMethodOptions Options() {
    BodyMethodOptions o;
    o.atlas.size_px = 256;
    return o;
  }

  static inline std::string* path_ = nullptr;
  static inline absl::Status* status_ = nullptr;
  static inline TakeFrames* take_ = nullptr;
};

// PSNR of two RGB images of the same size, dB.
double PsnrDb(const RgbImage& a, const RgbImage& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    const double d = static_cast<double>(a.data[i]) - b.data[i];
    sum += d * d;
  }
  const double mse = sum / static_cast<double>(a.data.size());
  return mse == 0.0 ? INFINITY : 10.0 * std::log10(255.0 * 255.0 / mse);
}

TEST_F(BodySegments, ThreeSegmentsEqualTheWholeRun) {
  const BodyMethodOptions options = Options();
  auto whole = RunBody(*take_, options);
  ASSERT_TRUE(whole.ok()) << whole.status();
  auto prepared = PrepareBody(*take_, options);
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  constexpr int kCount = 3;
  std::vector<std::string> segments;
  for (int k = 0; k < kCount; ++k) {
    auto segment = FitBodySegment(*take_, options, {}, *prepared, k, kCount);
    ASSERT_TRUE(segment.ok()) << segment.status();
    segments.push_back(std::move(*segment));
  }
  auto stitched = StitchBody(*take_, options, {}, *prepared, segments);
  ASSERT_TRUE(stitched.ok()) << stitched.status();

  // The same shape: the prepared one is the whole run's.
  ASSERT_TRUE(whole->is_body());
  ASSERT_TRUE(stitched->is_body());
  ASSERT_EQ(whole->body->shape.size(), stitched->body->shape.size());
  for (size_t k = 0; k < whole->body->shape.size(); ++k) {
    EXPECT_NEAR(whole->body->shape[k], stitched->body->shape[k], 1e-9) << k;
  }

  // Joints and posed vertices, frame by frame.
  ASSERT_EQ(whole->frames.size(), stitched->frames.size());
  const BodyMesh* mesh = &*whole->body;
  double joint_sum_mm = 0.0, vertex_sum_mm = 0.0, joint_max_mm = 0.0;
  int joints = 0, frames = 0;
  for (size_t i = 0; i < whole->frames.size(); ++i) {
    const ReenactmentFrame& a = whole->frames[i];
    const ReenactmentFrame& b = stitched->frames[i];
    ASSERT_EQ(a.frame_index, b.frame_index);
    EXPECT_EQ(a.stamp_ns, b.stamp_ns);
    ASSERT_TRUE(a.body && b.body);
    EXPECT_EQ(a.body->valid, b.body->valid) << i;
    ASSERT_EQ(a.joints_in_world_m.size(), b.joints_in_world_m.size());
    for (size_t j = 0; j < a.joints_in_world_m.size(); ++j) {
      const double d = 1000.0 * (a.joints_in_world_m[j] - b.joints_in_world_m[j]).norm();
      joint_sum_mm += d;
      joint_max_mm = std::max(joint_max_mm, d);
      ++joints;
    }
    auto pa = PoseBodyMesh(*mesh, *a.body);
    auto pb = PoseBodyMesh(*mesh, *b.body);
    ASSERT_TRUE(pa.ok() && pb.ok());
    vertex_sum_mm += 1000.0 * (pa->vertices_m - pb->vertices_m).colwise().norm().mean();
    ++frames;
  }
  const double joint_mm = joint_sum_mm / std::max(1, joints);
  const double vertex_mm = vertex_sum_mm / std::max(1, frames);

  // The atlases.
  auto atlas_whole = DecodeJpeg(whole->body->atlas_jpeg);
  auto atlas_stitched = DecodeJpeg(stitched->body->atlas_jpeg);
  ASSERT_TRUE(atlas_whole.ok() && atlas_stitched.ok());
  ASSERT_EQ(atlas_whole->width, atlas_stitched->width);
  const double atlas_psnr = PsnrDb(*atlas_whole, *atlas_stitched);

  std::printf(
      "body, %d instants in %d segments (CMU 131_03, random shape): joints differ by %.3f mm "
      "on average (max %.3f mm), posed vertices by %.3f mm (tolerance 1 mm); the atlases agree "
      "to %.1f dB PSNR\n",
      take_->num_instants(), kCount, joint_mm, joint_max_mm, vertex_mm, atlas_psnr);
  EXPECT_LE(joint_mm, 1.0);
  EXPECT_LE(vertex_mm, 1.0);
  // Equal sums but for the order of float additions and the JPEG coding.
  EXPECT_GE(atlas_psnr, 40.0);
}

TEST_F(BodySegments, PartsThatDoNotFitAreRefused) {
  const BodyMethodOptions options = Options();
  auto prepared = PrepareBody(*take_, options);
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  // Segments that do not exist.
  EXPECT_EQ(FitBodySegment(*take_, options, {}, *prepared, 3, 3).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(FitBodySegment(*take_, options, {}, *prepared, -1, 3).status().code(),
            absl::StatusCode::kInvalidArgument);
  // A prepared file that does not parse, or of another model.
  EXPECT_EQ(FitBodySegment(*take_, options, {}, "\xff\xff\xff", 0, 2).status().code(),
            absl::StatusCode::kDataLoss);
  v1::BodyShapePart other;
  ASSERT_TRUE(other.ParseFromString(*prepared));
  other.set_model("makehuman:someone");
  EXPECT_EQ(FitBodySegment(*take_, options, {}, other.SerializeAsString(), 0, 2).status().code(),
            absl::StatusCode::kInvalidArgument);
  // Segments missing, out of order, or with a hostile atlas.
  auto first = FitBodySegment(*take_, options, {}, *prepared, 0, 2);
  auto second = FitBodySegment(*take_, options, {}, *prepared, 1, 2);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_EQ(StitchBody(*take_, options, {}, *prepared, {*first}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(StitchBody(*take_, options, {}, *prepared, {*second, *first}).status().code(),
            absl::StatusCode::kInvalidArgument);
  v1::BodySegmentPart hostile;
  ASSERT_TRUE(hostile.ParseFromString(*second));
  hostile.set_atlas_px(8000);  // Its sums are of 256 px: refused before allocating 1 GiB.
  EXPECT_EQ(StitchBody(*take_, options, {}, *prepared, {*first, hostile.SerializeAsString()})
                .status()
                .code(),
            absl::StatusCode::kDataLoss);
  auto stitched = StitchBody(*take_, options, {}, *prepared, {*first, *second});
  ASSERT_TRUE(stitched.ok()) << stitched.status();
  EXPECT_EQ(static_cast<int>(stitched->frames.size()), take_->num_instants());
}

}  // namespace
}  // namespace reenact::recon
