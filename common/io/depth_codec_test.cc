#include "common/io/depth_codec.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace reenact {
namespace {

// A 512x424 frame like a Kinect v2 sees: a floor and a back wall, a body-like
// blob in front, invalid holes and borders, and depth-dependent noise.
DepthImageMm SyntheticKinectFrame(uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit_noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DepthImageMm depth_mm(512, 424);
  for (int y = 0; y < depth_mm.height; ++y) {
    for (int x = 0; x < depth_mm.width; ++x) {
      // Wall at 4 m; the floor below the horizon approaches the sensor.
      double z_mm = 4000.0;
      if (y > 212) z_mm = std::min(z_mm, 1200.0 * 365.0 / (y - 205.0));
      // Body: an ellipse 2.5 m away, slightly rounded.
      const double dx = (x - 256.0) / 45.0;
      const double dy = (y - 200.0) / 130.0;
      if (dx * dx + dy * dy < 1.0) z_mm = 2500.0 - 80.0 * std::sqrt(1.0 - dx * dx - dy * dy);
      z_mm += unit_noise(rng) * (1.0 + 0.001 * z_mm);
      const bool border =
          x < 6 || x >= 506 || (x - 256) * (x - 256) + (y - 212) * (y - 212) > 300 * 300;
      const bool hole = uniform(rng) < 0.02 || z_mm > 4500.0;
      depth_mm.at(x, y) = (border || hole) ? 0 : static_cast<uint16_t>(std::lround(z_mm));
    }
  }
  return depth_mm;
}

void ExpectRoundTrip(const DepthImageMm& depth_mm, const DepthCodecOptions& options) {
  const absl::StatusOr<std::string> encoded = EncodeDepth(depth_mm, options);
  ASSERT_TRUE(encoded.ok()) << encoded.status();
  const absl::StatusOr<DepthImageMm> decoded = DecodeDepth(*encoded);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  ASSERT_EQ(decoded->width, depth_mm.width);
  ASSERT_EQ(decoded->height, depth_mm.height);
  size_t mismatched_pixels = 0;
  for (size_t i = 0; i < depth_mm.data.size(); ++i) {
    mismatched_pixels += decoded->data[i] != depth_mm.data[i] ? 1 : 0;
  }
  EXPECT_EQ(mismatched_pixels, 0u);  // Bit-exact: zero pixels may differ.
}

DepthCodecOptions WithZstd(bool zstd) {
  DepthCodecOptions options;
  options.zstd = zstd;
  return options;
}

TEST(DepthCodec, RealisticFrameRoundTripsBitExactly) {
  const DepthImageMm frame = SyntheticKinectFrame(1);
  ExpectRoundTrip(frame, WithZstd(false));
  ExpectRoundTrip(frame, WithZstd(true));
  // RVL alone compresses such a frame by more than 2x (Wilson 2017 reports
  // roughly 3-5x on Kinect data).
  const double ratio =
      static_cast<double>(frame.data.size() * 2) / EncodeDepth(frame, WithZstd(false))->size();
  EXPECT_GT(ratio, 2.0);
}

TEST(DepthCodec, AllZeroFrameRoundTripsAndIsTiny) {
  const DepthImageMm zeros(512, 424, 0);
  ExpectRoundTrip(zeros, WithZstd(false));
  ExpectRoundTrip(zeros, WithZstd(true));
  EXPECT_LE(EncodeDepth(zeros, WithZstd(false))->size(), 40u);  // Bytes: header + one word.
}

TEST(DepthCodec, ExtremeValuesRoundTrip) {
  DepthImageMm extremes(512, 424, 65535);
  ExpectRoundTrip(extremes, WithZstd(false));
  ExpectRoundTrip(extremes, WithZstd(true));
  // Largest possible differences: 1 <-> 65535 alternating, with zeros between.
  for (size_t i = 0; i < extremes.data.size(); ++i) {
    extremes.data[i] = (i % 3 == 0) ? 1 : (i % 3 == 1) ? 65535 : 0;
  }
  ExpectRoundTrip(extremes, WithZstd(false));
  ExpectRoundTrip(extremes, WithZstd(true));
}

TEST(DepthCodec, OddSizesAndEmptyImageRoundTrip) {
  DepthImageMm odd(7, 3);
  for (size_t i = 0; i < odd.data.size(); ++i) odd.data[i] = static_cast<uint16_t>(i * 977 % 5000);
  ExpectRoundTrip(odd, WithZstd(false));
  ExpectRoundTrip(odd, WithZstd(true));
  ExpectRoundTrip(DepthImageMm(), WithZstd(false));
  ExpectRoundTrip(DepthImageMm(), WithZstd(true));
}

TEST(DepthCodec, EveryTruncationIsRejected) {
  const DepthImageMm frame = [] {
    DepthImageMm small = SyntheticKinectFrame(2);
    DepthImageMm crop(40, 30);
    for (int y = 0; y < 30; ++y) {
      for (int x = 0; x < 40; ++x) crop.at(x, y) = small.at(x + 230, y + 150);
    }
    return crop;
  }();
  for (bool zstd : {false, true}) {
    const std::string encoded = *EncodeDepth(frame, WithZstd(zstd));
    int accepted = 0;
    for (size_t length = 0; length < encoded.size(); ++length) {
      const absl::StatusOr<DepthImageMm> decoded = DecodeDepth(encoded.substr(0, length));
      if (decoded.ok()) {
        ++accepted;
      } else {
        EXPECT_EQ(decoded.status().code(), absl::StatusCode::kDataLoss);
        EXPECT_NE(decoded.status().message().find("byte offset"), std::string::npos);
      }
    }
    EXPECT_EQ(accepted, 0) << "zstd=" << zstd;  // Truncations decoded without error.
  }
}

TEST(DepthCodec, RandomByteFlipsAreRejected) {
  DepthImageMm frame(64, 48);
  const DepthImageMm big = SyntheticKinectFrame(3);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) frame.at(x, y) = big.at(x + 220, y + 100);
  }
  std::mt19937 rng(4);
  for (bool zstd : {false, true}) {
    const std::string encoded = *EncodeDepth(frame, WithZstd(zstd));
    int accepted = 0;
    for (int trial = 0; trial < 2000; ++trial) {
      std::string corrupt = encoded;
      const int flips = 1 + trial % 4;
      for (int f = 0; f < flips; ++f) {
        const size_t at = std::uniform_int_distribution<size_t>(0, corrupt.size() - 1)(rng);
        corrupt[at] = static_cast<char>(corrupt[at] ^ (1 + rng() % 255));
      }
      const absl::StatusOr<DepthImageMm> decoded = DecodeDepth(corrupt);
      if (decoded.ok()) ++accepted;
    }
    EXPECT_EQ(accepted, 0) << "zstd=" << zstd;  // Corrupt buffers decoded without error.
  }
}

