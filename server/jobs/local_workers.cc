#include "server/jobs/local_workers.h"

#include <chrono>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/log/log.h"
#include "server/jobs/job_scheduler.h"
#include "server/worker/work_agent.h"

namespace reenact::server {

LocalWorkers::LocalWorkers(LocalWorkersOptions options) : options_(std::move(options)) {
  for (int i = 1; i <= options_.count; ++i) threads_.emplace_back([this, i] { Run(i); });
}

LocalWorkers::~LocalWorkers() { Stop(); }

void LocalWorkers::Stop() {
  stop_.store(true);
  for (std::thread& thread : threads_) {
    if (thread.joinable()) thread.join();
  }
}

void LocalWorkers::Run(int index) {
  WorkAgentOptions agent;
  agent.server = "(in process)";
  agent.channel = options_.channel;
  agent.local_take = options_.local_take;
  agent.job_program = options_.job_program;
  agent.scratch_dir = options_.scratch_dir;
  agent.asset_roots = options_.asset_roots;
  agent.memory_limit_mb = options_.memory_limit_mb;
  agent.name = absl::StrCat(kLocalWorkerPrefix, index);
  agent.cancel_grace_s = options_.cancel_grace_s;
  agent.stop_grace_s = options_.stop_grace_s;
  agent.poll_period_s = options_.poll_period_s;
  agent.retry_max_s = 1;
  // In process, beats are cheap: watchers see progress as it comes.
  agent.heartbeat_period_s = 0.1;
  // The server stops: its jobs stay RUNNING and run again when it starts.
  agent.give_back_on_stop = false;
  while (!stop_.load()) {
    // It returns on a stop, or when the server refuses it for good (which
    // its own channel should never see): then it tries again a little later.
    const absl::StatusOr<WorkAgentSummary> ran = RunWorkAgent(agent, stop_);
    if (!ran.ok() && !stop_.load()) {
      log::Error("local_worker_refused",
                 {{"worker", agent.name}, {"error", ran.status().message()}},
                 absl::StrCat("local worker ", agent.name, ": ", ran.status().message()));
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  }
}

}  // namespace reenact::server
