#include "clients/viewer/playback.h"

#include <gtest/gtest.h>

namespace reenact::viewer {
namespace {

TEST(Playback, AdvancesAtTheFrameRateTimesSpeed) {
  Playback playback(100, 30.0);
  playback.Advance(1.0);
  EXPECT_EQ(playback.frame(), 30);
  playback.SetSpeed(0.5);
  playback.Advance(1.0);
  EXPECT_EQ(playback.frame(), 45);
  playback.SetSpeed(100);  // Clamped to 8.
  EXPECT_DOUBLE_EQ(playback.speed(), 8.0);
}

TEST(Playback, LoopsOrStopsAtTheEnd) {
  Playback looping(10, 10.0);
  looping.Advance(1.25);  // 12.5 instants: wraps to 2.5.
  EXPECT_TRUE(looping.playing());
  EXPECT_GE(looping.frame(), 2);
  EXPECT_LE(looping.frame(), 3);
  Playback once(10, 10.0);
  once.SetLoop(false);
  once.Advance(5.0);
  EXPECT_EQ(once.frame(), 9);
  EXPECT_FALSE(once.playing());
}

TEST(Playback, ScrubStepAndPause) {
  Playback playback(101, 30.0);
  playback.Scrub(0.5);
  EXPECT_EQ(playback.frame(), 50);
  playback.Step(3);
  EXPECT_EQ(playback.frame(), 53);
  EXPECT_FALSE(playback.playing());
  playback.Advance(10.0);  // Paused: no motion.
  EXPECT_EQ(playback.frame(), 53);
  playback.Step(-1000);
  EXPECT_EQ(playback.frame(), 0);
  playback.Scrub(7.0);
  EXPECT_EQ(playback.frame(), 100);
  EXPECT_DOUBLE_EQ(playback.fraction(), 1.0);
}

}  // namespace
}  // namespace reenact::viewer
