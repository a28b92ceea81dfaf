#include "server/jobs/job_scheduler.h"

#include <signal.h>
#include <string.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/body/model_spec.h"
#include "common/log/log.h"
#include "server/server_metrics.h"
#include "server/store/frame_set_validation.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

// Longest log line passed on, and longest quoted in an error.
constexpr size_t kMaxLogLineChars = 2000;
constexpr size_t kMaxQuotedLogChars = 300;
// A worker line longer than this without a newline is cut into pieces.
constexpr size_t kMaxPendingBytes = 1 << 20;
// Option keys and values Submit accepts.
constexpr size_t kMaxOptionKeyChars = 64;
constexpr size_t kMaxOptionValueChars = 4096;
constexpr int kMaxOptions = 64;

std::string Truncate(std::string text, size_t max_chars) {
  if (text.size() > max_chars) text = text.substr(0, max_chars) + "...";
  return text;
}

// "SIGSEGV" for 11.
std::string SignalName(int signal) {
  const char* abbrev = sigabbrev_np(signal);
  return abbrev != nullptr ? absl::StrCat("SIG", abbrev) : absl::StrCat("signal ", signal);
}

std::string UtcNow() {
  const std::time_t seconds = static_cast<std::time_t>(WallNowNs() / kNanosPerSecond);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%d %H:%M:%SZ", &tm);
  return buffer;
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

// Whether `spec` lists `key` as an option only a live follow reads.
bool IsLiveOnly(const methods::MethodSpec* spec, const std::string& key) {
  if (spec == nullptr) return false;
  for (const methods::OptionSpec& option : spec->options) {
    if (option.name == key) return option.live_only;
  }
  return false;
}

// The options the worker gets: the method's live-only ones left out.
std::map<std::string, std::string> WorkerOptions(
    const methods::MethodSpec* spec,
    const google::protobuf::Map<std::string, std::string>& options) {
  std::map<std::string, std::string> worker;
  for (const auto& [key, value] : options) {
    if (!IsLiveOnly(spec, key)) worker.emplace(key, value);
  }
  return worker;
}

std::string OptionsJson(const std::map<std::string, std::string>& options) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : options) j[key] = value;
  return j.dump();
}

// Whether the job asks to follow its take (option live=true). InvalidArgument
// for another value, or live=true with a method that cannot follow a take.
absl::StatusOr<bool> LiveOption(const v1::SubmitJobRequest& request,
                                const methods::MethodSpec& spec) {
  const auto it = request.options().find("live");
  if (it == request.options().end() || it->second == "false") return false;
  if (it->second != "true") {
    return absl::InvalidArgumentError(
        absl::StrCat("option live takes true or false, not \"", Truncate(it->second, 80), "\""));
  }
  if (!spec.live) {
    return absl::InvalidArgumentError(
        absl::StrCat("method ", spec.name, " cannot follow a take live (option live)"));
  }
  return true;
}

// One line for the end of a job: job_finished, job_failed or
// job_cancelled.
void LogJobEnd(const v1::Job& job) {
  const double seconds =
      job.started_unix_ns() > 0 && job.finished_unix_ns() >= job.started_unix_ns()
          ? NsToSeconds(job.finished_unix_ns() - job.started_unix_ns())
          : 0.0;
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

// One worker process and what was read of its output.
struct JobScheduler::Running {
  std::string job_id;
  std::string reenactment_id;
  std::string out_path;
  std::string progress_path;
  std::string log_path;
  // Size of worker.log when this attempt began (earlier attempts' lines are
  // not quoted).
  int64_t log_offset = 0;
  std::unique_ptr<Subprocess> process;
  int64_t read_offset = 0;
  std::string pending;  // An incomplete last line.
  v1::JobProgress progress;
  // (steady ns, fraction) over the ETA window.
  std::deque<std::pair<int64_t, double>> samples;
  std::string worker_error;  // Its {"error"} message.
  std::string last_log;      // Its last {"log"} line.
  // Guarded by mu_.
  bool cancel_requested = false;
  // Scheduler thread only.
  bool term_sent = false;
  bool kill_sent = false;
  int64_t kill_at_ns = 0;
};

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
  return store.Validate();
}

