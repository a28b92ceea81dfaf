#include "common/io/mask_codec.h"

#include <random>

#include <gtest/gtest.h>

namespace reenact {
namespace {

MaskImage TwoBodies(int width, int height) {
  MaskImage mask(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (x > width / 4 && x < width / 2 && y > 5) mask.at(x, y) = 1;
      if (x > 2 * width / 3 && y > height / 2) mask.at(x, y) = 2;
    }
  }
  return mask;
}

TEST(EncodeMaskRle, RoundTripsExactly) {
  const MaskImage mask = TwoBodies(512, 424);
  const std::string bytes = EncodeMaskRle(mask);
  auto decoded = DecodeMaskRle(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_TRUE(*decoded == mask);
  EXPECT_LT(bytes.size(), mask.data.size() / 20);  // Silhouettes compress well.
}

TEST(EncodeMaskRle, RoundTripsNoiseAndEmpty) {
  MaskImage noise(37, 11);
  std::mt19937 rng(5);
  for (auto& v : noise.data) v = static_cast<uint8_t>(rng() % 3);
  auto decoded = DecodeMaskRle(EncodeMaskRle(noise));
  ASSERT_TRUE(decoded.ok());
  EXPECT_TRUE(*decoded == noise);
  auto empty = DecodeMaskRle(EncodeMaskRle(MaskImage()));
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(empty->empty());
}

TEST(DecodeMaskRle, RejectsEveryTruncation) {
  const std::string bytes = EncodeMaskRle(TwoBodies(64, 48));
  for (size_t size = 0; size < bytes.size(); ++size) {
    auto decoded = DecodeMaskRle(bytes.substr(0, size));
    ASSERT_FALSE(decoded.ok()) << "size " << size;
    EXPECT_NE(decoded.status().message().find("byte offset"), std::string::npos);
  }
  std::string longer = bytes;
  longer += std::string("\x01\x00", 2);
  EXPECT_FALSE(DecodeMaskRle(longer).ok());
}

}  // namespace
}  // namespace reenact
