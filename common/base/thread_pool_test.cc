#include "common/base/thread_pool.h"

#include <atomic>
#include <vector>

#include <gtest/gtest.h>

namespace reenact {
namespace {

TEST(ThreadPool, ParallelForVisitsEveryIndexOnce) {
  ThreadPool pool(3);
  std::vector<std::atomic<int>> visits(1000);
  pool.ParallelFor(0, 1000, [&](int i) { visits[i]++; });
  for (const auto& v : visits) EXPECT_EQ(v.load(), 1);
}

TEST(ThreadPool, WaitReturnsAfterScheduledTasks) {
  ThreadPool pool(2);
  std::atomic<int> sum{0};
  for (int i = 1; i <= 100; ++i) pool.Schedule([&, i] { sum += i; });
  pool.Wait();
  EXPECT_EQ(sum.load(), 5050);
}

}  // namespace
}  // namespace reenact