JobScheduler::JobScheduler(const JobSchedulerOptions& options, std::string jobs_dir, JobStore* jobs,
                           TakeStore* takes, ReenactmentStore* reenactments, LiveHub* live)
    : options_(options),
      jobs_dir_(std::move(jobs_dir)),
      jobs_(jobs),
      takes_(takes),
      reenactments_(reenactments),
      live_(live) {}

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
  RETURN_IF_ERROR(jobs->RequeueUnfinished().status());
  for (const v1::Job& job : jobs->Queued()) scheduler->queue_.push_back(job.job_id());
  scheduler->finisher_ = std::make_unique<ThreadPool>(1);
  scheduler->thread_ = std::thread([s = scheduler.get()] { s->Loop(); });
  return scheduler;
}

JobScheduler::~JobScheduler() { Shutdown(); }

absl::StatusOr<v1::Job> JobScheduler::Submit(const v1::SubmitJobRequest& request) {
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
  ASSIGN_OR_RETURN(const bool live, LiveOption(request, *spec));
  const std::map<std::string, std::string> all_options(request.options().begin(),
                                                       request.options().end());
  RETURN_IF_ERROR(methods::CheckOptions(*spec, all_options));
  if (options_.check_job) {
    RETURN_IF_ERROR(options_.check_job(request.method(), WorkerOptions(spec, request.options())));
  }
  if (const auto model = request.options().find("model"); model != request.options().end()) {
    // A model the workers could not find fails now, not after the queue.
    RETURN_IF_ERROR(body::ResolveAssetModelSpec(model->second, options_.asset_roots).status());
  }
  ASSIGN_OR_RETURN(const v1::Take take, takes_->GetTake(request.take_id()));
  const bool recording = take.state() == v1::TAKE_STATE_RECORDING;
  if (recording) RETURN_IF_ERROR(CheckFollowable(take.take_id(), live));
  v1::Job job;
  job.set_take_id(request.take_id());
  job.set_method(request.method());
  *job.mutable_options() = request.options();
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
  absl::StatusOr<v1::Job> inserted = jobs_->Insert(std::move(job));
  if (!inserted.ok()) {
    log::Error("job_not_stored",
               {{"take_id", request.take_id()}, {"error", inserted.status().message()}},
               "a submitted job could not be stored");
    if (IsDiskFull(inserted.status())) {
      return absl::ResourceExhaustedError(
          "the server's disk is full: the job was not stored; delete takes or reenactments "
          "and submit again");
    }
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
    absl::StatusOr<v1::Job> following = FollowLocked(job);
    // FailedPrecondition: the take ended meanwhile; the job runs offline.
    if (following.ok() || !absl::IsFailedPrecondition(following.status())) return following;
  }
  queue_.push_back(job.job_id());
  wake_pending_ = true;
  wake_.notify_all();
  return job;
}

absl::Status JobScheduler::CheckFollowable(const std::string& take_id, bool live) const {
  if (!live) {
    return absl::FailedPreconditionError(absl::StrCat(
        "take ", take_id,
        " is still being recorded; submit the job once it is complete (or, for the body "
        "model, with option live=true to follow it now)"));
  }
  if (live_ == nullptr || !live_->enabled()) {
    return absl::FailedPreconditionError(
        absl::StrCat("take ", take_id,
                     " is still being recorded and this server cannot follow takes live; submit "
                     "the job once the take is complete"));
  }
  if (!live_->Recording(take_id)) {
    // The store has opened it; ingest has not told the hub yet.
    return absl::UnavailableError(
        absl::StrCat("take ", take_id, " is being opened; submit again in a moment"));
  }
  return absl::OkStatus();
}

