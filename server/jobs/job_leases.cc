// The Work service's side of the job scheduler (job_scheduler.h): leases of
// queued jobs to workers that connect over the network, their heartbeats,
// uploads and failures, and the expiry that queues a job again when its
// worker stops answering.
#include <sys/random.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "server/jobs/job_scheduler.h"
#include "server/worker/worker_protocol.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

// The longest a Lease call waits for a job, seconds.
constexpr double kMaxLeaseWaitS = 60.0;
// Longest worker name kept.
constexpr size_t kMaxWorkerNameChars = 128;

// A lease id holds 128 bits from the kernel's CSPRNG (getrandom): a worker
// cannot guess another's lease from its own, as it could from a seeded
// generator's outputs.
std::string NewLeaseId(const std::string& job_id, int attempt) {
  std::array<uint64_t, 2> salt{};
  size_t got = 0;
  auto* bytes = reinterpret_cast<unsigned char*>(salt.data());
  while (got < sizeof(salt)) {
    const ssize_t n = ::getrandom(bytes + got, sizeof(salt) - got, 0);
    if (n > 0) {
      got += static_cast<size_t>(n);
    } else if (n < 0 && errno != EINTR) {
      // No kernel source (never on Linux >= 3.17): the device instead.
      std::random_device device("/dev/urandom");
      for (uint64_t& word : salt) word = (uint64_t{device()} << 32) | device();
      break;
    }
  }
  return absl::StrFormat("%s.%d.%016x%016x", job_id, attempt, salt[0], salt[1]);
}

absl::Status NoLease(const std::string& lease_id) {
  return absl::AbortedError(
      absl::StrCat("lease ", lease_id.substr(0, 96),
                   " is not held: it expired, its job was cancelled or ended, or the server "
                   "restarted; drop the job"));
}

std::string WorkerName(const std::string& name) {
  std::string kept = name.substr(0, kMaxWorkerNameChars);
  for (char& c : kept) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  return kept.empty() ? "(unnamed)" : kept;
}

}  // namespace

bool IsLocalWorkerName(std::string_view name) { return name.starts_with(kLocalWorkerPrefix); }

void JobScheduler::AppendWorkerLog(const std::string& job_id,
                                   const std::vector<std::string>& lines) {
  if (lines.empty()) return;
  const fs::path dir = fs::path(jobs_dir_) / job_id;
  std::error_code error;
  fs::create_directories(dir, error);
  std::ofstream log(dir / "worker.log", std::ios::app);
  for (const std::string& line : lines) log << line << "\n";
}

void JobScheduler::Lease(const v1::LeaseRequest& request, const std::string& holder,
                         LeaseDone done) {
  if (request.protocol() != v1::WORK_PROTOCOL_V1) {
    done(absl::FailedPreconditionError(
        absl::StrCat("this server speaks Work protocol 1; the worker asked for ",
                     static_cast<int>(request.protocol()), ": run a worker of the same release")));
    return;
  }
  if (!(request.wait_s() >= 0)) {
    done(absl::InvalidArgumentError("wait_s must be >= 0"));
    return;
  }
  std::set<std::string> methods;
  for (const std::string& method : request.methods()) {
    if (methods::FindMethod(options_.methods, method) == nullptr) {
      done(methods::UnknownMethodError(options_.methods, method));
      return;
    }
    methods.insert(method);
  }
  const std::string worker_name = WorkerName(request.worker_name());
  std::optional<v1::WorkLease> lease;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_) {
      done(absl::UnavailableError("the server is shutting down"));
      return;
    }
    lease = LeaseQueuedLocked(methods, worker_name, holder);
    if (!lease.has_value() && request.wait_s() > 0) {
      const double wait_s = std::min(request.wait_s(), kMaxLeaseWaitS);
      lease_waiters_.push_back({std::move(methods), worker_name, holder,
                                SteadyNowNs() + SecondsToNs(wait_s), std::move(done)});
      return;
    }
  }
  v1::LeaseResponse response;
  if (lease.has_value()) *response.mutable_lease() = std::move(*lease);
  done(std::move(response));
}

void JobScheduler::StopLeasing() {
  std::lock_guard<std::mutex> lock(mu_);
  leasing_stopped_ = true;
}

