#include "server/jobs/job_scheduler.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/files.h"
#include "common/base/memory_limit.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "common/metrics/metrics.h"
#include "server/metrics/server_metrics.h"
#include "server/store/frame_set_validation.h"
#include "server/worker/worker_protocol.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

absl::Status DiskFullRefusal() {
  return absl::ResourceExhaustedError(
      "the server's disk is full: the job was not stored; delete takes or reenactments and "
      "submit again");
}

// Option keys and values Submit accepts.
constexpr size_t kMaxOptionKeyChars = 64;
constexpr size_t kMaxOptionValueChars = 4096;
constexpr int kMaxOptions = 64;

std::string Truncate(std::string text, size_t max_chars) {
  if (text.size() > max_chars) text = text.substr(0, max_chars) + "...";
  return text;
}

absl::StatusOr<std::string> DefaultWorkerPath() {
  std::error_code error;
  const fs::path self = fs::read_symlink("/proc/self/exe", error);
  if (error) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot find the server's own path (/proc/self/exe: ", error.message(),
                     "); give the worker's path"));
  }
  return (self.parent_path() / "reenact-worker").string();
}

absl::Status ValidateOptions(const google::protobuf::Map<std::string, std::string>& options) {
  if (options.size() > static_cast<size_t>(kMaxOptions)) {
    return absl::InvalidArgumentError(
        absl::StrCat(options.size(), " options; at most ", kMaxOptions));
  }
  for (const auto& [key, value] : options) {
    if (key.empty() || key.size() > kMaxOptionKeyChars) {
      return absl::InvalidArgumentError(absl::StrCat("option name \"", Truncate(key, 80),
                                                     "\" must be 1..", kMaxOptionKeyChars,
                                                     " characters"));
    }
    if (value.size() > kMaxOptionValueChars) {
      return absl::InvalidArgumentError(
          absl::StrCat("option ", key, " is longer than ", kMaxOptionValueChars, " characters"));
    }
  }
  return absl::OkStatus();
}

// Whether the job asks to follow its take (SubmitJobRequest.live).
// InvalidArgument for live with a method that cannot follow a take, or for
// "live" among the options (it is the request's own field).
absl::StatusOr<bool> LiveRequest(const v1::SubmitJobRequest& request,
                                 const methods::MethodSpec& spec) {
  if (request.options().contains("live")) {
    return absl::InvalidArgumentError(
        "live is not an option: ask with SubmitJobRequest.live (reenact jobs submit --live)");
  }
  if (request.live() && !spec.live) {
    return absl::InvalidArgumentError(
        absl::StrCat("method ", spec.name, " cannot follow a take while it is recorded (live)"));
  }
  return request.live();
}

// One line for the end of a job: job_finished, job_failed or
// job_cancelled; and its times in the reenact_job_duration_seconds and
// reenact_job_wait_seconds histograms.
void LogJobEnd(const v1::Job& job) {
  const double seconds =
      job.started_unix_ns() > 0 && job.finished_unix_ns() >= job.started_unix_ns()
          ? NsToSeconds(job.finished_unix_ns() - job.started_unix_ns())
          : 0.0;
  const std::string outcome = job.state() == v1::JOB_STATE_SUCCEEDED   ? "succeeded"
                              : job.state() == v1::JOB_STATE_CANCELLED ? "cancelled"
                                                                       : "failed";
  metrics::Registry& registry = metrics::DefaultRegistry();
  if (job.started_unix_ns() > 0) {
    registry
        .GetHistogram("reenact_job_duration_seconds",
                      "Time from a job's start on a worker to its end, by method and outcome.",
                      {{"method", job.method()}, {"outcome", outcome}}, metrics::JobSecondsBounds())
        .Observe(seconds);
  }
  // A job cancelled in the queue waited until then.
  const int64_t waited_until_ns =
      job.started_unix_ns() > 0 ? job.started_unix_ns() : job.finished_unix_ns();
  if (job.submitted_unix_ns() > 0 && waited_until_ns >= job.submitted_unix_ns()) {
    registry
        .GetHistogram("reenact_job_wait_seconds",
                      "Time from a job's submission to its start (or end, if it never started), "
                      "by method.",
                      {{"method", job.method()}}, metrics::JobSecondsBounds())
        .Observe(NsToSeconds(waited_until_ns - job.submitted_unix_ns()));
  }
  const log::Field fields[] = {{"job_id", job.job_id()}, {"take_id", job.take_id()},
                               {"method", job.method()}, {"attempts", job.attempts()},
                               {"seconds", seconds},     {"reenactment_id", job.reenactment_id()},
                               {"error", job.error()}};
  switch (job.state()) {
    case v1::JOB_STATE_SUCCEEDED:
      log::Info("job_finished", fields, absl::StrCat("job ", job.job_id(), " succeeded"));
      break;
    case v1::JOB_STATE_CANCELLED:
      log::Info("job_cancelled", fields, absl::StrCat("job ", job.job_id(), " was cancelled"));
      break;
    default:
      log::Warn("job_failed", fields, absl::StrCat("job ", job.job_id(), " failed"));
  }
}

}  // namespace