absl::StatusOr<v1::Job> JobScheduler::FollowLocked(const v1::Job& job) {
  const std::string job_id = job.job_id();
  LiveJobCallbacks callbacks;
  callbacks.progress = [this, job_id](int64_t frames) { LiveProgress(job_id, frames); };
  callbacks.ended = [this, job_id](const LiveFollowSummary& summary) {
    LiveEnded(job_id, summary);
  };
  const absl::Status followed = live_->Follow(
      job_id, job.take_id(), {job.options().begin(), job.options().end()}, std::move(callbacks));
  if (!followed.ok()) {
    if (absl::IsFailedPrecondition(followed)) return followed;
    // The job was stored: it fails with the reason rather than vanish.
    const absl::StatusOr<v1::Job> failed = jobs_->Mutate(job_id, [&](v1::Job& j) {
      j.set_state(v1::JOB_STATE_FAILED);
      j.set_finished_unix_ns(WallNowNs());
      j.set_error(absl::StrCat("the take could not be followed: ", followed.message()));
    });
    if (failed.ok()) LogJobEnd(*failed);
    return followed;
  }
  following_.insert(job_id);
  absl::StatusOr<v1::Job> running = jobs_->Mutate(job_id, [](v1::Job& j) {
    j.set_state(v1::JOB_STATE_RUNNING);
    j.set_started_unix_ns(WallNowNs());
    j.mutable_progress()->set_stage(kFollowingStage);
    j.mutable_progress()->set_eta_s(-1);
  });
  if (running.ok()) {
    log::Info(
        "job_started",
        {{"job_id", job_id}, {"take_id", job.take_id()}, {"method", job.method()}, {"live", true}},
        absl::StrCat("job ", job_id, " follows take ", job.take_id(), " live"));
  }
  return running;
}

void JobScheduler::LiveProgress(const std::string& job_id, int64_t frames_followed) {
  // Only noted: the scheduler thread stores and publishes it (a catalog
  // write must not hold up the follower).
  std::lock_guard<std::mutex> lock(mu_);
  if (following_.contains(job_id)) live_progress_[job_id] = frames_followed;
}

void JobScheduler::PublishLiveProgress() {
  std::map<std::string, int64_t> noted;
  {
    std::lock_guard<std::mutex> lock(mu_);
    noted.swap(live_progress_);
  }
  for (const auto& [job_id, frames] : noted) {
    absl::StatusOr<v1::Job> job;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (!following_.contains(job_id)) continue;  // Cancelled or ended meanwhile.
      v1::JobProgress progress;
      progress.set_stage(kFollowingStage);
      progress.set_frames_done(frames);
      progress.set_eta_s(-1);
      job = jobs_->UpdateProgress(job_id, progress);
    }
    if (job.ok()) Publish(*job, {}, /*last=*/false);
  }
}

void JobScheduler::LiveEnded(const std::string& job_id, const LiveFollowSummary& summary) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (following_.erase(job_id) == 0) return;
    live_progress_.erase(job_id);
    if (summary.reason != v1::FOLLOW_END_REASON_FAILED) {
      // The take is stored: the same job goes on with a worker, before the
      // queued jobs.
      handoff_.push_back(job_id);
      wake_pending_ = true;
      wake_.notify_all();
    }
  }
  std::vector<std::string> logs = {
      absl::StrCat(summary.message, "; followed ", summary.frames_followed, " of ",
                   summary.frames_received, " frame sets (", summary.frames_skipped, " skipped)")};
  if (summary.reason == v1::FOLLOW_END_REASON_FAILED) {
    EndJob(job_id, v1::JOB_STATE_FAILED, summary.message, "", std::move(logs));
    return;
  }
  if (auto job = jobs_->Get(job_id); job.ok()) Publish(*job, std::move(logs), /*last=*/false);
}

