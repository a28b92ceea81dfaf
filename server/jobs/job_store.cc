#include "server/jobs/job_store.h"

#include <algorithm>
#include <ctime>
#include <random>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"

namespace reenact::server {
namespace {

bool NewerFirst(const v1::Job& a, const v1::Job& b) {
  if (a.submitted_unix_ns() != b.submitted_unix_ns()) {
    return a.submitted_unix_ns() > b.submitted_unix_ns();
  }
  return a.job_id() > b.job_id();
}

}  // namespace

absl::Status JobStoreOptions::Validate() const {
  if (!(progress_write_period_s >= 0)) {
    return absl::InvalidArgumentError("progress_write_period_s must be >= 0");
  }
  if (max_attempts < 1) return absl::InvalidArgumentError("max_attempts must be >= 1");
  return absl::OkStatus();
}

absl::Status ValidateJobId(std::string_view job_id) {
  const bool ok = !job_id.empty() && job_id.size() <= 64 &&
                  std::all_of(job_id.begin(), job_id.end(), [](char c) {
                    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                           (c >= '0' && c <= '9') || c == '_' || c == '-';
                  });
  if (ok) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat("job id \"", std::string(job_id.substr(0, 80)),
                                                 "\" is not 1..64 characters of [A-Za-z0-9_-]"));
}

bool IsFinished(v1::JobState state) {
  return state == v1::JOB_STATE_SUCCEEDED || state == v1::JOB_STATE_FAILED ||
         state == v1::JOB_STATE_CANCELLED;
}

absl::StatusOr<std::unique_ptr<JobStore>> JobStore::Open(Catalog* catalog,
                                                         const JobStoreOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::unique_ptr<JobStore> store(new JobStore(catalog, options));
  ASSIGN_OR_RETURN(std::vector<v1::Job> jobs, catalog->ListJobs());
  for (v1::Job& job : jobs) {
    std::string id = job.job_id();
    store->jobs_.emplace(std::move(id), std::move(job));
  }
  return store;
}

std::string JobStore::NewIdLocked() const {
  static thread_local std::mt19937 random(std::random_device{}());
  const int64_t now_ns = WallNowNs();
  const std::time_t seconds = static_cast<std::time_t>(now_ns / kNanosPerSecond);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", &tm);
  while (true) {
    std::string id = absl::StrFormat("j-%s-%04x", stamp, static_cast<unsigned>(random() & 0xffffu));
    if (jobs_.count(id) == 0) return id;
  }
}

absl::StatusOr<v1::Job> JobStore::Insert(v1::Job job) {
  std::lock_guard<std::mutex> lock(mu_);
  job.set_job_id(NewIdLocked());
  job.set_state(v1::JOB_STATE_QUEUED);
  job.clear_progress();
  job.mutable_progress()->set_eta_s(-1);
  job.set_submitted_unix_ns(WallNowNs());
  job.set_started_unix_ns(0);
  job.set_finished_unix_ns(0);
  job.clear_reenactment_id();
  job.clear_error();
  job.set_attempts(0);
  RETURN_IF_ERROR(catalog_->PutJob(job));
  jobs_[job.job_id()] = job;
  written_ns_[job.job_id()] = SteadyNowNs();
  return job;
}

absl::StatusOr<v1::Job> JobStore::Mutate(const std::string& job_id,
                                         const std::function<void(v1::Job&)>& change) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return absl::NotFoundError(absl::StrCat("no job \"", job_id, "\""));
  v1::Job job = it->second;
  change(job);
  job.set_job_id(job_id);
  const absl::Status put = catalog_->PutJob(job);
  if (!put.ok() && !IsDiskFull(put)) return put;
  it->second = job;
  if (!put.ok()) {
    unsaved_.insert(job_id);
    return job;
  }
  written_ns_[job_id] = SteadyNowNs();
  unsaved_.erase(job_id);
  // The catalog takes writes again: what a full disk held back goes too.
  for (auto unsaved = unsaved_.begin(); unsaved != unsaved_.end();) {
    const auto held = jobs_.find(*unsaved);
    if (held == jobs_.end() || catalog_->PutJob(held->second).ok()) {
      unsaved = unsaved_.erase(unsaved);
    } else {
      ++unsaved;
    }
  }
  return job;
}

