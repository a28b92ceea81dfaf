#include "server/store/frame_set_validation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "common/io/depth_codec.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

using testing::MakeFrameSet;
using testing::TestSensor;

SensorMap TwoSensors() { return {{"k0", TestSensor("k0")}, {"k1", TestSensor("k1")}}; }

TEST(ValidateFrameSet, AcceptsWellFormedSets) {
  const FrameSetLimits limits;
  for (uint64_t s = 1; s <= 5; ++s) {
    EXPECT_TRUE(ValidateFrameSet(MakeFrameSet(s, {"k0", "k1"}), TwoSensors(), limits).ok());
  }
  v1::FrameSet one = MakeFrameSet(1, {"k1"});
  one.add_missing_sensor_ids("k0");
  EXPECT_TRUE(ValidateFrameSet(one, TwoSensors(), limits).ok());
}

struct BadCase {
  std::string name;
  std::function<void(v1::FrameSet&)> mutate;
  std::string message;  // Expected in the error.
};

TEST(ValidateFrameSet, RefusesEachKindOfBadSet) {
  const std::vector<BadCase> cases = {
      {"unknown sensor", [](v1::FrameSet& s) { s.mutable_frames(1)->set_sensor_id("k7"); },
       "not in the take"},
      {"same sensor twice", [](v1::FrameSet& s) { s.mutable_frames(1)->set_sensor_id("k0"); },
       "second frame"},
      {"nested sensor id",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_sensor_id("k1"); },
       "differ from the frame"},
      {"nested stamp",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_color()->set_host_stamp_ns(5); },
       "differ from the frame"},
      {"nested index",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_mask()->set_frame_index(99); },
       "differ from the frame"},
      {"skeleton stamp",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_skeletons(0)->set_device_stamp_ns(1); },
       "differ from the frame"},
      {"no depth", [](v1::FrameSet& s) { s.mutable_frames(0)->clear_depth(); }, "no depth"},
      {"depth encoding",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_encoding("png"); },
       "encoding \"png\""},
      {"depth label vs header",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_encoding("rvl+zstd"); },
       "zstd"},
      {"zero width", [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_width_px(0); },
       "outside 1.."},
      {"absurd size",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_color()->set_height_px(1 << 20); },
       "outside 1.."},
      {"size vs calibration",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_width_px(64); },
       "calibration"},
      {"truncated depth",
       [](v1::FrameSet& s) {
         std::string* d = s.mutable_frames(0)->mutable_depth()->mutable_data();
         d->resize(d->size() - 4);
       },
       "but the header says"},
      {"foreign depth",
       [](v1::FrameSet& s) {
         s.mutable_frames(0)->mutable_depth()->set_data(std::string(200, 'x'));
       },
       "RVLD"},
      {"flipped depth bit",
       [](v1::FrameSet& s) {
         std::string* d = s.mutable_frames(0)->mutable_depth()->mutable_data();
         (*d)[d->size() - 3] ^= 0x10;
       },
       "checksum"},
      {"colour encoding",
       [](v1::FrameSet& s) { s.mutable_frames(1)->mutable_color()->set_encoding("png"); },
       "encoding \"png\""},
      {"colour bytes",
       [](v1::FrameSet& s) {
         s.mutable_frames(1)->mutable_color()->set_data("\xFF\xD8 not really");
       },
       "not a JPEG"},
      {"colour size vs JPEG",
       [](v1::FrameSet& s) {
         auto* c = s.mutable_frames(1)->mutable_color();
         c->set_width_px(16);
       },
       "px"},
      {"mask encoding",
       [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_mask()->set_encoding("png"); },
       "encoding \"png\""},
      {"mask bytes", [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_mask()->set_data("RLM1"); },
       "RLM1"},
      {"mask runs short of the image",
       [](v1::FrameSet& s) {
         // A valid header, then one run of a single pixel.
         std::string* d = s.mutable_frames(0)->mutable_mask()->mutable_data();
         d->resize(12);
         d->append(std::string("\x01\x00", 2));
       },
       "runs cover 1 of"},
      {"mask runs past the image",
       [](v1::FrameSet& s) {
         std::string* d = s.mutable_frames(0)->mutable_mask()->mutable_data();
         d->append(std::string("\x01\x00", 2));
       },
       "more pixels than the mask has"},
      {"NaN joint",
       [](v1::FrameSet& s) {
         s.mutable_frames(0)
             ->mutable_skeletons(0)
             ->mutable_joints(0)
             ->mutable_position_in_depth_m()
             ->set_x(std::numeric_limits<double>::quiet_NaN());
       },
       "not finite"},
      {"joint confidence",
       [](v1::FrameSet& s) {
         s.mutable_frames(0)->mutable_skeletons(0)->mutable_joints(0)->set_confidence(
             std::numeric_limits<float>::quiet_NaN());
       },
       "confidence"},
      {"joint confidence above one",
       [](v1::FrameSet& s) {
         s.mutable_frames(0)->mutable_skeletons(0)->mutable_joints(0)->set_confidence(7.0f);
       },
       "confidence"},
      {"negative stamp", [](v1::FrameSet& s) { s.set_stamp_ns(-1); }, "negative"},
      {"missing names a framed sensor", [](v1::FrameSet& s) { s.add_missing_sensor_ids("k0"); },
       "missing_sensor_ids"},
      {"missing names unknown", [](v1::FrameSet& s) { s.add_missing_sensor_ids("zz"); },
       "missing_sensor_ids"},
  };
  for (const BadCase& c : cases) {
    v1::FrameSet set = MakeFrameSet(3, {"k0", "k1"});
    c.mutate(set);
    const absl::Status status = ValidateFrameSet(set, TwoSensors(), FrameSetLimits{});
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c.name << ": " << status;
    EXPECT_NE(status.message().find(c.message), std::string::npos) << c.name << ": " << status;
  }
}