absl::StatusOr<v1::Job> JobScheduler::Cancel(const std::string& job_id) {
  RETURN_IF_ERROR(ValidateJobId(job_id));
  v1::Job job;
  {
    std::lock_guard<std::mutex> lock(mu_);
    ASSIGN_OR_RETURN(job, jobs_->Get(job_id));
    std::string error;
    if (job.state() == v1::JOB_STATE_RUNNING) {
      if (auto it = running_.find(job_id); it != running_.end()) {
        it->second->cancel_requested = true;
        wake_pending_ = true;
        wake_.notify_all();
        return job;
      }
      error = StopLiveLocked(job_id);
      if (error.empty()) return job;
    } else if (job.state() == v1::JOB_STATE_QUEUED) {
      queue_.erase(std::remove(queue_.begin(), queue_.end(), job_id), queue_.end());
      error = "cancelled by a client before it started";
    } else {
      return job;
    }
    ASSIGN_OR_RETURN(job, jobs_->Mutate(job_id, [&](v1::Job& j) {
      j.set_state(v1::JOB_STATE_CANCELLED);
      j.set_finished_unix_ns(WallNowNs());
      j.set_error(error);
      j.mutable_progress()->set_eta_s(-1);
    }));
  }
  LogJobEnd(job);
  Publish(job, {}, /*last=*/true);
  return job;
}

std::string JobScheduler::StopLiveLocked(const std::string& job_id) {
  if (following_.erase(job_id) > 0) {
    live_->Stop(job_id, v1::FOLLOW_END_REASON_CANCELLED, "the job was cancelled");
    return "cancelled by a client while following its take";
  }
  const auto it = std::find(handoff_.begin(), handoff_.end(), job_id);
  if (it == handoff_.end()) return "";
  handoff_.erase(it);
  return "cancelled by a client before its worker started";
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

void JobScheduler::Publish(const v1::Job& job, std::vector<std::string> logs, bool last) {
  v1::JobEvent event;
  *event.mutable_job() = job;
  for (std::string& line : logs) event.add_log_lines(std::move(line));
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
    PollRunning();
    PublishLiveProgress();
    StartQueued();
    SweepRetention();
  }
  StopWorkers();
}

void JobScheduler::StartQueued() {
  while (true) {
    std::string job_id;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (stopping_ || BusyLocked() >= concurrency_) return;
      // Live jobs whose take was closed go first: they have run for a while.
      std::deque<std::string>& source = handoff_.empty() ? queue_ : handoff_;
      if (source.empty()) return;
      job_id = source.front();
      source.pop_front();
      const bool started =
          &source == &handoff_ ? StartHandoffLocked(job_id) : StartQueuedLocked(job_id);
      if (!started) continue;
    }
    Launch(job_id);
  }
}

