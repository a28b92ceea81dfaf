// Segmented jobs on the job scheduler (job_scheduler.h): one take split
// across several workers as the parts prepare, segment-1 .. segment-N and
// stitch, each queued, leased and retried like a job of its own, and each
// part's upload handed on to the parts after it.
#include <algorithm>
#include <filesystem>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "server/jobs/job_scheduler.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

constexpr char kPrepare[] = "prepare";
constexpr char kStitch[] = "stitch";
constexpr char kSegmentPrefix[] = "segment-";

bool IsSegment(const std::string& part) { return absl::StartsWith(part, kSegmentPrefix); }

v1::JobPart* FindPart(v1::Job& job, const std::string& name) {
  for (v1::JobPart& part : *job.mutable_parts()) {
    if (part.name() == name) return &part;
  }
  return nullptr;
}

const v1::JobPart* FindPart(const v1::Job& job, const std::string& name) {
  for (const v1::JobPart& part : job.parts()) {
    if (part.name() == name) return &part;
  }
  return nullptr;
}

// The weight of a part in the job's progress: the segments do most of the
// work, together as much as prepare and stitch four times over.
double PartWeight(const v1::Job& job, const std::string& part) {
  return IsSegment(part) ? 8.0 / std::max(1, job.segments()) : 1.0;
}

}  // namespace

std::string UnitId(const std::string& job_id, const std::string& part) {
  return part.empty() ? job_id : absl::StrCat(job_id, "/", part);
}

std::pair<std::string, std::string> SplitUnit(const std::string& unit) {
  const size_t slash = unit.find('/');
  if (slash == std::string::npos) return {unit, ""};
  return {unit.substr(0, slash), unit.substr(slash + 1)};
}

std::vector<v1::JobPart> NewParts(int segments) {
  std::vector<v1::JobPart> parts(segments + 2);
  parts.front().set_name(kPrepare);
  parts.front().set_state(v1::JOB_STATE_QUEUED);
  for (int k = 1; k <= segments; ++k) parts[k].set_name(absl::StrCat(kSegmentPrefix, k));
  parts.back().set_name(kStitch);
  return parts;
}

std::string JobScheduler::PartPath(const std::string& job_id, const std::string& part) const {
  return (fs::path(jobs_dir_) / job_id / "parts" / (part + ".part")).string();
}

bool JobScheduler::StartPartLocked(const std::string& job_id, const std::string& part,
                                   const std::string& worker) {
  bool was_queued = false;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    v1::JobPart* p = FindPart(j, part);
    if (p == nullptr || IsFinished(j.state())) return;
    was_queued = p->state() == v1::JOB_STATE_QUEUED;
    if (!was_queued) return;
    p->set_state(v1::JOB_STATE_RUNNING);
    p->set_attempts(p->attempts() + 1);
    BeginAttempt(*p, worker);
    p->set_fraction(0.0);
    p->set_stage("starting");
    if (j.state() == v1::JOB_STATE_QUEUED) {
      j.set_state(v1::JOB_STATE_RUNNING);
      if (j.started_unix_ns() == 0) j.set_started_unix_ns(WallNowNs());
      j.clear_error();
    }
  });
  if (!job.ok() || !was_queued) return false;
  auto run = std::make_unique<Running>();
  run->job_id = job_id;
  run->part = part;
  running_[UnitId(job_id, part)] = std::move(run);
  return true;
}

absl::Status JobScheduler::FillPartLeaseLocked(const v1::Job& job, Running& run,
                                               v1::WorkLease& lease) {
  lease.set_part(run.part);
  if (run.part != kPrepare) run.inputs.push_back(kPrepare);
  if (run.part == kStitch) {
    for (int k = 1; k <= job.segments(); ++k) {
      run.inputs.push_back(absl::StrCat(kSegmentPrefix, k));
    }
  }
  for (const std::string& input : run.inputs) {
    std::error_code error;
    const auto bytes = fs::file_size(PartPath(job.job_id(), input), error);
    if (error) {
      return absl::DataLossError(
          absl::StrCat("the upload of part ", input, " is gone: ", error.message()));
    }
    v1::WorkInput* entry = lease.add_inputs();
    entry->set_name(input);
    entry->set_bytes(static_cast<int64_t>(bytes));
  }
  if (run.part != kStitch) {
    run.out_path = PartPath(job.job_id(), run.part);
    std::error_code error;
    fs::create_directories(fs::path(run.out_path).parent_path(), error);
    if (error) return absl::UnavailableError(absl::StrCat("parts folder: ", error.message()));
  }
  return absl::OkStatus();
}

