// Shared pieces of the libFuzzer targets in this folder.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace reenact::fuzz {

// The fuzzer's input as text.
inline std::string_view AsView(const uint8_t* data, size_t size) {
  return std::string_view(reinterpret_cast<const char*>(data), size);
}

// Stops the process with `what` on stderr: a broken invariant of the code
// under test, which libFuzzer then records as a crash.
[[noreturn]] inline void Fail(const char* what) {
  std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
  std::abort();
}

// A folder of this process ($TMPDIR or /tmp, then "reenact-fuzz-<pid>"),
// created on first use and removed when the process exits normally.
inline const std::string& ScratchDir() {
  static const std::string* dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path base = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
    auto* path = new std::string((base / ("reenact-fuzz-" + std::to_string(::getpid()))).string());
    std::error_code ec;
    std::filesystem::create_directories(*path, ec);
    if (ec) Fail("cannot create the scratch folder");
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(ScratchDir(), ignored);
    });
    return path;
  }();
  return *dir;
}

// Writes `bytes` to `path`, creating its folders.
inline void WriteFile(const std::string& path, std::string_view bytes) {
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) Fail("cannot create a file");
  const bool written =
      bytes.empty() || std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size();
  if (std::fclose(file) != 0 || !written) Fail("cannot write a file");
}

// Writes `bytes` to `name` (a path relative to ScratchDir()) and returns the
// file's path.
inline std::string WriteScratchFile(const std::string& name, std::string_view bytes) {
  const std::string path = ScratchDir() + "/" + name;
  WriteFile(path, bytes);
  return path;
}

// Splits `bytes` at its first NUL byte: (before, after), after being nullopt
// when there is none. Targets whose parser reads two files take both from one
// input this way (the text formats hold no NUL).
inline std::pair<std::string_view, std::optional<std::string_view>> SplitAtNul(
    std::string_view bytes) {
  const size_t nul = bytes.find('\0');
  if (nul == std::string_view::npos) return {bytes, std::nullopt};
  return {bytes.substr(0, nul), bytes.substr(nul + 1)};
}

}  // namespace reenact::fuzz