absl::Status JobSchedulerOptions::Validate() const {
  if (concurrency < 0) return absl::InvalidArgumentError("job concurrency must be >= 0");
  if (!(poll_period_s > 0 && poll_period_s <= 10)) {
    return absl::InvalidArgumentError("poll_period_s must be in (0, 10]");
  }
  if (!(cancel_grace_s >= 0) || !(shutdown_grace_s >= 0)) {
    return absl::InvalidArgumentError("grace periods must be >= 0 seconds");
  }
  if (!(eta_window_s > 0)) return absl::InvalidArgumentError("eta_window_s must be > 0");
  if (!(job_retention_days >= 0) || !(retention_sweep_period_s > 0)) {
    return absl::InvalidArgumentError(
        "job_retention_days must be >= 0 and retention_sweep_period_s > 0");
  }
  if (min_free_bytes < 0) return absl::InvalidArgumentError("min_free_bytes must be >= 0");
  if (!(lease_ttl_s >= 0.5 && lease_ttl_s <= 3600)) {
    return absl::InvalidArgumentError("lease_ttl_s must be in [0.5, 3600]");
  }
  return store.Validate();
}

JobScheduler::JobScheduler(const JobSchedulerOptions& options, std::string jobs_dir, JobStore* jobs,
                           TakeStore* takes, ReenactmentStore* reenactments, LiveHub* live)
    : options_(options),
      jobs_dir_(std::move(jobs_dir)),
      jobs_(jobs),
      takes_(takes),
      reenactments_(reenactments),
      live_jobs_(live, jobs, mu_,
                 {.publish = [this](const v1::Job& job, std::vector<std::string> logs,
                                    bool last) { Publish(job, std::move(logs), last); },
                  .end =
                      [this](const std::string& job_id, v1::JobState state,
                             const std::string& error, std::vector<std::string> logs) {
                        EndJob(job_id, state, error, "", std::move(logs));
                      },
                  .log_end = &LogJobEnd,
                  .wake_locked =
                      [this] {
                        wake_pending_ = true;
                        wake_.notify_all();
                      }}) {}