void JobScheduler::AdvancePartsLocked(const std::string& job_id) {
  std::vector<std::string> ready;
  const absl::StatusOr<v1::Job> job = jobs_->Mutate(job_id, [&](v1::Job& j) {
    if (IsFinished(j.state())) return;
    const v1::JobPart* prepare = FindPart(j, kPrepare);
    const bool prepared = prepare != nullptr && prepare->state() == v1::JOB_STATE_SUCCEEDED;
    bool segments_done = prepared;
    for (v1::JobPart& part : *j.mutable_parts()) {
      if (!IsSegment(part.name())) continue;
      if (prepared && part.state() == v1::JOB_STATE_UNSPECIFIED) {
        part.set_state(v1::JOB_STATE_QUEUED);
        ready.push_back(part.name());
      }
      segments_done = segments_done && part.state() == v1::JOB_STATE_SUCCEEDED;
    }
    v1::JobPart* stitch = FindPart(j, kStitch);
    if (segments_done && stitch != nullptr && stitch->state() == v1::JOB_STATE_UNSPECIFIED) {
      stitch->set_state(v1::JOB_STATE_QUEUED);
      ready.push_back(kStitch);
    }
  });
  if (!job.ok()) return;
  // First in line, in order: the job has begun.
  for (auto it = ready.rbegin(); it != ready.rend(); ++it) {
    queue_.push_front(UnitId(job_id, *it));
  }
  if (!ready.empty()) {
    wake_pending_ = true;
    wake_.notify_all();
  }
}

void JobScheduler::CountRead(const std::string& lease_id, int64_t bytes) {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Running*> run = HeldLeaseLocked(lease_id);
  if (!run.ok() || bytes <= 0) return;
  const std::string& part = (*run)->part;
  (void)jobs_->Mutate((*run)->job_id, [&](v1::Job& j) {
    auto* history = j.mutable_attempt_history();
    if (!part.empty()) {
      v1::JobPart* p = FindPart(j, part);
      if (p == nullptr) return;
      history = p->mutable_attempt_history();
    }
    if (history->empty()) return;
    v1::JobAttempt* last = history->Mutable(history->size() - 1);
    last->set_read_bytes(last->read_bytes() + bytes);
  });
}

absl::StatusOr<v1::Job> JobScheduler::CompletePart(const Running& run, int64_t file_bytes) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    RETURN_IF_ERROR(jobs_
                        ->Mutate(run.job_id,
                                 [&](v1::Job& j) {
                                   v1::JobPart* part = FindPart(j, run.part);
                                   if (part == nullptr) return;
                                   EndAttempt(*part, "succeeded");
                                   part->set_state(v1::JOB_STATE_SUCCEEDED);
                                   part->set_fraction(1.0);
                                   part->set_stage("done");
                                   part->set_file_bytes(file_bytes);
                                 })
                        .status());
    AdvancePartsLocked(run.job_id);
  }
  log::Info("part_committed",
            {{"job_id", run.job_id},
             {"part", run.part},
             {"worker", run.worker_name},
             {"bytes", file_bytes}},
            absl::StrCat("job ", run.job_id, ": part ", run.part, " from worker ", run.worker_name,
                         " is stored (", file_bytes, " bytes)"));
  ASSIGN_OR_RETURN(v1::Job job, jobs_->Get(run.job_id));
  Publish(job, {}, /*last=*/false);
  return job;
}