bool JobScheduler::StartQueuedLocked(const std::string& job_id) {
  // Under mu_, so that Cancel finds the job either queued or running.
  bool was_queued = false;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    was_queued = j.state() == v1::JOB_STATE_QUEUED;
    if (!was_queued) return;
    j.set_state(v1::JOB_STATE_RUNNING);
    j.set_started_unix_ns(WallNowNs());
    j.set_attempts(j.attempts() + 1);
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

bool JobScheduler::StartHandoffLocked(const std::string& job_id) {
  bool was_running = false;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    was_running = j.state() == v1::JOB_STATE_RUNNING;
    if (!was_running) return;
    j.set_attempts(j.attempts() + 1);
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

void JobScheduler::Launch(const std::string& job_id) {
  Running* run = nullptr;
  {
    std::lock_guard<std::mutex> lock(mu_);
    run = running_.at(job_id).get();
  }
  auto fail = [&](const std::string& error) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      running_.erase(job_id);
    }
    EndJob(job_id, v1::JOB_STATE_FAILED, error);
  };
  const absl::StatusOr<v1::Job> job = jobs_->Get(job_id);
  if (!job.ok()) return fail(std::string(job.status().message()));
  const absl::StatusOr<std::string> take_path = takes_->TakeFileForReading(job->take_id());
  if (!take_path.ok()) {
    return fail(absl::StrCat("the take cannot be read: ", take_path.status().message()));
  }
  const fs::path dir = fs::path(jobs_dir_) / job_id;
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) {
    log::Error("job_folder_failed", {{"job_id", job_id}, {"error", error.message()}},
               absl::StrCat("cannot create ", dir.string(), ": ", error.message()));
    return fail(error == std::errc::no_space_on_device
                    ? "the server's disk is full; delete takes or reenactments and submit again"
                    : "the server could not create the job's folder (its log says why)");
  }
  run->reenactment_id = reenactments_->NewId();
  run->out_path = reenactments_->PathFor(run->reenactment_id);
  run->progress_path = (dir / "progress.jsonl").string();
  run->log_path = (dir / "worker.log").string();
  fs::remove(run->progress_path, error);
  {
    std::ofstream log(run->log_path, std::ios::app);
    log << "--- attempt " << job->attempts() << ", " << UtcNow() << ", reenactment "
        << run->reenactment_id << " ---\n";
  }
  run->log_offset = static_cast<int64_t>(fs::file_size(run->log_path, error));
  if (error) run->log_offset = 0;
  SubprocessOptions process_options;
  process_options.stdout_path = run->progress_path;
  process_options.stderr_path = run->log_path;
  process_options.working_dir = dir.string();
  std::vector<std::string> args = {
      worker_path_,
      "--take",
      *take_path,
      "--method",
      job->method(),
      "--options-json",
      OptionsJson(
          WorkerOptions(methods::FindMethod(options_.methods, job->method()), job->options())),
      "--out",
      run->out_path,
      "--reenactment-id",
      run->reenactment_id,
      "--take-id",
      job->take_id(),
      "--job-id",
      job_id};
  if (!options_.asset_roots.empty()) {
    args.insert(args.end(), {"--assets", absl::StrJoin(options_.asset_roots, ",")});
  }
  absl::StatusOr<std::unique_ptr<Subprocess>> process = Subprocess::Start(args, process_options);
  if (!process.ok()) {
    return fail(absl::StrCat("cannot start the worker: ", process.status().message()));
  }
  run->process = std::move(*process);
  run->progress = job->progress();
  log::Info("job_started",
            {{"job_id", job_id},
             {"take_id", job->take_id()},
             {"method", job->method()},
             {"attempt", job->attempts()},
             {"reenactment_id", run->reenactment_id},
             {"live", false}},
            absl::StrCat("job ", job_id, " started its worker"));
  Publish(*job, {}, /*last=*/false);
}

bool JobScheduler::ReadOutput(Running& run, std::vector<std::string>* logs) {
  std::ifstream in(run.progress_path, std::ios::binary);
  if (!in) return false;
  in.seekg(run.read_offset);
  std::string fresh((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  run.read_offset += static_cast<int64_t>(fresh.size());
  run.pending += fresh;
  bool changed = false;
  size_t start = 0;
  while (true) {
    size_t end = run.pending.find('\n', start);
    if (end == std::string::npos) {
      if (run.pending.size() - start < kMaxPendingBytes) break;
      end = run.pending.size();
    }
    std::string line = run.pending.substr(start, end - start);
    start = std::min(end + 1, run.pending.size());
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && HandleLine(run, line, logs)) changed = true;
  }
  run.pending.erase(0, start);
  if (changed) {
    // One sample per read: lines read together arrived together.
    run.samples.emplace_back(SteadyNowNs(), run.progress.fraction());
    UpdateEta(run);
  }
  return changed;
}

bool JobScheduler::HandleLine(Running& run, const std::string& line,
                              std::vector<std::string>* logs) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) {
    run.last_log = Truncate(line, kMaxLogLineChars);
    logs->push_back(run.last_log);
    return false;
  }
  if (auto it = j.find("log"); it != j.end() && it->is_string()) {
    run.last_log = Truncate(it->get<std::string>(), kMaxLogLineChars);
    logs->push_back(run.last_log);
  }
  if (auto it = j.find("error"); it != j.end() && it->is_string()) {
    run.worker_error = Truncate(it->get<std::string>(), kMaxLogLineChars);
    logs->push_back("error: " + run.worker_error);
  }
  if (auto it = j.find("result"); it != j.end()) {
    logs->push_back(Truncate("result: " + it->dump(), kMaxLogLineChars));
  }
  v1::JobProgress& p = run.progress;
  bool progress = false;
  if (auto it = j.find("stage"); it != j.end() && it->is_string()) {
    p.set_stage(Truncate(it->get<std::string>(), 64));
    progress = true;
  }
  if (auto it = j.find("fraction"); it != j.end() && it->is_number()) {
    const double f = it->get<double>();
    if (std::isfinite(f)) p.set_fraction(std::clamp(f, 0.0, 1.0));
    progress = true;
  }
  if (auto it = j.find("frames_done"); it != j.end() && it->is_number_integer()) {
    p.set_frames_done(it->get<int64_t>());
  }
  if (auto it = j.find("frames_total"); it != j.end() && it->is_number_integer()) {
    p.set_frames_total(it->get<int64_t>());
  }
  return progress;
}

