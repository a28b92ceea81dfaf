#include "common/base/files.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace reenact {

absl::StatusOr<std::string> ReadFileToString(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    if (err == ENOENT) return absl::NotFoundError(absl::StrCat(path, ": no such file"));
    return absl::UnavailableError(absl::StrCat(path, ": ", std::strerror(err)));
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return absl::DataLossError(absl::StrCat(path, ": read failed"));
  return std::move(buffer).str();
}

absl::StatusOr<std::string> ReadFileToString(const std::string& path, uint64_t max_bytes) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": not a regular file"));
  }
  const uintmax_t bytes = std::filesystem::file_size(path, ec);
  if (!ec && bytes > max_bytes) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": ", bytes, " bytes, more than the ", max_bytes, " bytes allowed"));
  }
  return ReadFileToString(path);
}

absl::Status WriteFileAtomically(const std::string& path, const std::string& contents) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      return absl::PermissionDeniedError(
          absl::StrCat(tmp, ": cannot open for writing: ", std::strerror(errno)));
    }
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) return FileError(absl::StrCat(tmp, ": write failed"), errno);
  }
  // The contents, then the name: after a power loss the file is the old one
  // or the new one, whole.
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    return FileError(absl::StrCat(tmp, ": fsync failed"), error);
  }
  ::close(fd);
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return absl::DataLossError(absl::StrCat(path, ": rename failed: ", ec.message()));
  const std::string parent = std::filesystem::path(path).parent_path().string();
  return SyncDirectory(parent.empty() ? "." : parent);
}

absl::Status FileError(const std::string& what, int errno_value) {
  const std::string message = absl::StrCat(what, ": ", std::strerror(errno_value));
  if (errno_value == ENOSPC || errno_value == EDQUOT) {
    return absl::ResourceExhaustedError(absl::StrCat(message, " (disk full)"));
  }
  return absl::DataLossError(message);
}

bool IsDiskFull(const absl::Status& status) {
  return absl::IsResourceExhausted(status) && absl::EndsWith(status.message(), "(disk full)");
}

absl::Status SyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return FileError(absl::StrCat("cannot open folder ", dir, " to sync it"), errno);
  const int synced = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (synced != 0) return FileError(absl::StrCat("fsync of folder ", dir), error);
  return absl::OkStatus();
}

absl::Status CreateDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(path, ": ", ec.message()));
  return absl::OkStatus();
}

absl::Status ReadAt(int fd, int64_t offset, int64_t n, std::string* out) {
  out->resize(static_cast<size_t>(n));
  int64_t done = 0;
  while (done < n) {
    const ssize_t got =
        ::pread(fd, out->data() + done, static_cast<size_t>(n - done), offset + done);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      return absl::DataLossError(absl::StrCat("reading failed at byte ", offset + done, ": ",
                                              got < 0 ? std::strerror(errno) : "end of file"));
    }
    done += got;
  }
  return absl::OkStatus();
}

}  // namespace reenact
