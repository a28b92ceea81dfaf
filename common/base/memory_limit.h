// A ceiling on the memory this process may allocate, so that one job that
// asks for too much fails on its own instead of taking the machine (and
// the server beside it) down.
//
// The ceiling is RLIMIT_DATA: since Linux 4.7 it counts the heap and every
// private writable mapping, which is what new, malloc and thread stacks
// take. It is preferred to RLIMIT_AS, which also counts the shared
// libraries and the address space malloc reserves for its arenas (about
// 250 MB here, more with more threads), so that a limit by address space
// would depend on the thread count rather than on what the job holds. An
// allocation past the ceiling fails: std::bad_alloc from new, nullptr from
// malloc.
#pragma once

#include <cstdint>

#include "absl/status/status.h"

namespace reenact {

// Whether LimitDataMemory is in force in this build: not under
// AddressSanitizer or ThreadSanitizer, whose shadow memory (terabytes of
// private writable address space) counts as data, so that any limit would
// stop every allocation.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
inline constexpr bool kDataMemoryLimitEnforced = false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
inline constexpr bool kDataMemoryLimitEnforced = false;
#else
inline constexpr bool kDataMemoryLimitEnforced = true;
#endif
#else
inline constexpr bool kDataMemoryLimitEnforced = true;
#endif

// Lowers this process's RLIMIT_DATA (soft and hard) to `bytes`; never
// raises it (a lower limit already in force stays). InvalidArgument for
// bytes <= 0; Internal when the kernel refuses. Does nothing (OK) where
// !kDataMemoryLimitEnforced.
absl::Status LimitDataMemory(int64_t bytes);

// The current soft RLIMIT_DATA, bytes; -1 when unlimited.
int64_t DataMemoryLimit();

// The machine's physical memory, bytes (0 when it cannot be read).
int64_t PhysicalMemoryBytes();

}  // namespace reenact
