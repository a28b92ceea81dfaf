// One take split across workers (PrepareBody, FitBodySegment, StitchBody)
// against the same take run whole (RunBody), on a synthetic take whose
// motion and shape the method was not tuned on: the segmented result must
// equal the whole one within 1 mm of joints and surface, and its atlas
// within 0.2 dB of the whole one's against the truth (here: the whole
// atlas itself, so the PSNR between the two bounds any difference).
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/io/take_selection.h"
#include "common/testing/test_data.h"
#include "reenact/v1/segments.pb.h"
#include "server/recon/body/body_method.h"
#include "server/recon/take_frames.h"
#include "server/recon/testing/selected_take.h"
#include "server/recon/testing/suite_take.h"

namespace reenact::recon {
namespace {

class BodySegments : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    suite_ = new testing::SuiteTake(testing::MakeSuiteTake("body_segments", "131_03.bvh",
                                                           "random:11", 4.0,
                                                           /*truth_meshes=*/false));
    path_ = &suite_->path;
    take_ = suite_->take.get();
  }
  static void TearDownTestSuite() {
    delete suite_;
    suite_ = nullptr;
    take_ = nullptr;
  }

  void SetUp() override { RECON_REQUIRE_SUITE_TAKE(*suite_); }

  static BodyMethodOptions Options() {
    BodyMethodOptions o;
    o.atlas.size_px = 256;
    return o;
  }

  static inline testing::SuiteTake* suite_ = nullptr;
  static inline const std::string* path_ = nullptr;
  static inline const TakeFrames* take_ = nullptr;
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

// The take with the image bytes of only what `needs` names, loaded.
std::unique_ptr<TakeFrames> Selected(const std::string& path, const TakeFrames& take,
                                     const TakeNeeds& needs, const std::string& out) {
  auto loaded = testing::SelectedTake(path, take, needs, out);
  EXPECT_TRUE(loaded.ok()) << loaded.status();
  return loaded.ok() ? std::move(*loaded) : nullptr;
}

TEST_F(BodySegments, EachPhaseOnlyDecodesTheFramesItNames) {
  const BodyMethodOptions options = Options();
  const std::string dir = reenact::testing::MakeTempDir("body_segments_needs");
  constexpr int kCount = 2;
  const int n = take_->num_instants();

  // Prepare: the depth near the shape's targets, no colour.
  auto prepare_needs = BodyNeeds(*take_, options, MethodPhase::kPrepare, 0, kCount);
  ASSERT_TRUE(prepare_needs.ok()) << prepare_needs.status();
  EXPECT_TRUE(prepare_needs->color.empty());
  EXPECT_LT(prepare_needs->depth.size(), static_cast<size_t>(n));
  auto prepare_take = Selected(*path_, *take_, *prepare_needs, dir + "/prepare.mcap");
  ASSERT_NE(prepare_take, nullptr);
  ASSERT_EQ(prepare_take->num_instants(), n) << "the same instants";
  auto whole_prepared = PrepareBody(*take_, options);
  auto prepared = PrepareBody(*prepare_take, options);
  ASSERT_TRUE(whole_prepared.ok() && prepared.ok()) << prepared.status();
  v1::BodyShapePart a, b;
  ASSERT_TRUE(a.ParseFromString(*whole_prepared) && b.ParseFromString(*prepared));
  EXPECT_EQ(std::vector<int>(a.shape_instants().begin(), a.shape_instants().end()),
            std::vector<int>(b.shape_instants().begin(), b.shape_instants().end()));
  ASSERT_EQ(a.shape_size(), b.shape_size());
  for (int k = 0; k < a.shape_size(); ++k) EXPECT_EQ(a.shape(k), b.shape(k)) << k;

  // Each segment: its frames' depth from the warm-up on, the atlas's colour.
  std::vector<std::string> segments;
  for (int k = 0; k < kCount; ++k) {
    auto needs = BodyNeeds(*take_, options, MethodPhase::kSegment, k, kCount);
    ASSERT_TRUE(needs.ok()) << needs.status();
    EXPECT_LT(needs->depth.size(), static_cast<size_t>(n));
    EXPECT_LE(needs->color.size(), needs->depth.size() / 2 + 1) << "every other instant's colour";
    auto segment_take =
        Selected(*path_, *take_, *needs, absl::StrCat(dir, "/segment-", k, ".mcap"));
    ASSERT_NE(segment_take, nullptr);
    auto whole_segment = FitBodySegment(*take_, options, {}, *prepared, k, kCount);
    auto segment = FitBodySegment(*segment_take, options, {}, *prepared, k, kCount);
    ASSERT_TRUE(whole_segment.ok() && segment.ok()) << segment.status();
    v1::BodySegmentPart x, y;
    ASSERT_TRUE(x.ParseFromString(*whole_segment) && y.ParseFromString(*segment));
    ASSERT_EQ(x.frames_size(), y.frames_size());
    for (int f = 0; f < x.frames_size(); ++f) {
      EXPECT_EQ(x.frames(f).SerializeAsString(), y.frames(f).SerializeAsString()) << f;
    }
    EXPECT_EQ(x.atlas_views(), y.atlas_views()) << "the same colour images";
    segments.push_back(*std::move(segment));
  }

  // The stitch: no image at all.
  auto stitch_needs = BodyNeeds(*take_, options, MethodPhase::kStitch, 0, kCount);
  ASSERT_TRUE(stitch_needs.ok());
  EXPECT_TRUE(stitch_needs->depth.empty() && stitch_needs->color.empty());
  auto index = Selected(*path_, *take_, *stitch_needs, dir + "/index.mcap");
  ASSERT_NE(index, nullptr);
  auto stitched = StitchBody(*index, options, {}, *prepared, segments);
  auto whole_stitched = StitchBody(*take_, options, {}, *prepared, segments);
  ASSERT_TRUE(stitched.ok() && whole_stitched.ok()) << stitched.status();
  EXPECT_EQ(stitched->body->atlas_jpeg, whole_stitched->body->atlas_jpeg);
  ASSERT_EQ(stitched->frames.size(), whole_stitched->frames.size());
  for (size_t i = 0; i < stitched->frames.size(); ++i) {
    EXPECT_EQ(stitched->frames[i].stamp_ns, whole_stitched->frames[i].stamp_ns);
  }
  std::printf(
      "body, %d instants in %d segments: prepare decodes the depth of %zu instants, the "
      "segments depth of %zu and %zu and colour of %zu and %zu, the stitch none; every phase's "
      "result equals its result on the whole take\n",
      n, kCount, prepare_needs->depth.size(),
      BodyNeeds(*take_, options, MethodPhase::kSegment, 0, kCount)->depth.size(),
      BodyNeeds(*take_, options, MethodPhase::kSegment, 1, kCount)->depth.size(),
      BodyNeeds(*take_, options, MethodPhase::kSegment, 0, kCount)->color.size(),
      BodyNeeds(*take_, options, MethodPhase::kSegment, 1, kCount)->color.size());
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