std::optional<v1::WorkLease> JobScheduler::LeaseQueuedLocked(const std::set<std::string>& methods,
                                                             const std::string& worker_name,
                                                             const std::string& holder) {
  auto runs = [&](const std::string& unit) {
    if (methods.empty()) return true;
    const absl::StatusOr<v1::Job> job = jobs_->Get(SplitUnit(unit).first);
    return job.ok() && methods.contains(job->method());
  };
  if (leasing_stopped_) return std::nullopt;
  // This server's own workers share its job slots with live follows.
  const bool local = IsLocalWorkerName(worker_name);
  if (local && BusyLocked() >= concurrency_) return std::nullopt;
  std::string unit;
  bool started = false;
  // Live jobs whose take ended go first: they have run for a while.
  if (std::optional<std::string> next = live_jobs_.NextHandoffLocked()) {
    if (runs(*next)) {
      unit = *next;
      started = StartHandoffLocked(unit, worker_name);
    } else {
      live_jobs_.ReturnHandoffLocked(*next);
    }
  }
  for (auto it = queue_.begin(); !started && it != queue_.end();) {
    if (!runs(*it)) {
      ++it;
      continue;
    }
    unit = *it;
    it = queue_.erase(it);
    const auto [id, part] = SplitUnit(unit);
    started =
        part.empty() ? StartQueuedLocked(id, worker_name) : StartPartLocked(id, part, worker_name);
  }
  if (!started) return std::nullopt;
  Running& run = *running_.at(unit);
  const std::string job_id = run.job_id;
  const absl::StatusOr<v1::Job> job = jobs_->Get(job_id);
  const absl::StatusOr<std::string> take_path =
      job.ok() ? takes_->TakeFileForReading(job->take_id()) : job.status();
  std::error_code error;
  const int64_t take_bytes =
      take_path.ok() ? static_cast<int64_t>(fs::file_size(*take_path, error)) : -1;
  if (!job.ok() || !take_path.ok() || error) {
    // The take went (deleted under a queued job cannot happen: Delete
    // refuses; a file that cannot be read can): the job fails here.
    const std::string why =
        absl::StrCat("the take cannot be read: ",
                     !take_path.ok() ? std::string(take_path.status().message()) : error.message());
    running_.erase(unit);
    finisher_->Schedule([this, job_id, why] { EndJob(job_id, v1::JOB_STATE_FAILED, why); });
    return std::nullopt;
  }
  v1::WorkLease lease;
  int attempt = job->attempts();
  if (!run.part.empty()) {
    if (const absl::Status filled = FillPartLeaseLocked(*job, run, lease); !filled.ok()) {
      const std::string why = absl::StrCat("part ", run.part, ": ", filled.message());
      running_.erase(unit);
      finisher_->Schedule([this, job_id, why] { EndJob(job_id, v1::JOB_STATE_FAILED, why); });
      return std::nullopt;
    }
    for (const v1::JobPart& part : job->parts()) {
      if (part.name() == run.part) attempt = part.attempts();
    }
  }
  run.lease_id = NewLeaseId(unit, attempt);
  run.worker_name = worker_name;
  run.holder = holder;
  run.local = local;
  if (local) ++local_leases_;
  if (run.part.empty() || run.part == "stitch") {
    run.reenactment_id = reenactments_->NewId();
    run.out_path = reenactments_->PathFor(run.reenactment_id);
  }
  run.expires_ns = SteadyNowNs() + SecondsToNs(options_.lease_ttl_s);
  run.eta.emplace(options_.eta_window_s);
  leases_[run.lease_id] = unit;

  lease.set_lease_id(run.lease_id);
  *lease.mutable_job() = *job;
  lease.mutable_job()->clear_options();
  for (const auto& [key, value] :
       WorkerOptions(methods::FindMethod(options_.methods, job->method()), job->options())) {
    (*lease.mutable_job()->mutable_options())[key] = value;
  }
  lease.set_reenactment_id(run.reenactment_id);
  lease.set_take_bytes(take_bytes);
  lease.set_ttl_s(options_.lease_ttl_s);
  // Often enough that a cancel reaches the worker within two seconds.
  lease.set_heartbeat_period_s(std::min(2.0, options_.lease_ttl_s / 6));
  const std::string what = run.part.empty() ? "" : absl::StrCat(", part ", run.part);
  log::Info("job_started",
            {{"job_id", job_id},
             {"take_id", job->take_id()},
             {"method", job->method()},
             {"part", run.part},
             {"attempt", attempt},
             {"worker", worker_name},
             {"reenactment_id", run.reenactment_id}},
            absl::StrCat("job ", job_id, what, " started: leased to worker ", worker_name));
  AppendWorkerLog(job_id,
                  {absl::StrCat("--- attempt ", attempt, what, ", ", UtcNowText(), ", worker ",
                                worker_name, run.reenactment_id.empty() ? "" : ", reenactment ",
                                run.reenactment_id, " ---")});
  finisher_->Schedule([this, job = *job] { Publish(job, {}, /*last=*/false); });
  return lease;
}

