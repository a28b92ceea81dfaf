#include "common/io/png.h"

#include <cstdint>
#include <iostream>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/base/files.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

// A rendered-looking frame: smooth gradients, a flat disc and some noise.
RgbImage TestImage(int width, int height) {
  RgbImage image(width, height);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> noise(0, 255);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool disc = (x - width / 2) * (x - width / 2) + (y - height / 2) * (y - height / 2) <
                        (height / 3) * (height / 3);
      image.at(x, y, 0) = static_cast<uint8_t>(disc ? 200 : x * 255 / width);
      image.at(x, y, 1) = static_cast<uint8_t>(disc ? 40 : y * 255 / height);
      image.at(x, y, 2) = static_cast<uint8_t>(x % 17 == 0 ? noise(rng) : 90);
    }
  }
  return image;
}

// Decoded by OpenCV (libpng), an independent reader: RGB(A) in file order.
cv::Mat Decode(const std::string& png) {
  const std::vector<uint8_t> bytes(png.begin(), png.end());
  return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
}

TEST(Png, RgbRoundTripsThroughAnIndependentDecoderExactly) {
  const RgbImage image = TestImage(321, 123);  // Odd sizes.
  for (int level : {0, 1, 9}) {
    absl::StatusOr<std::string> png = EncodePng(image, {.compression_level = level});
    ASSERT_TRUE(png.ok()) << png.status();
    const cv::Mat decoded = Decode(*png);
    ASSERT_EQ(decoded.type(), CV_8UC3);
    ASSERT_EQ(decoded.cols, 321);
    ASSERT_EQ(decoded.rows, 123);
    int mismatches = 0;
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const cv::Vec3b bgr = decoded.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) mismatches += bgr[2 - c] != image.at(x, y, c);
      }
    }
    EXPECT_EQ(mismatches, 0) << "level " << level;  // Lossless.
    std::cout << "level " << level << ": " << png->size() << " bytes for " << image.data.size()
              << " raw\n";
    if (level > 0) {
      EXPECT_LT(png->size(), image.data.size());
    }
  }
}

TEST(Png, MaskBecomesAlpha) {
  const RgbImage image = TestImage(64, 48);
  MaskImage mask(64, 48);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) mask.at(x, y) = x < 20 ? 0 : static_cast<uint8_t>(1 + y % 3);
  }
  absl::StatusOr<std::string> png = EncodePng(image, {.alpha_mask = &mask});
  ASSERT_TRUE(png.ok()) << png.status();
  const cv::Mat decoded = Decode(*png);
  ASSERT_EQ(decoded.type(), CV_8UC4);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      const cv::Vec4b bgra = decoded.at<cv::Vec4b>(y, x);
      ASSERT_EQ(bgra[3], x < 20 ? 0 : 255) << x << "," << y;
      ASSERT_EQ(bgra[2], image.at(x, y, 0));
      ASSERT_EQ(bgra[0], image.at(x, y, 2));
    }
  }
}

TEST(Png, BadInputIsAnErrorAndWritingReplacesTheFile) {
  EXPECT_EQ(EncodePng(RgbImage()).status().code(), absl::StatusCode::kInvalidArgument);
  const RgbImage image = TestImage(8, 8);
  EXPECT_EQ(EncodePng(image, {.compression_level = 10}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const MaskImage small(4, 4);
  EXPECT_EQ(EncodePng(image, {.alpha_mask = &small}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const std::string dir = testing::MakeTempDir("png");
  const std::string path = dir + "/frame.png";
  ASSERT_TRUE(WriteFileAtomically(path, "old").ok());
  ASSERT_TRUE(WritePng(image, path).ok());
  const cv::Mat read = cv::imread(path, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(read.cols, 8);
  EXPECT_FALSE(WritePng(image, dir + "/missing/frame.png").ok());
}

}  // namespace
}  // namespace reenact
