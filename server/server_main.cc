// reenact-server: the take store and its services. See server/server.h and
// `reenact-server --help`. SIGINT/SIGTERM stop it gracefully (exit 0); usage
// errors exit 2, an unusable data folder or address exits 1.
#include <pthread.h>
#include <signal.h>

#include <iostream>
#include <string>
#include <vector>

#include "server/live/live_body_follower.h"
#include "server/server.h"
#include "server/server_flags.h"

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

int Fail(const absl::Status& status, int code) {
  std::cerr << "reenact-server: " << status.message() << "\n";
  if (code == kExitUsage) std::cerr << reenact::server::kServerUsage << "\n";
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace reenact::server;
  // Signals are taken by sigwait below; every thread inherits this mask.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  const absl::StatusOr<ServerCommandLine> command_line =
      ParseServerCommandLine(std::vector<std::string>(argv + 1, argv + argc));
  if (!command_line.ok()) return Fail(command_line.status(), kExitUsage);
  if (command_line->help) {
    std::cout << kServerUsage << "\n";
    return 0;
  }
  ServerOptions options = command_line->options;
  options.live.factory = MakeLiveBodyFollowerFactory();  // Live jobs of method body.
  absl::StatusOr<std::unique_ptr<Server>> server = Server::Start(options);
  if (!server.ok()) return Fail(server.status(), kExitFailure);
  for (const RecoveredTake& take : (*server)->recovered()) {
    std::cerr << "reenact-server: recovered take " << take.take_id << ": " << take.durable_sequence
              << " frame sets, " << take.size_bytes << " bytes (" << take.dropped_bytes
              << " cut) in " << take.elapsed_s << " s" << (take.problem.empty() ? "" : "; ")
              << take.problem << "\n";
  }
  std::cerr << "reenact-server: listening on " << (*server)->address() << std::endl;
  if (!command_line->port_file.empty()) {
    if (absl::Status written = WritePortFile(command_line->port_file, (*server)->address());
        !written.ok()) {
      (*server)->Shutdown();
      return Fail(written, kExitFailure);
    }
  }
  int signal_number = 0;
  sigwait(&stop_signals, &signal_number);
  std::cerr << "reenact-server: " << (signal_number == SIGINT ? "SIGINT" : "SIGTERM")
            << ", shutting down" << std::endl;
  (*server)->Shutdown();
  std::cerr << "reenact-server: stopped" << std::endl;
  return 0;
}