void JobScheduler::ServeLeaseWaiters() {
  std::vector<std::pair<LeaseDone, v1::LeaseResponse>> answers;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const int64_t now_ns = SteadyNowNs();
    for (auto it = lease_waiters_.begin(); it != lease_waiters_.end();) {
      std::optional<v1::WorkLease> lease =
          queue_.empty() && !live_jobs_.HasHandoffLocked()
              ? std::nullopt
              : LeaseQueuedLocked(it->methods, it->worker_name, it->holder);
      if (!lease.has_value() && now_ns < it->deadline_ns) {
        ++it;
        continue;
      }
      v1::LeaseResponse response;
      if (lease.has_value()) *response.mutable_lease() = std::move(*lease);
      answers.emplace_back(std::move(it->done), std::move(response));
      it = lease_waiters_.erase(it);
    }
  }
  for (auto& [done, response] : answers) done(std::move(response));
}

void JobScheduler::EndLeaseWaiters() {
  std::deque<LeaseWaiter> waiters;
  {
    std::lock_guard<std::mutex> lock(mu_);
    waiters.swap(lease_waiters_);
  }
  for (LeaseWaiter& waiter : waiters) {
    waiter.done(absl::UnavailableError("the server is shutting down"));
  }
}

absl::StatusOr<JobScheduler::Running*> JobScheduler::HeldLeaseLocked(
    const std::string& lease_id) const {
  const auto lease = leases_.find(lease_id);
  if (lease == leases_.end()) return NoLease(lease_id);
  const auto run = running_.find(lease->second);
  if (run == running_.end() || SteadyNowNs() > run->second->expires_ns) return NoLease(lease_id);
  return run->second.get();
}

absl::Status JobScheduler::CheckLeaseHolder(const std::string& lease_id,
                                            const std::string& holder) const {
  std::lock_guard<std::mutex> lock(mu_);
  ASSIGN_OR_RETURN(const Running* run, HeldLeaseLocked(lease_id));
  if (run->holder != holder) {
    log::Warn("lease_holder_refused",
              {{"job_id", run->job_id}, {"holder", run->holder}, {"caller", holder}},
              absl::StrCat("a call for a lease of job ", run->job_id,
                           " came with another credential than the one it was given to"));
    return absl::PermissionDeniedError(
        "this lease was given to another worker's credential; a worker may only use the leases "
        "it took");
  }
  return absl::OkStatus();
}

std::unique_ptr<JobScheduler::Running> JobScheduler::ReleaseLocked(const std::string& lease_id) {
  const auto lease = leases_.find(lease_id);
  if (lease == leases_.end()) return nullptr;
  const std::string unit = lease->second;
  leases_.erase(lease);
  const auto run = running_.find(unit);
  if (run == running_.end()) return nullptr;
  std::unique_ptr<Running> owned = std::move(run->second);
  running_.erase(run);
  if (owned->local) --local_leases_;
  if (owned->uploading) {
    std::error_code error;
    fs::remove(owned->upload_path, error);
  }
  return owned;
}

void JobScheduler::ExpireLeases() {
  std::vector<std::unique_ptr<Running>> expired;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const int64_t now_ns = SteadyNowNs();
    std::vector<std::string> ids;
    for (const auto& [lease_id, unit] : leases_) {
      const auto run = running_.find(unit);
      if (run != running_.end() && now_ns > run->second->expires_ns) ids.push_back(lease_id);
    }
    for (const std::string& id : ids) expired.push_back(ReleaseLocked(id));
  }
  for (const std::unique_ptr<Running>& run : expired) {
    if (run == nullptr) continue;
    log::Warn(
        "lease_expired",
        {{"job_id", run->job_id}, {"worker", run->worker_name}, {"ttl_s", options_.lease_ttl_s}},
        absl::StrCat("worker ", run->worker_name, " stopped answering for job ", run->job_id,
                     " (no heartbeat in ", options_.lease_ttl_s, " s)"));
    Requeue(*run, "lease expired", absl::StrCat("no heartbeat in ", options_.lease_ttl_s, " s"));
  }
}

