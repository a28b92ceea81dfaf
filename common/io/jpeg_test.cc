#include "common/io/jpeg.h"

#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>

namespace reenact {
namespace {

// A smooth colour gradient with a soft disc: the kind of content JPEG keeps well.
RgbImage TestImage(int width, int height) {
  RgbImage image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double r = std::hypot(x - width / 2.0, y - height / 2.0);
      image.at(x, y, 0) = static_cast<uint8_t>(255 * x / (width - 1));
      image.at(x, y, 1) = static_cast<uint8_t>(255 * y / (height - 1));
      image.at(x, y, 2) = static_cast<uint8_t>(r < width / 4.0 ? 200 : 40);
    }
  }
  return image;
}

double MeanAbsError(const RgbImage& a, const RgbImage& b) {
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i) sum += std::abs(int{a.data[i]} - int{b.data[i]});
  return sum / static_cast<double>(a.data.size());
}

TEST(EncodeJpeg, RoundTripsWithinQualityBoundError) {
  const RgbImage image = TestImage(96, 64);
  auto high = EncodeJpeg(image, 95);
  auto low = EncodeJpeg(image, 10);
  ASSERT_TRUE(high.ok() && low.ok());
  auto high_decoded = DecodeJpeg(*high);
  auto low_decoded = DecodeJpeg(*low);
  ASSERT_TRUE(high_decoded.ok() && low_decoded.ok());
  ASSERT_EQ(high_decoded->width, 96);
  ASSERT_EQ(high_decoded->height, 64);
  const double high_error = MeanAbsError(image, *high_decoded);
  const double low_error = MeanAbsError(image, *low_decoded);
  EXPECT_LT(high_error, 3.0);  // Grey levels.
  EXPECT_GT(low_error, high_error);
  EXPECT_LT(low->size(), high->size());
}

TEST(EncodeJpeg, RejectsBadArguments) {
  EXPECT_EQ(EncodeJpeg(RgbImage(), 90).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeJpeg(TestImage(8, 8), 0).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeJpeg(TestImage(8, 8), 101).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(DecodeJpeg, RejectsGarbageAndTruncation) {
  EXPECT_EQ(DecodeJpeg("not a jpeg").status().code(), absl::StatusCode::kInvalidArgument);
  auto jpeg = EncodeJpeg(TestImage(64, 64), 90);
  ASSERT_TRUE(jpeg.ok());
  EXPECT_FALSE(DecodeJpeg(jpeg->substr(0, jpeg->size() / 2)).ok());
}

}  // namespace
}  // namespace reenact