void JobScheduler::UpdateEta(Running& run) const {
  // The rate of the fraction between the oldest sample in the window and the
  // newest; (1 - fraction) / rate to go.
  const int64_t window_ns = SecondsToNs(options_.eta_window_s);
  while (run.samples.size() > 2 && run.samples.back().first - run.samples[1].first > window_ns) {
    run.samples.pop_front();
  }
  v1::JobProgress& p = run.progress;
  const auto& [t0, f0] = run.samples.front();
  const auto& [t1, f1] = run.samples.back();
  const double rate = t1 > t0 ? (f1 - f0) / NsToSeconds(t1 - t0) : 0.0;
  if (p.fraction() >= 1.0) {
    p.set_eta_s(0);
  } else if (rate > 0) {
    p.set_eta_s((1.0 - p.fraction()) / rate);
  } else {
    p.set_eta_s(-1);
  }
}

void JobScheduler::PollRunning() {
  std::vector<Running*> runs;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& [id, run] : running_) runs.push_back(run.get());
  }
  for (Running* run : runs) {
    bool cancel = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      cancel = run->cancel_requested;
    }
    // Exit first, then read: whatever the worker wrote before exiting is in.
    const std::optional<ExitInfo> exit = run->process->Poll();
    std::vector<std::string> logs;
    const bool changed = ReadOutput(*run, &logs);
    if (exit.has_value()) {
      std::unique_ptr<Running> owned;
      {
        std::lock_guard<std::mutex> lock(mu_);
        auto it = running_.find(run->job_id);
        owned = std::move(it->second);
        running_.erase(it);
      }
      if (changed) (void)jobs_->UpdateProgress(owned->job_id, owned->progress);
      Finish(std::move(owned), *exit, std::move(logs));
      continue;
    }
    if (changed || !logs.empty()) {
      absl::StatusOr<v1::Job> job =
          changed ? jobs_->UpdateProgress(run->job_id, run->progress) : jobs_->Get(run->job_id);
      if (job.ok()) Publish(*job, std::move(logs), /*last=*/false);
    }
    if (cancel && !run->term_sent) {
      (void)run->process->Signal(SIGTERM);
      run->term_sent = true;
      run->kill_at_ns = SteadyNowNs() + SecondsToNs(options_.cancel_grace_s);
    } else if (cancel && !run->kill_sent && SteadyNowNs() >= run->kill_at_ns) {
      (void)run->process->Signal(SIGKILL);
      run->kill_sent = true;
    }
  }
}

std::string JobScheduler::LastLog(const Running& run) const {
  // The last line the worker wrote on stderr in this attempt, else its last
  // {"log"} line.
  std::ifstream in(run.log_path, std::ios::binary);
  std::string tail;
  if (in) {
    in.seekg(0, std::ios::end);
    const int64_t size = static_cast<int64_t>(in.tellg());
    const int64_t from = std::max(run.log_offset, size - 4096);
    if (size > from) {
      in.seekg(from);
      tail.resize(static_cast<size_t>(size - from));
      in.read(tail.data(), static_cast<std::streamsize>(tail.size()));
    }
  }
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == '\r' || tail.back() == ' ')) {
    tail.pop_back();
  }
  if (const size_t nl = tail.rfind('\n'); nl != std::string::npos) tail = tail.substr(nl + 1);
  if (tail.empty()) tail = run.last_log;
  if (tail.empty()) return "(none)";
  return Truncate(tail, kMaxQuotedLogChars);
}