absl::StatusOr<std::unique_ptr<JobScheduler>> JobScheduler::Start(
    const JobSchedulerOptions& options, const std::string& jobs_dir, JobStore* jobs,
    TakeStore* takes, ReenactmentStore* reenactments, LiveHub* live) {
  RETURN_IF_ERROR(options.Validate());
  std::unique_ptr<JobScheduler> scheduler(
      new JobScheduler(options, jobs_dir, jobs, takes, reenactments, live));
  std::error_code error;
  fs::create_directories(jobs_dir, error);
  if (error) {
    return absl::UnavailableError(
        absl::StrCat("cannot create the jobs folder ", jobs_dir, ": ", error.message()));
  }
  if (options.worker_path.empty()) {
    ASSIGN_OR_RETURN(scheduler->worker_path_, DefaultWorkerPath());
  } else {
    scheduler->worker_path_ = options.worker_path;
  }
  scheduler->concurrency_ =
      options.concurrency > 0 ? options.concurrency
                              : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  if (options.job_memory_mb >= 0) {
    scheduler->job_memory_mb_ = options.job_memory_mb;
  } else {
    const int64_t machine_mb = PhysicalMemoryBytes() >> 20;
    scheduler->job_memory_mb_ =
        std::max<int64_t>(1024, machine_mb * 3 / 4 / std::max(1, scheduler->concurrency_));
  }
  RETURN_IF_ERROR(jobs->RequeueUnfinished().status());
  for (const v1::Job& job : jobs->Queued()) {
    if (job.segments() == 0) {
      scheduler->queue_.push_back(job.job_id());
      continue;
    }
    // A segmented job: its parts that wait, and those whose predecessors
    // finished before the server stopped.
    std::lock_guard<std::mutex> lock(scheduler->mu_);
    scheduler->AdvancePartsLocked(job.job_id());
    const absl::StatusOr<v1::Job> advanced = jobs->Get(job.job_id());
    if (!advanced.ok()) continue;
    for (const v1::JobPart& part : advanced->parts()) {
      const std::string unit = UnitId(job.job_id(), part.name());
      if (part.state() == v1::JOB_STATE_QUEUED &&
          std::find(scheduler->queue_.begin(), scheduler->queue_.end(), unit) ==
              scheduler->queue_.end()) {
        scheduler->queue_.push_back(unit);
      }
    }
  }
  scheduler->finisher_ = std::make_unique<ThreadPool>(1);
  scheduler->thread_ = std::thread([s = scheduler.get()] { s->Loop(); });
  return scheduler;
}

JobScheduler::~JobScheduler() { Shutdown(); }