void JobScheduler::RequeuePart(const Running& run, const std::string& outcome,
                               const std::string& why) {
  const absl::StatusOr<v1::Job> job = jobs_->Get(run.job_id);
  if (!job.ok() || IsFinished(job->state())) return;
  const v1::JobPart* part = FindPart(*job, run.part);
  if (part == nullptr) return;
  if (part->attempts() >= options_.store.max_attempts) {
    EndJob(run.job_id, v1::JOB_STATE_FAILED,
           absl::StrCat("the workers of its part ", run.part, " stopped ", part->attempts(),
                        " times (the last: ", run.worker_name, ", ", why, ")"));
    return;
  }
  std::lock_guard<std::mutex> lock(mu_);
  const absl::StatusOr<v1::Job> queued = jobs_->Mutate(run.job_id, [&](v1::Job& j) {
    v1::JobPart* p = FindPart(j, run.part);
    if (p == nullptr || p->state() != v1::JOB_STATE_RUNNING) return;
    EndAttempt(*p, outcome);
    p->set_state(v1::JOB_STATE_QUEUED);
    p->set_stage("queued again");
    p->set_fraction(0.0);
  });
  if (!queued.ok()) return;
  const v1::JobPart* requeued = FindPart(*queued, run.part);
  if (requeued == nullptr || requeued->state() != v1::JOB_STATE_QUEUED) return;
  queue_.push_front(UnitId(run.job_id, run.part));
  wake_pending_ = true;
  wake_.notify_all();
  finisher_->Schedule([this, job = *queued] { Publish(job, {}, /*last=*/false); });
}

void JobScheduler::FailPart(const Running& run, const std::string& error,
                            std::vector<std::string> logs) {
  (void)jobs_->Mutate(run.job_id, [&](v1::Job& j) {
    v1::JobPart* part = FindPart(j, run.part);
    if (part == nullptr || part->state() != v1::JOB_STATE_RUNNING) return;
    EndAttempt(*part, "failed");
    part->set_state(v1::JOB_STATE_FAILED);
  });
  EndJob(run.job_id, v1::JOB_STATE_FAILED, absl::StrCat("part ", run.part, " failed: ", error), "",
         std::move(logs));
}

v1::JobProgress JobScheduler::SegmentedProgressLocked(const v1::Job& job) const {
  double done = 0.0, total = 0.0;
  int segments_done = 0, segments_running = 0;
  std::string running_stage;
  for (const v1::JobPart& part : job.parts()) {
    const double weight = PartWeight(job, part.name());
    total += weight;
    if (part.state() == v1::JOB_STATE_SUCCEEDED) {
      done += weight;
      segments_done += IsSegment(part.name()) ? 1 : 0;
    } else if (part.state() == v1::JOB_STATE_RUNNING) {
      const auto run = running_.find(UnitId(job.job_id(), part.name()));
      if (run != running_.end()) done += weight * std::clamp(run->second->fraction, 0.0, 1.0);
      segments_running += IsSegment(part.name()) ? 1 : 0;
      if (!IsSegment(part.name())) running_stage = part.name();
    }
  }
  v1::JobProgress progress = job.progress();
  progress.set_fraction(total > 0 ? std::clamp(done / total, 0.0, 1.0) : 0.0);
  progress.set_frames_done(0);
  progress.set_frames_total(0);
  progress.set_stage(!running_stage.empty()
                         ? running_stage
                         : absl::StrCat("segments: ", segments_done, " of ", job.segments(),
                                        " done, ", segments_running, " running"));
  return progress;
}

std::vector<std::string> JobScheduler::DropUnitsLocked(const std::string& job_id) {
  const std::string prefix = job_id + "/";
  queue_.erase(std::remove_if(queue_.begin(), queue_.end(),
                              [&](const std::string& unit) {
                                return unit == job_id || absl::StartsWith(unit, prefix);
                              }),
               queue_.end());
  std::vector<std::string> leases, workers;
  for (const auto& [lease_id, unit] : leases_) {
    if (unit == job_id || absl::StartsWith(unit, prefix)) leases.push_back(lease_id);
  }
  for (const std::string& lease_id : leases) {
    if (std::unique_ptr<Running> run = ReleaseLocked(lease_id)) {
      workers.push_back(run->worker_name);
    }
  }
  return workers;
}

}  // namespace reenact::server
