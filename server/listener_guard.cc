#include "server/listener_guard.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <utility>

#include <grpc/support/log.h>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/log/log.h"

namespace reenact::server {
namespace {

std::mutex& CallbackMutex() {
  static std::mutex mutex;
  return mutex;
}

std::function<void()>& ListenerStopped() {
  static std::function<void()> callback;
  return callback;
}

void OnGrpcLog(gpr_log_func_args* args) {
  if (args == nullptr || args->message == nullptr) return;
  const std::string message = args->message;
  if (args->severity == GPR_LOG_SEVERITY_ERROR) {
    log::Error("grpc_error",
               {{"file", args->file != nullptr ? args->file : ""}, {"line", args->line}}, message);
  }
  if (!IsListenerFailure(message)) return;
  std::function<void()> callback;
  {
    std::lock_guard<std::mutex> lock(CallbackMutex());
    callback = ListenerStopped();
  }
  if (callback) callback();
}

}  // namespace

int64_t RaiseDescriptorLimit() {
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) != 0) return -1;
  if (limit.rlim_cur < limit.rlim_max) {
    rlimit raised = limit;
    raised.rlim_cur = limit.rlim_max;
    if (::setrlimit(RLIMIT_NOFILE, &raised) == 0) limit = raised;
  }
  return limit.rlim_cur == RLIM_INFINITY ? INT64_MAX : static_cast<int64_t>(limit.rlim_cur);
}

int64_t OpenDescriptorCount() {
  DIR* dir = ::opendir("/proc/self/fd");
  if (dir == nullptr) return -1;
  int64_t count = 0;
  while (const dirent* entry = ::readdir(dir)) {
    if (entry->d_name[0] != '.') ++count;
  }
  ::closedir(dir);
  return count - 1;  // The directory's own descriptor.
}

bool IsListenerFailure(const std::string& message) {
  return absl::StrContains(message, "Failed accept4");
}

void WatchGrpcLog(std::function<void()> listener_stopped) {
  {
    std::lock_guard<std::mutex> lock(CallbackMutex());
    ListenerStopped() = std::move(listener_stopped);
  }
  gpr_set_log_function(&OnGrpcLog);
}

std::vector<std::string> PinnedArguments(const std::vector<std::string>& argv,
                                         const std::map<std::string, std::string>& pinned) {
  std::vector<std::string> out;
  out.reserve(argv.size());
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& arg = argv[i];
    bool replaced = false;
    for (const auto& [flag, value] : pinned) {
      if (i > 0 && arg == flag && i + 1 < argv.size()) {
        out.push_back(arg);
        out.push_back(value);
        ++i;
        replaced = true;
      } else if (i > 0 && absl::StartsWith(arg, flag + "=")) {
        out.push_back(absl::StrCat(flag, "=", value));
        replaced = true;
      }
      if (replaced) break;
    }
    if (!replaced) out.push_back(arg);
  }
  return out;
}

std::string ExecSelf(const std::vector<std::string>& argv) {
  if (argv.empty()) return "no program to start";
  // Descriptors the new image must not inherit: sockets of clients, files.
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    const int own = ::dirfd(dir);
    while (const dirent* entry = ::readdir(dir)) {
      char* end = nullptr;
      const long fd = std::strtol(entry->d_name, &end, 10);
      if (end == entry->d_name || *end != '\0' || fd <= 2 || fd == own) continue;
      const int flags = ::fcntl(static_cast<int>(fd), F_GETFD);
      if (flags >= 0) ::fcntl(static_cast<int>(fd), F_SETFD, flags | FD_CLOEXEC);
    }
    ::closedir(dir);
  }
  sigset_t none;
  sigemptyset(&none);
  pthread_sigmask(SIG_SETMASK, &none, nullptr);
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  ::execv("/proc/self/exe", args.data());
  return std::strerror(errno);
}

}  // namespace reenact::server