TEST(RvlDecompress, RejectsStreamsThatDoNotFitTheImage) {
  DepthImageMm frame(16, 4, 1234);
  const std::string rvl = RvlCompress(frame.data);
  std::vector<uint16_t> too_small(32);
  EXPECT_EQ(RvlDecompress(rvl, absl::MakeSpan(too_small)).code(), absl::StatusCode::kDataLoss);
  std::vector<uint16_t> too_large(128);
  EXPECT_EQ(RvlDecompress(rvl, absl::MakeSpan(too_large)).code(), absl::StatusCode::kDataLoss);
  std::vector<uint16_t> exact(64);
  ASSERT_TRUE(RvlDecompress(rvl, absl::MakeSpan(exact)).ok());
  EXPECT_EQ(std::count(exact.begin(), exact.end(), 1234), 64);  // Pixels.
}

TEST(RvlDecompress, CorruptStreamsFailCleanly) {
  // The bare stream has no checksum: corrupt words must still decode into
  // bounds or fail with DataLoss, never read or write out of bounds.
  DepthImageMm frame(64, 48);
  const DepthImageMm big = SyntheticKinectFrame(5);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) frame.at(x, y) = big.at(x + 200, y + 300);
  }
  const std::string rvl = RvlCompress(frame.data);
  std::mt19937 rng(6);
  std::vector<uint16_t> out(frame.data.size());
  int rejected = 0;
  int other_codes = 0;
  constexpr int kTrials = 3000;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::string corrupt = rvl.substr(0, rvl.size() - 4 * (trial % 3));
    const size_t at = std::uniform_int_distribution<size_t>(0, corrupt.size() - 1)(rng);
    corrupt[at] = static_cast<char>(corrupt[at] ^ (1 + rng() % 255));
    const absl::Status status = RvlDecompress(corrupt, absl::MakeSpan(out));
    if (!status.ok()) ++rejected;
    if (!status.ok() && status.code() != absl::StatusCode::kDataLoss) ++other_codes;
  }
  EXPECT_EQ(other_codes, 0);
  // Most corruptions break the run structure; a flip inside one difference
  // can still yield a valid (different) image, which the container's CRC
  // catches.
  EXPECT_GT(rejected, kTrials / 2);
}

TEST(DepthCodec, ImagesLargerThanThePixelCapAreRefusedFromTheHeader) {
  // RVL codes a blank image of any size in a few bytes: the stated size, not
  // the payload, must bound what decoding allocates.
  const absl::StatusOr<std::string> encoded = EncodeDepth(DepthImageMm(640, 480), WithZstd(false));
  ASSERT_TRUE(encoded.ok()) << encoded.status();
  EXPECT_LT(encoded->size(), 64u);
  EXPECT_TRUE(DecodeDepth(*encoded).ok());
  EXPECT_TRUE(DecodeDepth(*encoded, 640 * 480).ok());
  for (const auto& result : {InspectDepth(*encoded, 640 * 480 - 1).status(),
                             DecodeDepth(*encoded, 640 * 480 - 1).status()}) {
    EXPECT_EQ(result.code(), absl::StatusCode::kDataLoss) << result;
    EXPECT_NE(result.message().find("307200 pixels, more than the 307199 allowed"),
              std::string::npos)
        << result;
  }
  // No caller can raise the ceiling.
  EXPECT_TRUE(DecodeDepth(*encoded, ~uint64_t{0}).ok());
  EXPECT_GE(uint64_t{8192} * 8192, kMaxDecodedImagePixels);
}

TEST(DepthCodecOptions, ValidateRejectsBadLevel) {
  DepthCodecOptions options;
  options.zstd_level = 0;
  EXPECT_FALSE(options.Validate().ok());
  EXPECT_FALSE(EncodeDepth(DepthImageMm(4, 4), options).ok());
  options.zstd_level = 3;
  EXPECT_TRUE(options.Validate().ok());
}

}  // namespace
}  // namespace reenact
