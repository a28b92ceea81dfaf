// Live jobs of the job scheduler (server/jobs/job_scheduler.h): a job of a
// take still recording follows the take through the live hub
// (server/live/live_hub.h), RUNNING in stage "following" with the frame sets
// followed as its progress, and is handed back to the scheduler for a worker
// on the stored take once the take stops recording.
//
// The scheduler owns one LiveJobs. Its state is guarded by the scheduler's
// mutex, so that Cancel and the start of the next job find a job in exactly
// one place (queued, following, handed off or running): the methods named
// ...Locked are called with it held, the others take it.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "reenact/v1/jobs_service.pb.h"
#include "server/jobs/job_store.h"
#include "server/live/live_hub.h"

namespace reenact::server {

// The stage of a live job while it follows its take.
inline constexpr char kFollowingStage[] = "following";

class LiveJobs {
 public:
  // What live jobs need of their scheduler.
  struct Hooks {
    // Tells the job's watchers (`last` ends their watches).
    std::function<void(const v1::Job& job, std::vector<std::string> logs, bool last)> publish;
    // Writes the job's end and tells its watchers.
    std::function<void(const std::string& job_id, v1::JobState state, const std::string& error,
                       std::vector<std::string> logs)>
        end;
    // Logs the end of a job that no watcher has seen.
    std::function<void(const v1::Job& job)> log_end;
    // Wakes the scheduler thread (a job waits for a worker); the mutex is
    // held.
    std::function<void()> wake_locked;
  };

  // `hub`: null when the server follows no takes. `hub` and `jobs` must
  // outlive this; the hub must be shut down before it is destroyed.
  LiveJobs(LiveHub* hub, JobStore* jobs, std::mutex& mu, Hooks hooks);
  LiveJobs(const LiveJobs&) = delete;
  LiveJobs& operator=(const LiveJobs&) = delete;

  // Submit of a recording take: OK when the job may follow it (live and a
  // live hub that knows the take), else the error Submit answers.
  absl::Status CheckFollowable(const std::string& take_id, bool live) const;
  // Starts the follow of a stored job and makes it RUNNING.
  // FailedPrecondition when the take stopped recording meanwhile (the job
  // stays QUEUED); other errors fail the job.
  absl::StatusOr<v1::Job> FollowLocked(const v1::Job& job);
  // Jobs following their take (each takes a job slot).
  int FollowingLocked() const { return static_cast<int>(following_.size()); }
  // The oldest job whose take ended and that waits for a worker, taken off
  // the list; none when no job waits.
  std::optional<std::string> NextHandoffLocked();
  // Puts a job NextHandoffLocked gave back at the front (no worker there
  // runs its method).
  void ReturnHandoffLocked(const std::string& job_id) { handoff_.push_front(job_id); }
  bool HasHandoffLocked() const { return !handoff_.empty(); }
  // Cancel of a live job that follows or waits for its worker: stops it and
  // returns the job's error text; "" when the job is neither.
  std::string StopLocked(const std::string& job_id);
  // Stores and publishes the progress the follows noted since the last call
  // (scheduler thread).
  void PublishProgress();

 private:
  // The live hub's callbacks (on its follower threads).
  void Progress(const std::string& job_id, int64_t frames_followed);
  void Ended(const std::string& job_id, const LiveFollowSummary& summary);

  LiveHub* const hub_;
  JobStore* const jobs_;
  std::mutex& mu_;
  const Hooks hooks_;
  // Guarded by mu_: jobs following their take, those whose take ended,
  // waiting for a worker slot, and the frames followed since the last
  // PublishProgress, per job.
  std::set<std::string> following_;
  std::deque<std::string> handoff_;
  std::map<std::string, int64_t> progress_;
};

}  // namespace reenact::server