TEST(ValidateFrameSet, RefusesImagesOverThePixelCap) {
  const v1::FrameSet set = MakeFrameSet(3, {"k0", "k1"});
  int64_t largest = 0;  // Pixels of the largest image in the set.
  for (const v1::Frame& f : set.frames()) {
    largest = std::max({largest, int64_t{f.depth().width_px()} * f.depth().height_px(),
                        int64_t{f.color().width_px()} * f.color().height_px()});
  }
  FrameSetLimits limits;
  limits.max_image_pixels = largest;
  EXPECT_TRUE(ValidateFrameSet(set, TwoSensors(), limits).ok());
  limits.max_image_pixels = largest - 1;
  ASSERT_TRUE(limits.Validate().ok());
  const absl::Status status = ValidateFrameSet(set, TwoSensors(), limits);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_NE(status.message().find("--max-frame-pixels"), std::string::npos) << status;
  limits.max_image_pixels = int64_t{1} << 40;  // Past what any decoder allocates.
  EXPECT_FALSE(limits.Validate().ok());
}

TEST(ValidateTakeId, AcceptsIdsOfTheProtocolOnly) {
  EXPECT_TRUE(ValidateTakeId("20261121T153000-studio-3f9a").ok());
  EXPECT_TRUE(ValidateTakeId(std::string(64, 'a')).ok());
  for (const std::string& bad :
       std::vector<std::string>{"", "../etc", "a b", "a/b", std::string(65, 'a'), "dot.dot"}) {
    EXPECT_EQ(ValidateTakeId(bad).code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

TEST(ValidateSensors, RefusesRepeatsBadIdsAndSizes) {
  const FrameSetLimits limits;
  EXPECT_TRUE(ValidateSensors({TestSensor("k0"), TestSensor("k1")}, limits).ok());
  EXPECT_FALSE(ValidateSensors({}, limits).ok());
  EXPECT_FALSE(ValidateSensors({TestSensor("k0"), TestSensor("k0")}, limits).ok());
  EXPECT_FALSE(ValidateSensors({TestSensor("k/0")}, limits).ok());
  v1::SensorCalibration huge = TestSensor("k0");
  huge.mutable_depth_intrinsics()->set_width_px(100000);
  EXPECT_FALSE(ValidateSensors({huge}, limits).ok());
}

// A Kinect v2 depth frame (512x424) of a smooth scene with noise and holes.
DepthImageMm KinectLikeDepth(uint32_t seed) {
  DepthImageMm depth(512, 424);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 3.0);
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const bool hole = ((x / 16 + y / 16) % 11 == 0);
      depth.at(x, y) = hole ? 0
                            : static_cast<uint16_t>(2500 + 400 * std::sin(x / 60.0) +
                                                    200 * std::cos(y / 45.0) + noise(rng));
    }
  }
  return depth;
}

// Both depth checks accept a full-size frame; only the decode finds a
// flipped payload bit. Prints the cost of each (not asserted).
TEST(ValidateFrameSet, DepthCheckCostAndCoverage) {
  SensorMap sensors = {{"k0", TestSensor("k0")}};
  sensors["k0"].mutable_depth_intrinsics()->set_width_px(512);
  sensors["k0"].mutable_depth_intrinsics()->set_height_px(424);
  for (const bool zstd : {false, true}) {
    v1::FrameSet set = MakeFrameSet(1, {"k0"});
    v1::Frame* f = set.mutable_frames(0);
    f->clear_color();
    f->clear_mask();
    f->mutable_depth()->set_width_px(512);
    f->mutable_depth()->set_height_px(424);
    f->mutable_depth()->set_encoding(zstd ? "rvl+zstd" : "rvl");
    f->mutable_depth()->set_data(*EncodeDepth(KinectLikeDepth(7), DepthCodecOptions{.zstd = zstd}));
    for (const DepthCheck check : {DepthCheck::kHeader, DepthCheck::kDecode}) {
      FrameSetLimits limits;
      limits.depth_check = check;
      constexpr int kRuns = 20;
      const auto start = std::chrono::steady_clock::now();
      for (int i = 0; i < kRuns; ++i) ASSERT_TRUE(ValidateFrameSet(set, sensors, limits).ok());
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count() /
          kRuns;
      std::printf("depth check %s of %zu-byte %s frame: %.3f ms\n",
                  check == DepthCheck::kHeader ? "header" : "decode", f->depth().data().size(),
                  zstd ? "rvl+zstd" : "rvl", ms);
    }
    v1::FrameSet flipped = set;
    std::string* data = flipped.mutable_frames(0)->mutable_depth()->mutable_data();
    (*data)[data->size() / 2] ^= 0x01;
    FrameSetLimits header_only;
    header_only.depth_check = DepthCheck::kHeader;
    // The checksum catches a flipped payload bit without decoding.
    EXPECT_EQ(ValidateFrameSet(flipped, sensors, header_only).code(),
              absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(ValidateFrameSet(flipped, sensors, FrameSetLimits{}).code(),
              absl::StatusCode::kInvalidArgument);
  }
}

}  // namespace
}  // namespace reenact::server