absl::StatusOr<v1::Job> JobScheduler::Submit(const v1::SubmitJobRequest& request,
                                             const std::string& submitter) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_) return absl::UnavailableError("the server is shutting down; submit later");
  }
  RETURN_IF_ERROR(ValidateTakeId(request.take_id()));
  if (options_.methods.empty()) {
    return absl::FailedPreconditionError("this server runs no reconstruction methods");
  }
  const methods::MethodSpec* spec = methods::FindMethod(options_.methods, request.method());
  if (spec == nullptr) return methods::UnknownMethodError(options_.methods, request.method());
  RETURN_IF_ERROR(ValidateOptions(request.options()));
  ASSIGN_OR_RETURN(const bool live, LiveRequest(request, *spec));
  if (request.segments() < 0 || request.segments() > kMaxSegments) {
    return absl::InvalidArgumentError(
        absl::StrCat("segments must be 0 to ", kMaxSegments, ", got ", request.segments()));
  }
  const bool segmented = request.segments() > 1;
  if (segmented && !spec->segmentable) {
    std::vector<std::string> segmentable;
    for (const methods::MethodSpec& m : options_.methods) {
      if (m.segmentable) segmentable.push_back(m.name);
    }
    return absl::InvalidArgumentError(absl::StrCat(
        "method ", spec->name, " cannot split a take across workers (segments); methods that can: ",
        segmentable.empty() ? "none" : absl::StrJoin(segmentable, ", ")));
  }
  if (segmented && live) {
    return absl::InvalidArgumentError("a live job follows its take whole; leave out segments");
  }
  const std::map<std::string, std::string> all_options(request.options().begin(),
                                                       request.options().end());
  RETURN_IF_ERROR(methods::CheckOptions(*spec, all_options));
  if (options_.check_job) {
    RETURN_IF_ERROR(options_.check_job(request.method(), WorkerOptions(spec, request.options())));
  }
  ASSIGN_OR_RETURN(const v1::Take take, takes_->GetTake(request.take_id()));
  const bool recording = take.state() == v1::TAKE_STATE_RECORDING;
  if (job_memory_mb_ > 0 && options_.job_memory && !recording) {
    // A take still recording has no size yet; its worker runs under the
    // limit all the same.
    ASSIGN_OR_RETURN(
        const int64_t estimate,
        options_.job_memory(request.method(), WorkerOptions(spec, request.options()), take));
    const int64_t estimate_mb = (estimate + (int64_t{1} << 20) - 1) >> 20;
    if (estimate_mb > job_memory_mb_) {
      const absl::Status over = absl::ResourceExhaustedError(absl::StrCat(
          "this job would take about ", estimate_mb, " MiB, over the server's ", job_memory_mb_,
          " MiB a job (--job-memory-mb); ask for smaller textures, meshes or voxels, or fewer "
          "frames (max_frames)"));
      LimitHit("job_memory",
               {{"take_id", request.take_id()},
                {"method", request.method()},
                {"estimate_mb", estimate_mb},
                {"budget_mb", job_memory_mb_}},
               over.message());
      return over;
    }
  }
  if (recording) RETURN_IF_ERROR(live_jobs_.CheckFollowable(take.take_id(), live));
  v1::Job job;
  job.set_take_id(request.take_id());
  job.set_method(request.method());
  *job.mutable_options() = request.options();
  job.set_submitted_by(submitter);
  job.set_live(live && recording);
  if (segmented) {
    job.set_segments(request.segments());
    for (v1::JobPart& part : NewParts(request.segments())) *job.add_parts() = std::move(part);
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (stopping_) return absl::UnavailableError("the server is shutting down; submit later");
  // A live job starts now or never: it takes one of the --jobs slots, like a
  // worker, and is refused when none is free.
  if (recording && BusyLocked() >= concurrency_) {
    const absl::Status busy = absl::ResourceExhaustedError(
        absl::StrCat("all ", concurrency_,
                     " job slots (--jobs) are busy; follow the take later, or submit "
                     "the job once the take is complete"));
    LimitHit(
        "job_slots",
        {{"take_id", request.take_id()}, {"method", request.method()}, {"slots", concurrency_}},
        busy.message());
    return busy;
  }
  if (options_.max_queued_jobs > 0) {
    const std::map<v1::JobState, int64_t> counts = jobs_->CountByState();
    const auto queued = counts.find(v1::JOB_STATE_QUEUED);
    if (queued != counts.end() && queued->second >= options_.max_queued_jobs) {
      const absl::Status full = absl::ResourceExhaustedError(
          absl::StrCat("the job queue is full (", queued->second,
                       " jobs wait, --max-queued-jobs); submit once some have run"));
      LimitHit("queued_jobs", {{"take_id", request.take_id()}, {"max", options_.max_queued_jobs}},
               full.message());
      return full;
    }
  }
  if (!submitter.empty() && options_.max_queued_jobs_per_token > 0) {
    const int64_t queued = jobs_->CountQueuedBy(submitter);
    if (queued >= options_.max_queued_jobs_per_token) {
      const absl::Status full = absl::ResourceExhaustedError(absl::StrCat(
          "this token has ", queued, " jobs waiting, its most (--max-queued-jobs-per-token ",
          options_.max_queued_jobs_per_token, "); submit once some have run"));
      LimitHit("queued_jobs_per_token",
               {{"take_id", request.take_id()},
                {"token", submitter},
                {"max", options_.max_queued_jobs_per_token}},
               full.message());
      return full;
    }
  }
  if (options_.min_free_bytes > 0) {
    const double free_bytes = metrics::FreeDiskBytes(jobs_dir_);
    if (free_bytes >= 0 && free_bytes < static_cast<double>(options_.min_free_bytes)) {
      log::Error("job_not_stored", {{"take_id", request.take_id()}, {"free_bytes", free_bytes}},
                 "a submitted job was refused: the jobs folder's disk is full");
      return DiskFullRefusal();
    }
  }
  absl::StatusOr<v1::Job> inserted = jobs_->Insert(std::move(job));
  if (!inserted.ok()) {
    log::Error("job_not_stored",
               {{"take_id", request.take_id()}, {"error", inserted.status().message()}},
               "a submitted job could not be stored");
    if (IsDiskFull(inserted.status())) return DiskFullRefusal();
    return absl::UnavailableError("the server could not store the job (its log says why)");
  }
  job = std::move(*inserted);
  log::Info("job_queued",
            {{"job_id", job.job_id()},
             {"take_id", job.take_id()},
             {"method", job.method()},
             {"live", live && recording}},
            absl::StrCat("job ", job.job_id(), " queued"));
  if (recording) {
    absl::StatusOr<v1::Job> following = live_jobs_.FollowLocked(job);
    // FailedPrecondition: the take ended meanwhile; the job runs offline.
    if (following.ok() || !absl::IsFailedPrecondition(following.status())) return following;
  }
  queue_.push_back(segmented ? UnitId(job.job_id(), "prepare") : job.job_id());
  wake_pending_ = true;
  wake_.notify_all();
  return job;
}

