// The server's own workers (reenact-server --workers local:N): N threads in
// the server process, each the same agent a network worker runs
// (server/worker/work_agent.h), leasing jobs over the Work service through
// the server's in-process channel and running each job as a child process.
// So there is one path for every job, local or not; only the take is read
// in place instead of streamed.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/channel.h>

namespace reenact::server {

struct LocalWorkersOptions {
  int count = 1;
  // The program each job runs as (reenact-worker; tests give a fake).
  std::string job_program;
  // Each job's scratch folder is made below this one.
  std::string scratch_dir;
  std::vector<std::string> asset_roots;
  // Each job's memory ceiling, MiB (WorkAgentOptions::memory_limit_mb).
  int64_t memory_limit_mb = 0;
  double cancel_grace_s = 5;
  double stop_grace_s = 2;
  double poll_period_s = 0.1;
  // The server's in-process channel (with its own workers' token when it
  // checks tokens).
  std::shared_ptr<grpc::Channel> channel;
  // The path of a leased job's take (JobScheduler::LeasedTakePath).
  std::function<std::optional<std::string>(const std::string& lease_id)> local_take;
};

class LocalWorkers {
 public:
  // Starts options.count workers, named "local-1", "local-2", ...
  explicit LocalWorkers(LocalWorkersOptions options);
  // Stop().
  ~LocalWorkers();
  LocalWorkers(const LocalWorkers&) = delete;
  LocalWorkers& operator=(const LocalWorkers&) = delete;

  // Stops the workers: a job under way is stopped (SIGTERM, SIGKILL after
  // the grace period) and given back to the queue. Idempotent.
  void Stop();

 private:
  void Run(int index);

  const LocalWorkersOptions options_;
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
};

}  // namespace reenact::server
