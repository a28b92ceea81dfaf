// reenact-server: the take store and its services. See server/server.h and
// `reenact-server --help`. SIGINT/SIGTERM stop it gracefully (exit 0); usage
// errors exit 2, an unusable data folder or address exits 1. Usage errors go
// to stderr as text; everything after the flags are read is an event of the
// structured log (common/log/log.h, --log-format, --log-level). SIGHUP reads
// the --auth token file again (tokens added or removed). When the
// gRPC listener stops accepting (out of descriptors), it stops gracefully
// and starts itself again on the same ports (server/listener_guard.h); exit
// 75 when it cannot.
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/log/log.h"
#include "server/http/http_front.h"
#include "server/jobs/slurm_launcher.h"
#include "server/listener_guard.h"
#include "server/live/live_method_follower.h"
#include "server/recon/methods.h"
#include "server/recon/registry.h"
#include "server/server.h"
#include "server/server_flags.h"

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
// EX_TEMPFAIL: stopped to start again, and could not; a supervisor may.
constexpr int kExitRestartFailed = 75;

int Fail(const absl::Status& status, int code) {
  std::cerr << "reenact-server: " << status.message() << "\n";
  if (code == kExitUsage) std::cerr << reenact::server::kServerUsage << "\n";
  return code;
}

// A failure once the log is set up: one error event, then the exit code.
int FailRunning(const absl::Status& status) {
  reenact::log::Error("server_failed", {{"status", absl::StatusCodeToString(status.code())}},
                      status.message());
  return kExitFailure;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace reenact::server;
  // Takes, spools, reenactments and logs hold images of people: everything
  // this process creates is its user's alone (files 0600, folders 0700).
  ::umask(077);
  // Signals are taken by sigwait below; every thread inherits this mask.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  // Raised by the process itself when its gRPC listener has stopped.
  sigaddset(&stop_signals, SIGUSR1);
  // Reads the token file again (systemctl reload).
  sigaddset(&stop_signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  const absl::StatusOr<ServerCommandLine> command_line =
      ParseServerCommandLine(std::vector<std::string>(argv + 1, argv + argc));
  if (!command_line.ok()) return Fail(command_line.status(), kExitUsage);
  if (command_line->help) {
    std::cout << kServerUsage << "\n";
    return 0;
  }
  reenact::log::Configure(command_line->log);
  const int64_t descriptor_limit = RaiseDescriptorLimit();
  WatchGrpcLog([] { ::kill(::getpid(), SIGUSR1); });
  ServerOptions options = command_line->options;
  // Live jobs: each method's own follower, from the registry.
  options.live.factory = MakeLiveMethodFollowerFactory(options.jobs.asset_roots);
  // The methods jobs may name: the registry's, checked as the worker will.
  options.jobs.methods = reenact::recon::MethodSpecs();
  options.jobs.check_job = [roots = options.jobs.asset_roots](
                               const std::string& method,
                               const std::map<std::string, std::string>& job_options) {
    return reenact::recon::CheckJob(method, job_options, roots);
  };
  // Jobs estimated over --job-memory-mb are refused at submit.
  options.jobs.job_memory = [](const std::string& method,
                               const std::map<std::string, std::string>& job_options,
                               const reenact::v1::Take& take) {
    reenact::recon::TakeSize size;
    size.frame_sets = take.frame_set_count();
    size.sensors = std::max(1, take.sensors_size());
    size.file_bytes = take.size_bytes();
    size.duration_s = static_cast<double>(take.duration_ns()) * 1e-9;
    return reenact::recon::JobMemoryBytes(method, job_options, size);
  };
  // --workers slurm: batch jobs that each run one network worker.
  if (!command_line->slurm_config.empty()) {
    absl::StatusOr<reenact::server::SlurmLauncherOptions> slurm =
        reenact::server::ParseSlurmConfig(command_line->slurm_config);
    if (!slurm.ok()) return FailRunning(slurm.status());
    absl::StatusOr<std::unique_ptr<reenact::server::SlurmLauncher>> launcher =
        reenact::server::SlurmLauncher::Create(*slurm);
    if (!launcher.ok()) return FailRunning(launcher.status());
    options.jobs.launcher = std::move(*launcher);
  }
  // Recovered takes are logged by the store as it recovers them
  // (take_recovered).
  absl::StatusOr<std::unique_ptr<Server>> server = Server::Start(options);
  if (!server.ok()) return FailRunning(server.status());
  reenact::log::Info("server_listening",
                     {{"address", (*server)->address()},
                      {"metrics_address", (*server)->metrics_address()},
                      {"data_dir", options.data_dir},
                      {"tls", options.tls.enabled()},
                      {"auth", !options.auth_file.empty()},
                      {"jobs", (*server)->jobs().concurrency()},
                      {"job_memory_mb", (*server)->jobs().job_memory_mb()},
                      {"descriptor_limit", descriptor_limit}},
                     absl::StrCat("listening on ", (*server)->address()));
  if (!command_line->port_file.empty()) {
    if (absl::Status written = WritePortFile(command_line->port_file, (*server)->address());
        !written.ok()) {
      (*server)->Shutdown();
      return FailRunning(written);
    }
  }
  // The tablet app and its API (--http), once the services answer.
  std::unique_ptr<http::HttpFront> web;
  if (!command_line->http.address.empty()) {
    http::HttpFrontOptions web_options;
    web_options.address = command_line->http.address;
    web_options.web_root = command_line->http.web_root.empty() ? http::FindWebRoot("/proc/self/exe")
                                                               : command_line->http.web_root;
    web_options.tls = options.tls;
    web_options.max_connections = command_line->http.max_connections;
    web_options.max_connections_per_client = command_line->http.max_connections_per_client;
    absl::StatusOr<std::unique_ptr<http::HttpFront>> started =
        http::HttpFront::Start(web_options, HttpBackendOf(server->get()));
    if (!started.ok()) {
      (*server)->Shutdown();
      return FailRunning(started.status());
    }
    web = *std::move(started);
    if (web->web_root().empty()) {
      reenact::log::Warn("web_app_missing", {},
                         "the web app is not built (deploy/build.sh builds it with node); "
                         "--http serves the API only");
    }
    reenact::log::Info(
        "http_listening",
        {{"address", web->address()}, {"url", web->url()}, {"web_root", web->web_root()}},
        absl::StrCat("the tablet app is at ", web->url()));
    if (!command_line->http.port_file.empty()) {
      if (absl::Status written = WritePortFile(command_line->http.port_file, web->address());
          !written.ok()) {
        web->Stop();
        (*server)->Shutdown();
        return FailRunning(written);
      }
    }
  }
  int signal_number = 0;
  for (;;) {
    sigwait(&stop_signals, &signal_number);
    if (signal_number != SIGHUP) break;
    if (absl::Status reloaded = (*server)->ReloadTokens(); !reloaded.ok()) {
      reenact::log::Error("tokens_not_reloaded",
                          {{"status", absl::StatusCodeToString(reloaded.code())}},
                          absl::StrCat("SIGHUP: ", reloaded.message()));
    }
  }
  if (signal_number == SIGUSR1) {
    // The gRPC listener accepts no more (listener_guard.h): probes hear
    // NOT_SERVING, the server drains as for SIGTERM, then starts again on
    // the ports it had.
    (*server)->health().SetProblem("grpc_listener_stopped", true);
    reenact::log::Error("grpc_listener_stopped",
                        {{"address", (*server)->address()},
                         {"open_descriptors", OpenDescriptorCount()},
                         {"descriptor_limit", descriptor_limit}},
                        "the gRPC listener stopped accepting (out of descriptors?); stopping "
                        "gracefully to start again");
    std::map<std::string, std::string> pinned = {{"--listen", (*server)->address()}};
    if (!(*server)->metrics_address().empty()) {
      pinned["--metrics"] = (*server)->metrics_address();
    }
    if (web != nullptr) pinned["--http"] = web->address();
    (*server)->Shutdown();
    if (web != nullptr) web->Stop();
    const std::vector<std::string> again =
        PinnedArguments(std::vector<std::string>(argv, argv + argc), pinned);
    reenact::log::Info("server_restarting", {{"address", pinned["--listen"]}},
                       "starting again in this process");
    const std::string why = ExecSelf(again);
    reenact::log::Error("server_restart_failed", {{"error", why}},
                        absl::StrCat("could not start again: ", why));
    return kExitRestartFailed;
  }
  const char* const signal_name = signal_number == SIGINT ? "SIGINT" : "SIGTERM";
  reenact::log::Info("server_stopping", {{"signal", signal_name}},
                     absl::StrCat(signal_name, ", shutting down"));
  (*server)->Shutdown();
  // After the services: live follows have ended, so its threads finish.
  if (web != nullptr) web->Stop();
  reenact::log::Info("server_stopped", {}, "stopped");
  return 0;
}
