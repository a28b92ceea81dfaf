#include "common/io/av_log.h"

#include <cstdarg>
#include <mutex>
#include <utility>

extern "C" {
#include <libavutil/log.h>
}

namespace reenact {
namespace {

thread_local std::string last_av_error;

void QuietLogCallback(void* context, int level, const char* format, va_list args) {
  if (level > AV_LOG_ERROR) return;
  char line[1024];
  int print_prefix = 1;
  av_log_format_line2(context, level, format, args, line, sizeof(line), &print_prefix);
  last_av_error = line;
  while (!last_av_error.empty() && last_av_error.back() == '\n') last_av_error.pop_back();
}

}  // namespace

void InstallQuietAvLog() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(QuietLogCallback); });
}

std::string TakeLastAvError() { return std::exchange(last_av_error, std::string()); }

}  // namespace reenact
