// What the end-to-end benchmark commands (capture_e2e, live_e2e) share:
// reading small files and the CPU time of the processes they start.
#pragma once

#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>

#include "absl/strings/str_format.h"

namespace reenact::bench {

// The file's text; "" when it cannot be read.
inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// user + system CPU seconds of a running process, from /proc/<pid>/stat.
inline double ProcessCpuSeconds(pid_t pid) {
  const std::string stat = ReadText(absl::StrFormat("/proc/%d/stat", pid));
  const auto close = stat.rfind(')');
  if (close == std::string::npos) return 0.0;
  std::istringstream fields(stat.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

}  // namespace reenact::bench
