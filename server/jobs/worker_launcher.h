// What the job scheduler (server/jobs/job_scheduler.h) asks of a launcher
// of network workers: reenact-server --workers slurm
// (server/jobs/slurm_launcher.h). A header of its own, so that launchers
// need not link the scheduler.
#pragma once

#include <string>

namespace reenact::server {

// Starts workers elsewhere for the jobs that wait (reenact-server --workers
// slurm: server/jobs/slurm_launcher.h). The scheduler's loop calls it; it
// must not block for long.
class WorkerLauncher {
 public:
  virtual ~WorkerLauncher() = default;
  // `queued` jobs wait for a worker now.
  virtual void Reconcile(int queued) = 0;
  // The job that `worker_name` leased was cancelled: stop that worker if it
  // is one of this launcher's.
  virtual void CancelWorker(const std::string& worker_name) = 0;
  // The server stops: withdraw what has not started.
  virtual void Shutdown() = 0;
};

}  // namespace reenact::server
