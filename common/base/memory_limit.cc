#include "common/base/memory_limit.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "absl/strings/str_cat.h"

namespace reenact {

absl::Status LimitDataMemory(int64_t bytes) {
  if (bytes <= 0) {
    return absl::InvalidArgumentError(absl::StrCat("a memory limit must be > 0, not ", bytes));
  }
  if (!kDataMemoryLimitEnforced) return absl::OkStatus();
  struct rlimit limit {};
  if (getrlimit(RLIMIT_DATA, &limit) != 0) {
    return absl::InternalError(absl::StrCat("getrlimit(RLIMIT_DATA): ", std::strerror(errno)));
  }
  const auto wanted = static_cast<rlim_t>(bytes);
  if (limit.rlim_cur != RLIM_INFINITY && limit.rlim_cur <= wanted) return absl::OkStatus();
  limit.rlim_cur = wanted;
  if (limit.rlim_max == RLIM_INFINITY || limit.rlim_max > wanted) limit.rlim_max = wanted;
  if (setrlimit(RLIMIT_DATA, &limit) != 0) {
    return absl::InternalError(absl::StrCat("setrlimit(RLIMIT_DATA): ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

int64_t DataMemoryLimit() {
  struct rlimit limit {};
  if (getrlimit(RLIMIT_DATA, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return -1;
  return static_cast<int64_t>(limit.rlim_cur);
}

int64_t PhysicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page_size <= 0) return 0;
  return static_cast<int64_t>(pages) * page_size;
}

}  // namespace reenact
