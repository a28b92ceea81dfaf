// The rigid methods split across workers (rigid_texturing.h: the prepare
// phase makes the untextured reenactment, each segment its instants'
// keyframes, the stitch bakes) against the same take run whole, through the
// methods' own interface as the worker calls it, on a synthetic take whose
// motion (CMU 131_03, a hop) and body shape (random) the methods were not
// tuned on. Only texturing is split, so the stitched reenactment must be the
// whole one: the same meshes, poses, keyframes and baked textures, byte for
// byte, and so the same accuracy against the ground truth (the scale-out's
// tolerances, 1 mm of joints and surface and 0.2 dB, hold with nothing to
// spare). Also: every phase gives the same result on the take as a worker
// streams it for that phase (its TakeNeeds alone), and parts that do not
// belong together are refused.
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "common/io/reenactment_convert.h"
#include "common/testing/test_data.h"
#include "reenact/v1/segments.pb.h"
#include "server/recon/carving/carving_eval.h"
#include "server/recon/registry.h"
#include "server/recon/take_frames.h"
#include "server/recon/testing/selected_take.h"
#include "server/recon/testing/suite_take.h"

namespace reenact::recon {
namespace {

class RigidSegments : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    suite_ = new testing::SuiteTake(
        testing::MakeSuiteTake("rigid_segments", "131_03.bvh", "random:23", 2.4));
    path_ = &suite_->path;
    take_ = suite_->take.get();
  }
  static void TearDownTestSuite() {
    delete suite_;
    suite_ = nullptr;
    take_ = nullptr;
  }

  void SetUp() override {
    RECON_REQUIRE_SUITE_TAKE(*suite_);
    method_ = FindMethod(GetParam());
    ASSERT_NE(method_, nullptr) << GetParam();
    ASSERT_TRUE(method_->spec().segmentable) << GetParam();
  }
  // Small baked textures keep the test quick; everything else is the job's
  // default.
  static OptionMap Options() { return {{"texture_size_px", "128"}}; }

  // All three phases on `take`, in `count` segments.
  absl::StatusOr<Reenactment> RunSplit(const TakeFrames& take, int count) const {
    ASSIGN_OR_RETURN(const std::string prepared, method_->Prepare(take, Options(), {}));
    std::vector<std::string> segments;
    for (int k = 0; k < count; ++k) {
      ASSIGN_OR_RETURN(std::string segment,
                       method_->Segment(take, Options(), {}, prepared, k, count));
      segments.push_back(std::move(segment));
    }
    return method_->Stitch(take, Options(), {}, prepared, segments);
  }

  static inline testing::SuiteTake* suite_ = nullptr;
  static inline const std::string* path_ = nullptr;
  static inline const TakeFrames* take_ = nullptr;
  const ReconstructionMethod* method_ = nullptr;
};

// The reenactment's messages without the figures (timings differ).
std::string Serialized(const Reenactment& data) {
  Reenactment copy = data;
  copy.info.figures.clear();
  const ReenactmentData messages = ReenactmentToProto(copy);
  std::string bytes = messages.info.SerializeAsString();
  for (const auto& part : messages.parts) bytes += part.SerializeAsString();
  for (const auto& frame : messages.frames) bytes += frame.SerializeAsString();
  for (const auto& keyframe : messages.keyframes) bytes += keyframe.SerializeAsString();
  return bytes;
}

TEST_P(RigidSegments, ThreeSegmentsEqualTheWholeRun) {
  auto whole = method_->Run(*take_, Options(), {});
  ASSERT_TRUE(whole.ok()) << whole.status();
  constexpr int kCount = 3;
  auto stitched = RunSplit(*take_, kCount);
  ASSERT_TRUE(stitched.ok()) << stitched.status();

  ASSERT_EQ(whole->parts.size(), stitched->parts.size());
  for (size_t p = 0; p < whole->parts.size(); ++p) {
    EXPECT_EQ(whole->parts[p].positions_in_part_m, stitched->parts[p].positions_in_part_m) << p;
    EXPECT_EQ(whole->parts[p].triangles, stitched->parts[p].triangles) << p;
    EXPECT_FALSE(stitched->parts[p].baked_texture_jpeg.empty()) << p;
    EXPECT_EQ(whole->parts[p].baked_texture_jpeg, stitched->parts[p].baked_texture_jpeg) << p;
  }
  ASSERT_EQ(whole->frames.size(), stitched->frames.size());
  for (size_t i = 0; i < whole->frames.size(); ++i) {
    ASSERT_EQ(whole->frames[i].parts.size(), stitched->frames[i].parts.size());
    for (size_t p = 0; p < whole->frames[i].parts.size(); ++p) {
      const reenact::PartPose& a = whole->frames[i].parts[p];
      const reenact::PartPose& b = stitched->frames[i].parts[p];
      EXPECT_TRUE(a.world_from_part.matrix() == b.world_from_part.matrix() && a.scale == b.scale &&
                  a.valid == b.valid)
          << "instant " << i << " part " << p;
    }
  }
  ASSERT_GT(whole->keyframes.size(), 0u);
  ASSERT_EQ(whole->keyframes.size(), stitched->keyframes.size());
  EXPECT_EQ(Serialized(*whole), Serialized(*stitched)) << "the reenactments differ";
  EXPECT_EQ(stitched->info.figures.at("segments"), kCount);
  EXPECT_EQ(whole->info.figures.at("keyframes"), stitched->info.figures.at("keyframes"));

  // Against the ground truth: the same figures.
  auto truth = carving::testing::ReadTruth(*path_);
  ASSERT_TRUE(truth.ok()) << truth.status();
  auto a = carving::testing::Evaluate(*whole, *truth, 3);
  auto b = carving::testing::Evaluate(*stitched, *truth, 3);
  ASSERT_TRUE(a.ok() && b.ok());
  std::printf(
      "%s, %d instants in %d segments (CMU 131_03, random shape): whole run surface %.3f mm, "
      "part frames to the true joints %.3f mm; split run %.3f mm and %.3f mm; %zu keyframes "
      "and %zu baked textures byte-identical\n",
      GetParam().c_str(), take_->num_instants(), kCount, a->mean_mm, a->joint_error_mm, b->mean_mm,
      b->joint_error_mm, stitched->keyframes.size(), stitched->parts.size());
  EXPECT_NEAR(a->mean_mm, b->mean_mm, 1.0);
  EXPECT_NEAR(a->joint_error_mm, b->joint_error_mm, 1.0);
  EXPECT_LT(b->mean_mm, 30.0) << "the parts are off the true surface";
}