void JobScheduler::Requeue(const Running& run, const std::string& outcome, const std::string& why) {
  if (!run.part.empty()) {
    RequeuePart(run, outcome, why);
    return;
  }
  const absl::StatusOr<v1::Job> job = jobs_->Get(run.job_id);
  if (!job.ok()) return;
  if (job->attempts() >= options_.store.max_attempts) {
    EndJob(run.job_id, v1::JOB_STATE_FAILED,
           absl::StrCat("its workers stopped ", job->attempts(),
                        " times (the last: ", run.worker_name, ", ", why, ")"));
    return;
  }
  std::lock_guard<std::mutex> lock(mu_);
  const absl::StatusOr<v1::Job> queued = jobs_->Mutate(run.job_id, [&](v1::Job& j) {
    if (j.state() != v1::JOB_STATE_RUNNING) return;
    EndAttempt(j, outcome);
    j.set_state(v1::JOB_STATE_QUEUED);
    j.mutable_progress()->set_stage("queued again");
    j.mutable_progress()->set_eta_s(-1);
  });
  if (queued.ok() && queued->state() == v1::JOB_STATE_QUEUED) {
    // First in line: it has waited already.
    queue_.push_front(run.job_id);
    wake_pending_ = true;
    wake_.notify_all();
    finisher_->Schedule([this, job = *queued] { Publish(job, {}, /*last=*/false); });
  }
}

absl::StatusOr<std::string> JobScheduler::LeasedTakePath(const std::string& lease_id,
                                                         const std::string& input) const {
  std::string take_id;
  {
    std::lock_guard<std::mutex> lock(mu_);
    ASSIGN_OR_RETURN(const Running* run, HeldLeaseLocked(lease_id));
    if (!input.empty()) {
      if (std::find(run->inputs.begin(), run->inputs.end(), input) == run->inputs.end()) {
        return absl::NotFoundError(
            absl::StrCat("the lease reads no input \"", input.substr(0, 64), "\""));
      }
      return PartPath(run->job_id, input);
    }
    ASSIGN_OR_RETURN(const v1::Job job, jobs_->Get(run->job_id));
    take_id = job.take_id();
  }
  return takes_->TakeFileForReading(take_id);
}

absl::StatusOr<std::string> JobScheduler::LeaseScratchDir(const std::string& lease_id) const {
  std::string job_id;
  {
    std::lock_guard<std::mutex> lock(mu_);
    ASSIGN_OR_RETURN(const Running* run, HeldLeaseLocked(lease_id));
    job_id = run->job_id;
  }
  const std::string dir = (fs::path(jobs_dir_) / job_id).string();
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) {
    return absl::InternalError(absl::StrCat("cannot create ", dir, ": ", error.message()));
  }
  return dir;
}

absl::StatusOr<v1::HeartbeatResponse> JobScheduler::Heartbeat(const v1::HeartbeatRequest& request) {
  v1::JobProgress progress = request.progress();
  std::string job_id;
  {
    std::lock_guard<std::mutex> lock(mu_);
    ASSIGN_OR_RETURN(Running * run, HeldLeaseLocked(request.lease_id()));
    const int64_t now_ns = SteadyNowNs();
    run->expires_ns = now_ns + SecondsToNs(options_.lease_ttl_s);
    progress.set_fraction(
        std::clamp(std::isfinite(progress.fraction()) ? progress.fraction() : 0.0, 0.0, 1.0));
    progress.set_frames_done(std::max<int64_t>(progress.frames_done(), 0));
    progress.set_frames_total(std::max<int64_t>(progress.frames_total(), 0));
    if (progress.stage().size() > 64) progress.mutable_stage()->resize(64);
    job_id = run->job_id;
    if (!run->part.empty()) {
      // A part: the job's progress sums its parts'.
      run->fraction = progress.fraction();
      ASSIGN_OR_RETURN(const v1::Job job, jobs_->Get(job_id));
      const std::string stage = progress.stage();
      progress = SegmentedProgressLocked(job);
      if (run->part == "prepare" || run->part == "stitch") {
        progress.set_stage(absl::StrCat(run->part, ": ", stage));
      }
    }
    progress.set_eta_s(run->eta->Update(now_ns, progress.fraction()));
  }
  std::vector<std::string> logs;
  for (const std::string& line : request.log_lines()) {
    logs.push_back(line.substr(0, kMaxWorkerLogLineChars));
  }
  AppendWorkerLog(job_id, logs);
  if (absl::StatusOr<v1::Job> job = jobs_->UpdateProgress(job_id, progress); job.ok()) {
    Publish(*job, std::move(logs), /*last=*/false);
  }
  v1::HeartbeatResponse response;
  response.set_ttl_s(options_.lease_ttl_s);
  return response;
}

absl::StatusOr<std::string> JobScheduler::BeginUpload(const std::string& lease_id) {
  std::lock_guard<std::mutex> lock(mu_);
  ASSIGN_OR_RETURN(Running * run, HeldLeaseLocked(lease_id));
  if (run->uploading) {
    return absl::AbortedError(
        absl::StrCat("lease ", lease_id, " is uploading already; one upload per attempt"));
  }
  run->uploading = true;
  run->upload_path = run->out_path + ".upload";
  run->expires_ns = SteadyNowNs() + SecondsToNs(options_.lease_ttl_s);
  return run->upload_path;
}