absl::StatusOr<v1::Job> JobStore::UpdateProgress(const std::string& job_id,
                                                 const v1::JobProgress& progress) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return absl::NotFoundError(absl::StrCat("no job \"", job_id, "\""));
  *it->second.mutable_progress() = progress;
  const int64_t now_ns = SteadyNowNs();
  int64_t& written_ns = written_ns_[job_id];
  if (now_ns - written_ns >= SecondsToNs(options_.progress_write_period_s)) {
    // A failed progress write is not worth failing the job for: the next
    // state change writes everything again.
    if (catalog_->PutJob(it->second).ok()) written_ns = now_ns;
  }
  return it->second;
}

absl::Status JobStore::Delete(const std::string& job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return absl::NotFoundError(absl::StrCat("no job \"", job_id, "\""));
  if (!IsFinished(it->second.state())) {
    return absl::FailedPreconditionError(
        absl::StrCat("job ", job_id, " has not finished; cancel it first"));
  }
  RETURN_IF_ERROR(catalog_->DeleteJob(job_id));
  jobs_.erase(it);
  written_ns_.erase(job_id);
  return absl::OkStatus();
}

absl::StatusOr<v1::Job> JobStore::Get(const std::string& job_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return absl::NotFoundError(absl::StrCat("no job \"", job_id, "\""));
  return it->second;
}

std::vector<v1::Job> JobStore::List(v1::JobState state, const std::string& take_id) const {
  std::vector<v1::Job> out;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, job] : jobs_) {
      if (state != v1::JOB_STATE_UNSPECIFIED && job.state() != state) continue;
      if (!take_id.empty() && job.take_id() != take_id) continue;
      out.push_back(job);
    }
  }
  std::sort(out.begin(), out.end(), NewerFirst);
  return out;
}

std::vector<v1::Job> JobStore::Queued() const {
  std::vector<v1::Job> queued = List(v1::JOB_STATE_QUEUED);
  std::reverse(queued.begin(), queued.end());
  return queued;
}

std::map<v1::JobState, int64_t> JobStore::CountByState() const {
  std::map<v1::JobState, int64_t> counts;
  std::lock_guard<std::mutex> lock(mu_);
  for (const auto& [id, job] : jobs_) ++counts[job.state()];
  return counts;
}

int64_t JobStore::CountQueuedBy(const std::string& submitter) const {
  int64_t count = 0;
  std::lock_guard<std::mutex> lock(mu_);
  for (const auto& [id, job] : jobs_) {
    count += job.state() == v1::JOB_STATE_QUEUED && job.submitted_by() == submitter ? 1 : 0;
  }
  return count;
}

absl::StatusOr<std::vector<std::string>> JobStore::RequeueUnfinished() {
  std::vector<v1::Job> running = List(v1::JOB_STATE_RUNNING);
  std::reverse(running.begin(), running.end());
  std::vector<std::string> requeued;
  for (const v1::Job& job : running) {
    const bool give_up = job.attempts() >= options_.max_attempts;
    ASSIGN_OR_RETURN(
        const v1::Job changed, Mutate(job.job_id(), [&](v1::Job& j) {
          j.mutable_progress()->set_eta_s(-1);
          EndAttempt(j, "server stopped");
          std::string part_given_up;
          for (v1::JobPart& part : *j.mutable_parts()) {
            if (part.state() != v1::JOB_STATE_RUNNING) continue;
            EndAttempt(part, "server stopped");
            part.set_state(v1::JOB_STATE_QUEUED);
            if (part.attempts() >= options_.max_attempts) part_given_up = part.name();
          }
          if (!part_given_up.empty()) {
            j.set_state(v1::JOB_STATE_FAILED);
            j.set_finished_unix_ns(WallNowNs());
            j.set_error(absl::StrCat("the server stopped while its part ", part_given_up, " ran, ",
                                     options_.max_attempts,
                                     " times (the limit); not trying again"));
          } else if (give_up) {
            j.set_state(v1::JOB_STATE_FAILED);
            j.set_finished_unix_ns(WallNowNs());
            j.set_error(absl::StrCat("the server stopped while the job ran, ", j.attempts(),
                                     " times (the limit); not trying again"));
          } else {
            j.set_state(v1::JOB_STATE_QUEUED);
          }
        }));
    if (changed.state() == v1::JOB_STATE_QUEUED) requeued.push_back(changed.job_id());
  }
  return requeued;
}

}  // namespace reenact::server