void JobScheduler::Finish(std::unique_ptr<Running> run, const ExitInfo& exit,
                          std::vector<std::string> logs) {
  bool cancelled = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    cancelled = run->cancel_requested;
  }
  if (exit.exited && exit.exit_code == 0) {
    // Done, even when a cancel came too late to stop it.
    if (!logs.empty()) {
      if (auto job = jobs_->Get(run->job_id); job.ok()) Publish(*job, std::move(logs), false);
    }
    finisher_->Schedule(
        [this, job_id = run->job_id, rid = run->reenactment_id] { Succeed(job_id, rid); });
    return;
  }
  std::error_code error;
  fs::remove(run->out_path, error);
  if (cancelled) {
    EndJob(run->job_id, v1::JOB_STATE_CANCELLED,
           run->kill_sent ? absl::StrCat("cancelled by a client (the worker was killed after ",
                                         options_.cancel_grace_s, " s)")
                          : "cancelled by a client",
           "", std::move(logs));
    return;
  }
  std::string why;
  if (!exit.exited) {
    why = absl::StrCat("worker killed by signal ", exit.signal, " (", SignalName(exit.signal),
                       "); last log: ", LastLog(*run));
  } else if (exit.exit_code == 1 && !run->worker_error.empty()) {
    why = run->worker_error;
  } else if (exit.exit_code == 2) {
    why = absl::StrCat("the worker refused its command line (exit code 2): ", LastLog(*run));
  } else if (exit.exit_code == 3) {
    why = absl::StrCat("the worker stopped early without a cancel (exit code 3); last log: ",
                       LastLog(*run));
  } else {
    why = absl::StrCat("worker failed (exit code ", exit.exit_code, "); last log: ", LastLog(*run));
  }
  EndJob(run->job_id, v1::JOB_STATE_FAILED, why, "", std::move(logs));
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
  auto change = [&](v1::Job& j) {
    j.set_state(state);
    j.set_finished_unix_ns(WallNowNs());
    j.set_error(error);
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
    current->set_error(absl::StrCat(error, error.empty() ? "" : "; ",
                                    "the end could not be stored: ", job.status().message()));
    job = std::move(current);
  }
  LogJobEnd(*job);
  Publish(*job, std::move(logs), /*last=*/true);
}

void JobScheduler::StopWorkers() {
  std::map<std::string, std::unique_ptr<Running>> runs;
  {
    std::lock_guard<std::mutex> lock(mu_);
    runs.swap(running_);
  }
  for (auto& [id, run] : runs) (void)run->process->Signal(SIGTERM);
  const int64_t deadline_ns = SteadyNowNs() + SecondsToNs(options_.shutdown_grace_s);
  for (auto& [id, run] : runs) {
    const double left_s = std::max(0.0, NsToSeconds(deadline_ns - SteadyNowNs()));
    absl::StatusOr<ExitInfo> exit = run->process->Wait(left_s);
    if (!exit.ok()) {
      (void)run->process->Signal(SIGKILL);
      exit = run->process->Wait();
    }
    std::vector<std::string> logs;
    ReadOutput(*run, &logs);
    if (exit.ok() && exit->exited && exit->exit_code == 0) {
      Succeed(id, run->reenactment_id);  // It finished within the grace period.
      continue;
    }
    std::error_code error;
    fs::remove(run->out_path, error);
    bool cancelled = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      cancelled = run->cancel_requested;
    }
    if (cancelled) {
      EndJob(id, v1::JOB_STATE_CANCELLED, "cancelled by a client (stopped at server shutdown)", "",
             std::move(logs));
      continue;
    }
    // The job stays RUNNING with its last progress: the next start queues it.
    (void)jobs_->Mutate(id, [&](v1::Job& j) {
      *j.mutable_progress() = run->progress;
      j.mutable_progress()->set_eta_s(-1);
    });
  }
}

}  // namespace reenact::server