absl::StatusOr<v1::Job> JobScheduler::Cancel(const std::string& job_id) {
  RETURN_IF_ERROR(ValidateJobId(job_id));
  v1::Job job;
  std::vector<std::string> leased_by;  // The network workers that held the job.
  {
    std::lock_guard<std::mutex> lock(mu_);
    ASSIGN_OR_RETURN(job, jobs_->Get(job_id));
    std::string error;
    if (job.segments() > 0 && !IsFinished(job.state())) {
      leased_by = DropUnitsLocked(job_id);
      error = leased_by.empty()
                  ? std::string("cancelled by a client")
                  : absl::StrCat("cancelled by a client (workers ", absl::StrJoin(leased_by, ", "),
                                 " were leasing its parts)");
    } else if (job.state() == v1::JOB_STATE_RUNNING) {
      auto it = running_.find(job_id);
      if (it != running_.end()) {
        // Its worker hears it at its next heartbeat (Aborted) and stops; a
        // launcher's worker (a Slurm job) is also cancelled there.
        error = absl::StrCat("cancelled by a client (worker ", it->second->worker_name,
                             " was leasing it)");
        leased_by.push_back(it->second->worker_name);
        ReleaseLocked(it->second->lease_id);
      } else {
        error = live_jobs_.StopLocked(job_id);
        if (error.empty()) return job;
      }
    } else if (job.state() == v1::JOB_STATE_QUEUED) {
      queue_.erase(std::remove(queue_.begin(), queue_.end(), job_id), queue_.end());
      error = "cancelled by a client before it started";
    } else {
      return job;
    }
    ASSIGN_OR_RETURN(job, jobs_->Mutate(job_id, [&](v1::Job& j) {
      EndAttempt(j, "cancelled");
      for (v1::JobPart& part : *j.mutable_parts()) {
        if (IsFinished(part.state())) continue;
        EndAttempt(part, "cancelled");
        part.set_state(v1::JOB_STATE_CANCELLED);
      }
      j.set_state(v1::JOB_STATE_CANCELLED);
      j.set_finished_unix_ns(WallNowNs());
      j.set_error(error);
      j.mutable_progress()->set_eta_s(-1);
    }));
  }
  if (options_.launcher) {
    for (const std::string& worker : leased_by) options_.launcher->CancelWorker(worker);
  }
  LogJobEnd(job);
  Publish(job, {}, /*last=*/true);
  return job;
}

absl::StatusOr<v1::Job> JobScheduler::Get(const std::string& job_id) const {
  RETURN_IF_ERROR(ValidateJobId(job_id));
  return jobs_->Get(job_id);
}