TEST_P(RigidSegments, EachPhaseOnlyDecodesTheFramesItNames) {
  const std::string dir = reenact::testing::MakeTempDir("rigid_segments_needs");
  constexpr int kCount = 2;
  const int n = take_->num_instants();

  auto prepare_needs = method_->Needs(*take_, Options(), MethodPhase::kPrepare, 0, kCount);
  ASSERT_TRUE(prepare_needs.ok()) << prepare_needs.status();
  auto prepare_take = testing::SelectedTake(*path_, *take_, *prepare_needs, dir + "/prepare.mcap");
  ASSERT_TRUE(prepare_take.ok()) << prepare_take.status();
  ASSERT_EQ((*prepare_take)->num_instants(), n) << "the same instants";
  auto whole_prepared = method_->Prepare(*take_, Options(), {});
  auto prepared = method_->Prepare(**prepare_take, Options(), {});
  ASSERT_TRUE(whole_prepared.ok() && prepared.ok()) << prepared.status();
  v1::RigidUntexturedPart p, q;
  ASSERT_TRUE(p.ParseFromString(*whole_prepared) && q.ParseFromString(*prepared));
  p.clear_figures();  // Timings.
  q.clear_figures();
  EXPECT_EQ(p.SerializeAsString(), q.SerializeAsString()) << "the prepared parts differ";

  // Each segment: its keyframe instants' images alone.
  std::vector<std::string> segments;
  size_t segment_instants = 0;
  for (int k = 0; k < kCount; ++k) {
    auto needs = method_->Needs(*take_, Options(), MethodPhase::kSegment, k, kCount);
    ASSERT_TRUE(needs.ok()) << needs.status();
    const SegmentRange range = SegmentOf(n, k, kCount, 0);
    ASSERT_FALSE(needs->depth.empty());
    EXPECT_EQ(needs->depth.front(), range.first);
    EXPECT_EQ(needs->depth.back(), range.end - 1);
    EXPECT_EQ(needs->color, needs->depth);
    segment_instants += needs->depth.size();
    auto segment_take =
        testing::SelectedTake(*path_, *take_, *needs, absl::StrCat(dir, "/segment-", k, ".mcap"));
    ASSERT_TRUE(segment_take.ok()) << segment_take.status();
    auto whole_segment = method_->Segment(*take_, Options(), {}, *prepared, k, kCount);
    auto segment = method_->Segment(**segment_take, Options(), {}, *prepared, k, kCount);
    ASSERT_TRUE(whole_segment.ok() && segment.ok()) << segment.status();
    v1::RigidKeyframesPart x, y;
    ASSERT_TRUE(x.ParseFromString(*whole_segment) && y.ParseFromString(*segment));
    ASSERT_GT(x.keyframes_size(), 0);
    ASSERT_EQ(x.keyframes_size(), y.keyframes_size());
    for (int f = 0; f < x.keyframes_size(); ++f) {
      EXPECT_EQ(x.keyframes(f).SerializeAsString(), y.keyframes(f).SerializeAsString()) << f;
    }
    segments.push_back(*std::move(segment));
  }
  EXPECT_EQ(segment_instants, static_cast<size_t>(n)) << "each keyframe instant once";

  // The stitch: no image at all.
  auto stitch_needs = method_->Needs(*take_, Options(), MethodPhase::kStitch, 0, kCount);
  ASSERT_TRUE(stitch_needs.ok());
  EXPECT_TRUE(stitch_needs->depth.empty() && stitch_needs->color.empty());
  auto index = testing::SelectedTake(*path_, *take_, *stitch_needs, dir + "/index.mcap");
  ASSERT_TRUE(index.ok()) << index.status();
  auto stitched = method_->Stitch(**index, Options(), {}, *prepared, segments);
  auto whole_stitched = method_->Stitch(*take_, Options(), {}, *prepared, segments);
  ASSERT_TRUE(stitched.ok() && whole_stitched.ok()) << stitched.status();
  EXPECT_EQ(Serialized(*stitched), Serialized(*whole_stitched));
  std::printf(
      "%s, %d instants in %d segments: prepare decodes the depth of %zu instants and the "
      "colour of %zu, the segments the images of their keyframe instants (%zu in all), the "
      "stitch none; every phase's result equals its result on the whole take\n",
      GetParam().c_str(), n, kCount, prepare_needs->depth.size(), prepare_needs->color.size(),
      segment_instants);
}