absl::Status JobScheduler::ContinueUpload(const std::string& lease_id) {
  std::lock_guard<std::mutex> lock(mu_);
  ASSIGN_OR_RETURN(Running * run, HeldLeaseLocked(lease_id));
  run->expires_ns = SteadyNowNs() + SecondsToNs(options_.lease_ttl_s);
  return absl::OkStatus();
}

void JobScheduler::AbortUpload(const std::string& lease_id) {
  std::lock_guard<std::mutex> lock(mu_);
  const absl::StatusOr<Running*> run = HeldLeaseLocked(lease_id);
  if (!run.ok() || !(*run)->uploading) return;
  std::error_code error;
  fs::remove((*run)->upload_path, error);
  (*run)->uploading = false;
}

absl::StatusOr<v1::Job> JobScheduler::CommitUpload(const std::string& lease_id) {
  std::unique_ptr<Running> run;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const absl::StatusOr<Running*> held = HeldLeaseLocked(lease_id);
    if (!held.ok()) {
      // The file of an attempt that lost its lease is not stored.
      const auto lease = leases_.find(lease_id);
      if (lease != leases_.end()) (void)ReleaseLocked(lease_id);
      return held.status();
    }
    if (!(*held)->uploading) return absl::AbortedError("no upload was begun for this lease");
    // Ends the lease first: nothing can queue the job again from here.
    const std::string unit = leases_.at(lease_id);
    leases_.erase(lease_id);
    run = std::move(running_.at(unit));
    running_.erase(unit);
    if (run->local) --local_leases_;
  }
  std::error_code error;
  const int64_t file_bytes = static_cast<int64_t>(fs::file_size(run->upload_path, error));
  fs::rename(run->upload_path, run->out_path, error);
  if (error) {
    fs::remove(run->upload_path, error);
    EndJob(run->job_id, v1::JOB_STATE_FAILED,
           absl::StrCat("the upload", run->part.empty() ? "" : " of part " + run->part,
                        " could not be stored: ", error.message()));
    return absl::UnavailableError("the server could not store the upload (its log says why)");
  }
  if (!run->part.empty() && run->part != "stitch") return CompletePart(*run, file_bytes);
  Succeed(run->job_id, run->reenactment_id);
  ASSIGN_OR_RETURN(v1::Job job, jobs_->Get(run->job_id));
  if (job.state() != v1::JOB_STATE_SUCCEEDED) {
    return absl::InvalidArgumentError(job.error());
  }
  log::Info("upload_committed",
            {{"job_id", job.job_id()},
             {"worker", run->worker_name},
             {"reenactment_id", run->reenactment_id}},
            absl::StrCat("job ", job.job_id(), ": the reenactment from worker ", run->worker_name,
                         " is stored"));
  return job;
}

absl::StatusOr<v1::Job> JobScheduler::FailLease(const v1::FailRequest& request) {
  std::unique_ptr<Running> run;
  {
    std::lock_guard<std::mutex> lock(mu_);
    RETURN_IF_ERROR(HeldLeaseLocked(request.lease_id()).status());
    run = ReleaseLocked(request.lease_id());
  }
  std::vector<std::string> logs;
  for (const std::string& line : request.log_lines()) {
    logs.push_back(line.substr(0, kMaxWorkerLogLineChars));
  }
  AppendWorkerLog(run->job_id, logs);
  std::string error = request.error().substr(0, kMaxWorkerLogLineChars);
  if (error.empty()) error = "the worker failed without saying why";
  if (!run->part.empty() && !request.give_back()) {
    FailPart(*run, error, std::move(logs));
    return jobs_->Get(run->job_id);
  }
  if (request.give_back()) {
    if (auto job = jobs_->Get(run->job_id); job.ok() && !logs.empty()) {
      Publish(*job, std::move(logs), /*last=*/false);
    }
    log::Info(
        "lease_given_back", {{"job_id", run->job_id}, {"worker", run->worker_name}, {"why", error}},
        absl::StrCat("worker ", run->worker_name, " gave job ", run->job_id, " back: ", error));
    Requeue(*run, "given back", absl::StrCat("gave it back: ", error));
    return jobs_->Get(run->job_id);
  }
  EndJob(run->job_id, v1::JOB_STATE_FAILED, error, "", std::move(logs));
  return jobs_->Get(run->job_id);
}

}  // namespace reenact::server