std::vector<v1::Job> JobScheduler::List(v1::JobState state, const std::string& take_id) const {
  return jobs_->List(state, take_id);
}

absl::Status JobScheduler::CheckNoUnfinishedJobs(const std::string& take_id) const {
  for (const v1::Job& job : jobs_->List(v1::JOB_STATE_UNSPECIFIED, take_id)) {
    if (!IsFinished(job.state())) {
      return absl::FailedPreconditionError(absl::StrCat(
          "job ", job.job_id(), " of take ", take_id,
          " has not finished; cancel it first (reenact jobs cancel ", job.job_id(), ")"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<int64_t> JobScheduler::DeleteFinishedJob(const v1::Job& job) {
  int64_t freed = 0;
  const fs::path dir = fs::path(jobs_dir_) / job.job_id();
  std::error_code error;
  for (fs::recursive_directory_iterator it(dir, error), end; !error && it != end;
       it.increment(error)) {
    if (it->is_regular_file(error)) freed += static_cast<int64_t>(it->file_size(error));
  }
  error.clear();
  fs::remove_all(dir, error);
  if (error) {
    return absl::UnavailableError(
        absl::StrCat("deleting the folder of job ", job.job_id(), ": ", error.message()));
  }
  RETURN_IF_ERROR(jobs_->Delete(job.job_id()));
  return freed;
}

absl::StatusOr<int64_t> JobScheduler::DeleteJobsOfTake(const std::string& take_id) {
  int64_t freed = 0;
  for (const v1::Job& job : jobs_->List(v1::JOB_STATE_UNSPECIFIED, take_id)) {
    if (!IsFinished(job.state())) continue;  // Submitted since the check: left alone.
    ASSIGN_OR_RETURN(const int64_t bytes, DeleteFinishedJob(job));
    freed += bytes;
  }
  return freed;
}

absl::StatusOr<int> JobScheduler::DeleteJobsFinishedBefore(int64_t cutoff_unix_ns) {
  int deleted = 0;
  for (const v1::Job& job : jobs_->List()) {
    if (!IsFinished(job.state()) || job.finished_unix_ns() == 0 ||
        job.finished_unix_ns() >= cutoff_unix_ns) {
      continue;
    }
    ASSIGN_OR_RETURN(const int64_t freed, DeleteFinishedJob(job));
    log::Info("job_expired",
              {{"job_id", job.job_id()}, {"take_id", job.take_id()}, {"bytes", freed}},
              absl::StrCat("job ", job.job_id(), " is past its retention: folder and row deleted"));
    ++deleted;
  }
  return deleted;
}

void JobScheduler::SweepRetention() {
  if (options_.job_retention_days <= 0) return;
  const int64_t now_ns = SteadyNowNs();
  if (last_sweep_ns_ != 0 &&
      now_ns - last_sweep_ns_ < SecondsToNs(options_.retention_sweep_period_s)) {
    return;
  }
  last_sweep_ns_ = now_ns;
  const int64_t cutoff =
      WallNowNs() - static_cast<int64_t>(options_.job_retention_days * 86400.0 * 1e9);
  if (absl::StatusOr<int> swept = DeleteJobsFinishedBefore(cutoff); !swept.ok()) {
    log::Warn("retention_failed", {{"error", swept.status().message()}},
              "old job folders could not all be deleted; the next sweep tries again");
  }
}

absl::StatusOr<uint64_t> JobScheduler::Watch(const std::string& job_id, JobEventCallback callback) {
  RETURN_IF_ERROR(ValidateJobId(job_id));
  std::lock_guard<std::mutex> lock(watch_mu_);
  if (watches_closed_) return absl::UnavailableError("the server is shutting down");
  // Read under watch_mu_: a change written before is seen here, one written
  // after is published to this watch (publishers write, then take the lock).
  ASSIGN_OR_RETURN(const v1::Job job, jobs_->Get(job_id));
  v1::JobEvent event;
  *event.mutable_job() = job;
  if (IsFinished(job.state())) {
    callback(event, /*last=*/true, absl::OkStatus());
    return 0;
  }
  callback(event, /*last=*/false, absl::OkStatus());
  const uint64_t id = next_watch_id_++;
  watchers_.emplace(id, Watcher{job_id, std::move(callback)});
  return id;
}

void JobScheduler::Unwatch(uint64_t watch_id) {
  std::lock_guard<std::mutex> lock(watch_mu_);
  watchers_.erase(watch_id);
}

std::string JobScheduler::WithoutServerPaths(std::string text) const {
  // The data folder (takes, jobs, scratch) is the server's business: a
  // client reads "DATA/takes/ID.mcap", never where the server keeps it.
  const std::string root = std::filesystem::path(jobs_dir_).parent_path().string();
  if (root.size() <= 1) return text;
  for (size_t at = text.find(root); at != std::string::npos; at = text.find(root, at + 4)) {
    text.replace(at, root.size(), "DATA");
  }
  return text;
}

void JobScheduler::Publish(const v1::Job& job, std::vector<std::string> logs, bool last) {
  v1::JobEvent event;
  *event.mutable_job() = job;
  event.mutable_job()->set_error(WithoutServerPaths(job.error()));
  for (std::string& line : logs) event.add_log_lines(WithoutServerPaths(std::move(line)));
  std::lock_guard<std::mutex> lock(watch_mu_);
  for (auto it = watchers_.begin(); it != watchers_.end();) {
    if (it->second.job_id != job.job_id()) {
      ++it;
      continue;
    }
    it->second.callback(event, last, absl::OkStatus());
    it = last ? watchers_.erase(it) : std::next(it);
  }
}

void JobScheduler::Shutdown() {
  std::call_once(shutdown_once_, [this] {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopping_ = true;
      wake_.notify_all();
    }
    if (thread_.joinable()) thread_.join();  // The loop stops the workers.
    if (finisher_) finisher_->Wait();
    std::lock_guard<std::mutex> lock(watch_mu_);
    watches_closed_ = true;
    const absl::Status end =
        absl::UnavailableError("the server is shutting down; the job runs again when it restarts");
    for (auto& [id, watcher] : watchers_) {
      v1::JobEvent event;
      if (auto job = jobs_->Get(watcher.job_id); job.ok()) *event.mutable_job() = *job;
      watcher.callback(event, /*last=*/true, end);
    }
    watchers_.clear();
  });
}

void JobScheduler::Loop() {
  const auto period = std::chrono::duration<double>(options_.poll_period_s);
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      wake_.wait_for(lock, period, [this] { return stopping_ || wake_pending_; });
      wake_pending_ = false;
      if (stopping_) break;
    }
    live_jobs_.PublishProgress();
    ExpireLeases();
    ServeLeaseWaiters();
    if (options_.launcher) {
      int queued = 0;
      {
        std::lock_guard<std::mutex> lock(mu_);
        queued = static_cast<int>(queue_.size());
      }
      options_.launcher->Reconcile(queued);
    }
    SweepRetention();
  }
  EndLeaseWaiters();
  if (options_.launcher) options_.launcher->Shutdown();
}

bool JobScheduler::StartQueuedLocked(const std::string& job_id, const std::string& worker) {
  // Under mu_, so that Cancel finds the job either queued or running.
  bool was_queued = false;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    was_queued = j.state() == v1::JOB_STATE_QUEUED;
    if (!was_queued) return;
    j.set_state(v1::JOB_STATE_RUNNING);
    j.set_started_unix_ns(WallNowNs());
    j.set_attempts(j.attempts() + 1);
    BeginAttempt(j, worker);
    j.clear_progress();
    j.mutable_progress()->set_stage("starting");
    j.mutable_progress()->set_eta_s(-1);
    j.clear_error();
    j.clear_reenactment_id();
  });
  // A job the catalog cannot write stays QUEUED in memory; it is tried
  // again at the next start.
  if (!job.ok() || !was_queued) return false;
  auto run = std::make_unique<Running>();
  run->job_id = job_id;
  running_[job_id] = std::move(run);
  return true;
}