TEST_P(RigidSegments, PartsThatDoNotBelongTogetherAreRefused) {
  auto prepared = method_->Prepare(*take_, Options(), {});
  ASSERT_TRUE(prepared.ok()) << prepared.status();
  const auto segment_code = [&](const std::string& bytes, int index, int count) {
    return method_->Segment(*take_, Options(), {}, bytes, index, count).status().code();
  };
  // Segments that do not exist.
  EXPECT_EQ(segment_code(*prepared, 3, 3), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(segment_code(*prepared, -1, 3), absl::StatusCode::kInvalidArgument);
  // A prepared part that does not parse, of another take, or not whole.
  EXPECT_EQ(segment_code("\xff\xff\xff", 0, 2), absl::StatusCode::kDataLoss);
  v1::RigidUntexturedPart part;
  ASSERT_TRUE(part.ParseFromString(*prepared));
  const auto refused = [&](const std::function<void(v1::RigidUntexturedPart*)>& change) {
    v1::RigidUntexturedPart other = part;
    change(&other);
    return segment_code(other.SerializeAsString(), 0, 2) == absl::StatusCode::kInvalidArgument;
  };
  EXPECT_TRUE(refused([](auto* p) { p->set_num_instants(p->num_instants() + 1); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames()->RemoveLast(); }));
  EXPECT_TRUE(refused([](auto* p) { p->set_keyframe_stride(0); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames(4)->mutable_poses()->RemoveLast(); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames(4)->set_frame_index(5); }));
  // A rotation that is not one, a NaN translation, a zero scale.
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames(2)->set_poses(13, 5.0); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames(2)->set_poses(10, NAN); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_frames(2)->set_poses(12, 0.0); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_parts()->RemoveLast(); }));
  EXPECT_TRUE(refused([](auto* p) { p->mutable_parts(0)->set_positions_in_part_m_f32("abc"); }));
  EXPECT_TRUE(refused([](auto* p) {  // A triangle of vertices the mesh does not have.
    for (int c = 0; c < 3; ++c) p->mutable_parts(3)->add_triangle_indices(1u << 30);
  }));

  // Segments missing, out of order, not parsing, or holding foreign keyframes.
  auto first = method_->Segment(*take_, Options(), {}, *prepared, 0, 2);
  auto second = method_->Segment(*take_, Options(), {}, *prepared, 1, 2);
  ASSERT_TRUE(first.ok() && second.ok());
  const auto stitch_code = [&](const std::vector<std::string>& segments) {
    return method_->Stitch(*take_, Options(), {}, *prepared, segments).status().code();
  };
  EXPECT_EQ(stitch_code({*first}), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(stitch_code({*second, *first}), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(stitch_code({*first, "\x01\x02"}), absl::StatusCode::kDataLoss);
  v1::RigidKeyframesPart hostile;
  ASSERT_TRUE(hostile.ParseFromString(*second));
  ASSERT_GT(hostile.keyframes_size(), 0);
  const auto stitch_refused = [&](const std::function<void(v1::TextureKeyframe*)>& change) {
    v1::RigidKeyframesPart other = hostile;
    change(other.mutable_keyframes(0));
    return stitch_code({*first, other.SerializeAsString()}) == absl::StatusCode::kInvalidArgument;
  };
  // An instant of the first segment, bits of another mesh, an unknown sensor.
  EXPECT_TRUE(stitch_refused([](auto* k) { k->set_frame_index(0); }));
  EXPECT_TRUE(stitch_refused([](auto* k) { k->set_vertex_visible_bits(3, "x"); }));
  EXPECT_TRUE(stitch_refused([](auto* k) { k->set_sensor_id("nobody"); }));
  auto stitched = method_->Stitch(*take_, Options(), {}, *prepared, {*first, *second});
  ASSERT_TRUE(stitched.ok()) << stitched.status();
  EXPECT_EQ(static_cast<int>(stitched->frames.size()), take_->num_instants());
}

INSTANTIATE_TEST_SUITE_P(Methods, RigidSegments,
                         ::testing::Values("rigid-carved", "rigid-cylinders"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return info.param == "rigid-carved" ? std::string("RigidCarved")
                                                               : std::string("RigidCylinders");
                         });

}  // namespace
}  // namespace reenact::recon
