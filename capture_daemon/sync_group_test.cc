#include "capture_daemon/sync_group.h"

#include <algorithm>
#include <iostream>
#include <map>
#include <random>
#include <set>

#include <gtest/gtest.h>

namespace reenact::capture {
namespace {

constexpr int64_t kPeriodNs = 33'333'333;  // 30 fps.
constexpr int64_t kMs = 1'000'000;

v1::Frame MakeFrame(const std::string& id, int64_t index, int64_t device_ns, int64_t host_ns) {
  v1::Frame f;
  f.set_sensor_id(id);
  f.set_frame_index(index);
  f.set_device_stamp_ns(device_ns);
  f.set_host_stamp_ns(host_ns);
  return f;
}

struct SimSensor {
  std::string id;
  int64_t clock_offset_ns;  // host = device + offset (true clock offset).
  int64_t phase_ns;         // Exposure phase within the period.
};

// Every frame of a simulated capture, in arrival (host stamp) order.
std::vector<v1::Frame> Simulate(const std::vector<SimSensor>& sensors, int frames,
                                int64_t latency_ns, int64_t jitter_ns, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int64_t> jitter(0, jitter_ns);
  std::vector<v1::Frame> out;
  const int64_t start_ns = 1'700'000'000'000'000'000;
  for (int f = 0; f < frames; ++f) {
    for (const SimSensor& s : sensors) {
      const int64_t exposure = start_ns + f * kPeriodNs + s.phase_ns;
      out.push_back(
          MakeFrame(s.id, f, exposure - s.clock_offset_ns, exposure + latency_ns + jitter(rng)));
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const v1::Frame& a, const v1::Frame& b) {
    return a.host_stamp_ns() < b.host_stamp_ns();
  });
  return out;
}

void Append(std::vector<v1::FrameSet>* all, std::vector<v1::FrameSet> more) {
  for (auto& s : more) all->push_back(std::move(s));
}

TEST(SyncGroup, EstimatesOffsetsAndPlacesEveryFrameOnce) {
  const std::vector<SimSensor> sim = {
      {"k0", 5'000 * kMs, 0}, {"k1", -3'000 * kMs, 3 * kMs}, {"k2", 123 * kMs, 7 * kMs}};
  const int64_t latency_ns = 20 * kMs;
  std::vector<v1::Frame> frames = Simulate(sim, 300, latency_ns, 6 * kMs, 7);

  // One frame of k1 is lost, one of k2 arrives twice, one of k0 arrives far
  // too late (after its set was sent).
  auto find = [&frames](const std::string& id, int64_t index) {
    return std::find_if(frames.begin(), frames.end(), [&](const v1::Frame& f) {
      return f.sensor_id() == id && f.frame_index() == index;
    });
  };
  frames.erase(find("k1", 100));
  auto dup = find("k2", 150);
  frames.insert(dup + 1, *dup);
  auto late = find("k0", 200);
  v1::Frame late_frame = *late;
  frames.erase(late);
  frames.insert(find("k1", 210), late_frame);

  auto group = SyncGroup::Create({});
  ASSERT_TRUE(group.ok()) << group.status();
  for (const SimSensor& s : sim) ASSERT_TRUE((*group)->AddSensor(s.id, 30.0).ok());
  std::vector<v1::FrameSet> sets;
  for (const v1::Frame& f : frames) Append(&sets, (*group)->Add(f));
  Append(&sets, (*group)->Flush());

  // Offsets: the lower envelope finds offset + smallest transport delay.
  const SyncSummary summary = (*group)->Summary();
  ASSERT_EQ(summary.sensors.size(), 3u);
  for (size_t i = 0; i < sim.size(); ++i) {
    const double error_ms =
        (summary.sensors[i].clock_offset_ns - (sim[i].clock_offset_ns + latency_ns)) / 1e6;
    std::cout << sim[i].id << ": offset error " << error_ms << " ms\n";
    EXPECT_NEAR(error_ms, 0.0, 2.0) << sim[i].id;
    EXPECT_GE(error_ms, 0.0) << "the lower envelope cannot undercut the true delay";
  }

  // Every instant gives one set; sequences 1..N.
  ASSERT_EQ(sets.size(), 300u);
  std::set<std::pair<std::string, int64_t>> seen;
  for (size_t i = 0; i < sets.size(); ++i) {
    EXPECT_EQ(sets[i].sequence(), i + 1);
    std::set<int64_t> indices;
    for (const v1::Frame& f : sets[i].frames()) {
      EXPECT_TRUE(seen.insert({f.sensor_id(), f.frame_index()}).second)
          << f.sensor_id() << " frame " << f.frame_index() << " in two sets";
      indices.insert(f.frame_index());
    }
    EXPECT_EQ(indices.size(), 1u) << "set " << sets[i].sequence() << " mixes instants";
    EXPECT_EQ(sets[i].frames_size() + sets[i].missing_sensor_ids_size(), 3);
    if (i > 0) {
      EXPECT_GT(sets[i].stamp_ns(), sets[i - 1].stamp_ns());
    }
  }
  // 900 frames - 1 lost - 1 late; the duplicate is not placed.
  EXPECT_EQ(seen.size(), 898u);
  EXPECT_EQ(summary.sensors[0].frames_dropped, 1);
  EXPECT_EQ(summary.sensors[0].frames_duplicate, 0);
  EXPECT_EQ(summary.sensors[1].frames_dropped, 0);
  EXPECT_EQ(summary.sensors[2].frames_duplicate, 1);
  EXPECT_EQ(summary.sensors[2].frames_dropped, 0);
  EXPECT_EQ(summary.sensors[2].frames_in, 301);
  EXPECT_EQ(summary.incomplete_sets, 2);
  EXPECT_EQ(sets[100].missing_sensor_ids_size(), 1);
  EXPECT_EQ(sets[100].missing_sensor_ids(0), "k1");

  // Skew: the exposure phases span 7 ms; offsets remove the clocks.
  std::cout << "skew p50 " << summary.skew_p50_ns / 1e6 << " ms, p99 " << summary.skew_p99_ns / 1e6
            << " ms, max " << summary.skew_max_ns / 1e6 << " ms\n";
  EXPECT_NEAR(summary.skew_p50_ns / 1e6, 7.0, 1.5);
  EXPECT_LT(summary.skew_max_ns, (*group)->tolerance_ns() * 2);
}

TEST(SyncGroup, EndedSensorNoLongerHoldsSets) {
  auto group = SyncGroup::Create({});
  ASSERT_TRUE(group.ok());
  ASSERT_TRUE((*group)->AddSensor("a", 30.0).ok());
  ASSERT_TRUE((*group)->AddSensor("b", 30.0).ok());
  std::vector<v1::FrameSet> sets;
  for (int f = 0; f < 10; ++f) {
    Append(&sets, (*group)->Add(MakeFrame("a", f, f * kPeriodNs, f * kPeriodNs + kMs)));
    Append(&sets, (*group)->Add(MakeFrame("b", f, f * kPeriodNs, f * kPeriodNs + 2 * kMs)));
  }
  EXPECT_EQ(sets.size(), 10u);
  Append(&sets, (*group)->SensorLost("b"));
  // From now on each frame of `a` completes its set at once.
  for (int f = 10; f < 20; ++f) {
    const size_t before = sets.size();
    Append(&sets, (*group)->Add(MakeFrame("a", f, f * kPeriodNs, f * kPeriodNs + kMs)));
    EXPECT_EQ(sets.size(), before + 1) << "frame " << f << " was held back";
    EXPECT_EQ(sets.back().missing_sensor_ids_size(), 1);
  }
  // A frame of the lost sensor is dropped.
  Append(&sets, (*group)->Add(MakeFrame("b", 20, 20 * kPeriodNs, 20 * kPeriodNs + kMs)));
  EXPECT_EQ((*group)->Summary().sensors[1].frames_dropped, 1);
}

TEST(SyncGroup, StalledSensorHoldsSetsForBoundedTime) {
  SyncOptions options;
  options.tolerance_ns = 10 * kMs;
  options.max_wait_ns = 40 * kMs;
  auto group = SyncGroup::Create(options);
  ASSERT_TRUE(group.ok());
  ASSERT_TRUE((*group)->AddSensor("a", 30.0).ok());
  ASSERT_TRUE((*group)->AddSensor("b", 30.0).ok());
  // `b` delivers its first frame only; `a` goes on.
  std::vector<v1::FrameSet> sets = (*group)->Add(MakeFrame("b", 0, 0, kMs));
  int64_t largest_backlog = 0;
  for (int f = 0; f < 30; ++f) {
    Append(&sets, (*group)->Add(MakeFrame("a", f, f * kPeriodNs, f * kPeriodNs + kMs)));
    largest_backlog = std::max<int64_t>(largest_backlog, f + 1 - static_cast<int64_t>(sets.size()));
  }
  // A set leaves once a frame 10 + 40 ms past its anchor arrives: two
  // periods later at 30 fps, so at most two sets wait.
  EXPECT_EQ(largest_backlog, 2);
  ASSERT_GE(sets.size(), 2u);
  EXPECT_EQ(sets[0].frames_size(), 2);
  EXPECT_EQ(sets[1].frames_size(), 1);
  // Expire sends what waits once the host clock is far past it.
  const auto expired = (*group)->Expire(40 * kPeriodNs, 0);
  EXPECT_EQ(sets.size() + expired.size(), 30u);
}

TEST(SyncGroup, RejectsBadInput) {
  SyncOptions bad;
  bad.tolerance_ns = -1;
  EXPECT_FALSE(SyncGroup::Create(bad).ok());
  auto group = SyncGroup::Create({});
  ASSERT_TRUE(group.ok());
  EXPECT_FALSE((*group)->AddSensor("", 30).ok());
  ASSERT_TRUE((*group)->AddSensor("a", 30).ok());
  EXPECT_FALSE((*group)->AddSensor("a", 30).ok());
  // Unknown sensors are ignored.
  EXPECT_TRUE((*group)->Add(MakeFrame("zz", 0, 0, 0)).empty());
  // Half a period at 30 fps.
  EXPECT_EQ((*group)->tolerance_ns(), 16'666'666);
}

}  // namespace
}  // namespace reenact::capture
