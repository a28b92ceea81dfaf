#include "capture_daemon/sensors/frame_pairing.h"

#include <gtest/gtest.h>

namespace reenact::capture {
namespace {

constexpr int64_t kPeriodNs = 33'333'333;

DepthImageMm DepthOf(uint16_t value) { return DepthImageMm(4, 3, value); }
RgbImage ColorOf(uint8_t value) { return RgbImage(4, 3, value); }

TEST(DepthColorPairer, PairsColourArrivingAfterDepth) {
  DepthColorPairer pairer(kPeriodNs / 2);
  EXPECT_TRUE(pairer.AddDepth(DepthOf(1000), 0, 100).empty());
  auto out = pairer.AddColor(ColorOf(7), 500'000);
  ASSERT_EQ(out.size(), 1u);
  ASSERT_TRUE(out[0].color.has_value());
  EXPECT_EQ(out[0].color->data[0], 7);
  EXPECT_EQ(out[0].depth_mm.data[0], 1000);
  EXPECT_EQ(out[0].host_stamp_ns, 100);
}

TEST(DepthColorPairer, PairsColourArrivingBeforeDepth) {
  DepthColorPairer pairer(kPeriodNs / 2);
  EXPECT_TRUE(pairer.AddColor(ColorOf(9), kPeriodNs - 1'000'000).empty());
  auto out = pairer.AddDepth(DepthOf(1200), kPeriodNs, 5);
  ASSERT_EQ(out.size(), 1u);
  ASSERT_TRUE(out[0].color.has_value());
  EXPECT_EQ(out[0].color->data[0], 9);
  EXPECT_EQ(out[0].device_stamp_ns, kPeriodNs);
}

TEST(DepthColorPairer, ReleasesDepthWithoutColourWhenColourIsLost) {
  DepthColorPairer pairer(kPeriodNs / 2);
  EXPECT_TRUE(pairer.AddDepth(DepthOf(1), 0, 0).empty());
  // The next depth frame arrives with no colour for the first: the first is
  // released alone, the second waits.
  auto out = pairer.AddDepth(DepthOf(2), kPeriodNs, 0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FALSE(out[0].color.has_value());
  EXPECT_EQ(out[0].depth_mm.data[0], 1);
  // Colour of a later instant also releases the waiting frame.
  out = pairer.AddColor(ColorOf(3), 3 * kPeriodNs);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].depth_mm.data[0], 2);
  EXPECT_FALSE(out[0].color.has_value());
  EXPECT_TRUE(pairer.Flush().empty());
}

TEST(DepthColorPairer, FlushReleasesTheWaitingFrame) {
  DepthColorPairer pairer(kPeriodNs / 2);
  pairer.AddDepth(DepthOf(5), 0, 0);
  auto out = pairer.Flush();
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].depth_mm.data[0], 5);
}

}  // namespace
}  // namespace reenact::capture
