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

TEST(DecodeMaskRle, MasksLargerThanThePixelCapAreRefusedFromTheHeader) {
  // One run covers a whole mask of any size: a 14-byte mask may state
  // 65536 x 65536 pixels (4 GiB), refused before anything is reserved.
  MaskImage blank(300, 200);
  const std::string bytes = EncodeMaskRle(blank);
  EXPECT_LT(bytes.size(), 20u);
  EXPECT_TRUE(DecodeMaskRle(bytes, 60000).ok());
  const absl::Status status = DecodeMaskRle(bytes, 59999).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("at most 59999 pixels"), std::string::npos) << status;

  std::string huge = bytes;
  for (int i = 4; i < 12; ++i) huge[i] = (i == 6 || i == 10) ? '\x01' : '\0';  // 65536 x 65536.
  const absl::Status huge_status = DecodeMaskRle(huge).status();
  EXPECT_EQ(huge_status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(huge_status.message().find("implausible size 65536x65536"), std::string::npos)
      << huge_status;
}

}  // namespace
}  // namespace reenact
