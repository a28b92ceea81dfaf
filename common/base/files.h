// Whole-file reads and atomic writes with errors that name the file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact {

// Reads the whole file at `path`. NotFound when it does not exist.
absl::StatusOr<std::string> ReadFileToString(const std::string& path);

// As above for input that may be hostile: InvalidArgument naming the file
// when it holds more than `max_bytes` or is not a regular file (a folder, a
// FIFO, a device), before anything is read.
absl::StatusOr<std::string> ReadFileToString(const std::string& path, uint64_t max_bytes);

// Writes `contents` to `path` through a temporary file and a rename, so that a
// reader never sees a half-written file.
absl::Status WriteFileAtomically(const std::string& path, const std::string& contents);

// The status of a failed file operation, `errno_value` its errno:
// ResourceExhausted for a full disk or quota (ENOSPC, EDQUOT), which callers
// report as such (the fix is to free space, not to retry), DataLoss for
// anything else. The message is `what` and the system's words.
absl::Status FileError(const std::string& what, int errno_value);

// True for FileError's disk-full statuses.
bool IsDiskFull(const absl::Status& status);

// fsync of the folder `dir`, so that files created, renamed or removed in
// it stay so after a power loss. DataLoss naming the folder on failure.
absl::Status SyncDirectory(const std::string& dir);

// Reads exactly `n` bytes at `offset` of the open file `fd` into `out`
// (resized to n), retrying short reads and EINTR. DataLoss naming the byte
// where reading stopped (an error, or the end of the file).
absl::Status ReadAt(int fd, int64_t offset, int64_t n, std::string* out);

// Creates `path` and its parents if missing.
absl::Status CreateDirectories(const std::string& path);

}  // namespace reenact
