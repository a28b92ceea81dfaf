#include "common/base/memory_limit.h"

#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

#include <gtest/gtest.h>

namespace reenact {
namespace {

constexpr int64_t kMiB = int64_t{1} << 20;

TEST(MemoryLimit, BadLimitsAreRefused) {
  EXPECT_EQ(LimitDataMemory(0).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LimitDataMemory(-5).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_GT(PhysicalMemoryBytes(), 256 * kMiB);
}

// In a child process (the limit cannot be raised again): an allocation
// over the limit is std::bad_alloc, one under it succeeds, and a higher
// limit asked later does not raise it.
TEST(MemoryLimit, AnAllocationOverTheLimitIsBadAllocAndTheLimitIsNeverRaised) {
  if (!kDataMemoryLimitEnforced) GTEST_SKIP() << "sanitizer shadow memory counts as data";
  EXPECT_EXIT(
      {
        if (!LimitDataMemory(512 * kMiB).ok()) std::_Exit(10);
        if (DataMemoryLimit() != 512 * kMiB) std::_Exit(11);
        // Asking for more leaves the lower limit.
        if (!LimitDataMemory(4096 * kMiB).ok() || DataMemoryLimit() != 512 * kMiB) std::_Exit(12);
        // 64 MiB, touched, fits.
        std::vector<char> fits(64 * kMiB, 1);
        if (fits[fits.size() - 1] != 1) std::_Exit(13);
        try {
          std::vector<char> too_much(1024 * kMiB, 1);
          std::_Exit(too_much[0] == 1 ? 14 : 15);
        } catch (const std::bad_alloc&) {
          std::_Exit(0);
        }
      },
      ::testing::ExitedWithCode(0), "");
}

}  // namespace
}  // namespace reenact