bool JobScheduler::StartHandoffLocked(const std::string& job_id, const std::string& worker) {
  bool was_running = false;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    was_running = j.state() == v1::JOB_STATE_RUNNING;
    if (!was_running) return;
    j.set_attempts(j.attempts() + 1);
    BeginAttempt(j, worker);
    j.mutable_progress()->set_stage("starting");
    j.mutable_progress()->set_eta_s(-1);
  });
  // A job the catalog cannot write stays RUNNING; the next start queues it.
  if (!job.ok() || !was_running) return false;
  auto run = std::make_unique<Running>();
  run->job_id = job_id;
  running_[job_id] = std::move(run);
  return true;
}

void JobScheduler::Succeed(const std::string& job_id, const std::string& reenactment_id) {
  const absl::StatusOr<v1::ReenactmentSummary> added = reenactments_->Add(reenactment_id);
  if (!added.ok()) {
    EndJob(job_id, v1::JOB_STATE_FAILED,
           absl::StrCat("the worker finished but its reenactment ", reenactment_id,
                        " is not usable: ", added.status().message()));
    return;
  }
  EndJob(job_id, v1::JOB_STATE_SUCCEEDED, "", reenactment_id);
}

void JobScheduler::EndJob(const std::string& job_id, v1::JobState state, const std::string& error,
                          const std::string& reenactment_id, std::vector<std::string> logs) {
  // A segmented job's other parts stop with it.
  if (const absl::StatusOr<v1::Job> current = jobs_->Get(job_id);
      current.ok() && current->segments() > 0) {
    std::vector<std::string> workers;
    {
      std::lock_guard<std::mutex> lock(mu_);
      workers = DropUnitsLocked(job_id);
    }
    if (options_.launcher) {
      for (const std::string& worker : workers) options_.launcher->CancelWorker(worker);
    }
  }
  const std::string outcome = state == v1::JOB_STATE_SUCCEEDED   ? "succeeded"
                              : state == v1::JOB_STATE_CANCELLED ? "cancelled"
                                                                 : "failed";
  auto change = [&](v1::Job& j) {
    EndAttempt(j, outcome);
    for (v1::JobPart& part : *j.mutable_parts()) {
      if (IsFinished(part.state())) continue;
      const bool ran = part.state() == v1::JOB_STATE_RUNNING;
      EndAttempt(part, ran ? outcome : "cancelled");
      // The stitch succeeds with the job; what else was left stops.
      part.set_state(ran && state == v1::JOB_STATE_SUCCEEDED ? v1::JOB_STATE_SUCCEEDED
                                                             : v1::JOB_STATE_CANCELLED);
      if (part.state() == v1::JOB_STATE_SUCCEEDED) part.set_fraction(1.0);
    }
    j.set_state(state);
    j.set_finished_unix_ns(WallNowNs());
    j.set_error(WithoutServerPaths(error));
    j.set_reenactment_id(reenactment_id);
    v1::JobProgress* p = j.mutable_progress();
    if (state == v1::JOB_STATE_SUCCEEDED) {
      p->set_fraction(1.0);
      p->set_eta_s(0);
    } else {
      p->set_eta_s(-1);
    }
  };
  absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, change);
  if (!job.ok()) {
    // The catalog refused the write: the watchers still hear the end.
    absl::StatusOr<v1::Job> current = jobs_->Get(job_id);
    if (!current.ok()) return;
    change(*current);
    current->set_error(absl::StrCat(WithoutServerPaths(error), error.empty() ? "" : "; ",
                                    "the end could not be stored: ", job.status().message()));
    job = std::move(current);
  }
  LogJobEnd(*job);
  Publish(*job, std::move(logs), /*last=*/true);
}

}  // namespace reenact::server
