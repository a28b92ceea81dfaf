#include "server/jobs/live_jobs.h"

#include <algorithm>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"
#include "common/log/log.h"

namespace reenact::server {

LiveJobs::LiveJobs(LiveHub* hub, JobStore* jobs, std::mutex& mu, Hooks hooks)
    : hub_(hub), jobs_(jobs), mu_(mu), hooks_(std::move(hooks)) {}

absl::Status LiveJobs::CheckFollowable(const std::string& take_id, bool live) const {
  if (!live) {
    return absl::FailedPreconditionError(absl::StrCat(
        "take ", take_id,
        " is still being recorded; submit the job once it is complete (or, with a method "
        "that can follow a take, as a live job to follow it now: reenact jobs submit --live)"));
  }
  if (hub_ == nullptr || !hub_->enabled()) {
    return absl::FailedPreconditionError(
        absl::StrCat("take ", take_id,
                     " is still being recorded and this server cannot follow takes live; submit "
                     "the job once the take is complete"));
  }
  if (!hub_->Recording(take_id)) {
    // The store has opened it; ingest has not told the hub yet.
    return absl::UnavailableError(
        absl::StrCat("take ", take_id, " is being opened; submit again in a moment"));
  }
  return absl::OkStatus();
}

absl::StatusOr<v1::Job> LiveJobs::FollowLocked(const v1::Job& job) {
  const std::string& job_id = job.job_id();
  LiveJobCallbacks callbacks;
  callbacks.progress = [this, job_id](int64_t frames) { Progress(job_id, frames); };
  callbacks.ended = [this, job_id](const LiveFollowSummary& summary) { Ended(job_id, summary); };
  const absl::Status followed =
      hub_->Follow(job_id, job.take_id(), job.method(),
                   {job.options().begin(), job.options().end()}, std::move(callbacks));
  if (!followed.ok()) {
    if (absl::IsFailedPrecondition(followed)) return followed;
    // The job was stored: it fails with the reason rather than vanish.
    const absl::StatusOr<v1::Job> failed = jobs_->Mutate(job_id, [&](v1::Job& j) {
      j.set_state(v1::JOB_STATE_FAILED);
      j.set_finished_unix_ns(WallNowNs());
      j.set_error(absl::StrCat("the take could not be followed: ", followed.message()));
    });
    if (failed.ok()) hooks_.log_end(*failed);
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

std::optional<std::string> LiveJobs::NextHandoffLocked() {
  if (handoff_.empty()) return std::nullopt;
  std::string job_id = std::move(handoff_.front());
  handoff_.pop_front();
  return job_id;
}

std::string LiveJobs::StopLocked(const std::string& job_id) {
  if (following_.erase(job_id) > 0) {
    hub_->Stop(job_id, v1::FOLLOW_END_REASON_CANCELLED, "the job was cancelled");
    return "cancelled by a client while following its take";
  }
  const auto it = std::find(handoff_.begin(), handoff_.end(), job_id);
  if (it == handoff_.end()) return "";
  handoff_.erase(it);
  return "cancelled by a client before its worker started";
}

void LiveJobs::Progress(const std::string& job_id, int64_t frames_followed) {
  // Only noted: the scheduler thread stores and publishes it (a catalog
  // write must not hold up the follower).
  std::lock_guard<std::mutex> lock(mu_);
  if (following_.contains(job_id)) progress_[job_id] = frames_followed;
}

void LiveJobs::PublishProgress() {
  std::map<std::string, int64_t> noted;
  {
    std::lock_guard<std::mutex> lock(mu_);
    noted.swap(progress_);
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
    if (job.ok()) hooks_.publish(*job, {}, /*last=*/false);
  }
}

void LiveJobs::Ended(const std::string& job_id, const LiveFollowSummary& summary) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (following_.erase(job_id) == 0) return;
    progress_.erase(job_id);
    if (summary.reason != v1::FOLLOW_END_REASON_FAILED) {
      // The take is stored: the same job goes on with a worker, before the
      // queued jobs.
      handoff_.push_back(job_id);
      hooks_.wake_locked();
    }
  }
  std::vector<std::string> logs = {
      absl::StrCat(summary.message, "; followed ", summary.frames_followed, " of ",
                   summary.frames_received, " frame sets (", summary.frames_skipped, " skipped)")};
  if (summary.reason == v1::FOLLOW_END_REASON_FAILED) {
    hooks_.end(job_id, v1::JOB_STATE_FAILED, summary.message, std::move(logs));
    return;
  }
  if (auto job = jobs_->Get(job_id); job.ok()) {
    hooks_.publish(*job, std::move(logs), /*last=*/false);
  }
}

}  // namespace reenact::server
