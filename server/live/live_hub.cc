#include "server/live/live_hub.h"

#include <atomic>
#include <condition_variable>
#include <deque>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"

namespace reenact::server {

// A recording take, as ingest told it.
struct LiveHub::Take {
  v1::TakeInfo info;
  std::vector<v1::SensorCalibration> sensors;
  std::vector<std::shared_ptr<Job>> followers;
};

// One live job's follow: its queue, its thread and its counts.
struct LiveHub::Job {
  std::string job_id;
  std::string take_id;
  std::string method;
  v1::TakeInfo info;
  std::vector<v1::SensorCalibration> sensors;
  std::map<std::string, std::string> options;
  LiveJobCallbacks callbacks;
  std::thread thread;
  std::atomic<bool> exited{false};

  std::mutex mu;
  std::condition_variable wake;
  // (FrameSet, arrived_unix_ns), oldest first.
  std::deque<std::pair<v1::FrameSet, int64_t>> queue;
  bool take_ended = false;
  v1::TakeState end_state = v1::TAKE_STATE_UNSPECIFIED;
  // Set once, by whoever ends the follow first (Stop or the thread).
  bool over = false;

  // Guarded by the hub's subscribers_mu_: no event after the FollowEnd.
  bool subscribers_ended = false;

  std::atomic<int64_t> received{0};
  std::atomic<int64_t> followed{0};
  std::atomic<int64_t> skipped{0};
  std::atomic<int64_t> unfitted{0};

  LiveFollowSummary Summary(v1::FollowEndReason reason, const std::string& message) const {
    LiveFollowSummary s;
    s.reason = reason;
    s.message = message;
    s.frames_received = received.load();
    s.frames_followed = followed.load();
    s.frames_skipped = skipped.load();
    s.frames_unfitted = unfitted.load();
    return s;
  }
};

absl::Status LiveHubOptions::Validate() const {
  if (max_queued_sets < 1) return absl::InvalidArgumentError("max_queued_sets must be >= 1");
  return absl::OkStatus();
}

LiveHub::LiveHub(LiveHubOptions options) : options_(std::move(options)) {}

LiveHub::~LiveHub() { Shutdown(); }

void LiveHub::TakeOpened(const std::string& take_id, const v1::TakeInfo& info,
                         std::vector<v1::SensorCalibration> sensors) {
  std::lock_guard<std::mutex> lock(mu_);
  if (shut_down_) return;
  auto take = std::make_shared<Take>();
  take->info = info;
  take->sensors = std::move(sensors);
  takes_[take_id] = std::move(take);
}

bool LiveHub::Follows(const std::string& take_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = takes_.find(take_id);
  return it != takes_.end() && !it->second->followers.empty();
}

bool LiveHub::Recording(const std::string& take_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  return takes_.contains(take_id);
}

void LiveHub::FrameSetArrived(const std::string& take_id, v1::FrameSet set,
                              int64_t arrived_unix_ns) {
  std::vector<std::shared_ptr<Job>> followers;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = takes_.find(take_id);
    if (it == takes_.end()) return;
    followers = it->second->followers;
  }
  for (size_t i = 0; i < followers.size(); ++i) {
    Job& job = *followers[i];
    std::lock_guard<std::mutex> lock(job.mu);
    if (job.over || job.take_ended) continue;
    ++job.received;
    if (static_cast<int>(job.queue.size()) >= options_.max_queued_sets) {
      job.queue.pop_front();
      ++job.skipped;
    }
    // The last follower takes the set itself, the others a copy.
    // NOLINTNEXTLINE(bugprone-use-after-move): only the last pass moves; no pass follows it.
    job.queue.emplace_back(i + 1 < followers.size() ? set : std::move(set), arrived_unix_ns);
    job.wake.notify_one();
  }
}

void LiveHub::TakeEnded(const std::string& take_id, v1::TakeState state) {
  std::shared_ptr<Take> take;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = takes_.find(take_id);
    if (it == takes_.end()) return;
    take = std::move(it->second);
    takes_.erase(it);
  }
  for (const std::shared_ptr<Job>& job : take->followers) {
    std::lock_guard<std::mutex> lock(job->mu);
    job->take_ended = true;
    job->end_state = state;
    job->wake.notify_one();
  }
}

absl::Status LiveHub::Follow(const std::string& job_id, const std::string& take_id,
                             const std::string& method,
                             const std::map<std::string, std::string>& options,
                             LiveJobCallbacks callbacks) {
  if (!enabled()) {
    return absl::UnimplementedError("this server cannot follow takes live (no live fit)");
  }
  ReapThreads();
  std::lock_guard<std::mutex> lock(mu_);
  if (shut_down_) return absl::UnavailableError("the server is shutting down");
  if (jobs_.contains(job_id)) {
    return absl::AlreadyExistsError(absl::StrCat("job ", job_id, " follows its take already"));
  }
  const auto it = takes_.find(take_id);
  if (it == takes_.end()) {
    return absl::FailedPreconditionError(absl::StrCat("take ", take_id, " is not being recorded"));
  }
  auto job = std::make_shared<Job>();
  job->job_id = job_id;
  job->take_id = take_id;
  job->info = it->second->info;
  job->sensors = it->second->sensors;
  job->method = method;
  job->options = options;
  job->callbacks = std::move(callbacks);
  it->second->followers.push_back(job);
  jobs_[job_id] = job;
  threads_.push_back(job);
  job->thread = std::thread([this, raw = job.get()] {
    Run(*raw);
    raw->exited = true;
  });
  return absl::OkStatus();
}

void LiveHub::Run(Job& job) {
  absl::StatusOr<std::unique_ptr<LiveFollower>> follower =
      options_.factory(job.method, job.info, job.sensors, job.options);
  if (!follower.ok()) {
    EndFromThread(job, v1::FOLLOW_END_REASON_FAILED,
                  absl::StrCat("the live fit could not start: ", follower.status().message()),
                  follower.status());
    return;
  }
  v1::FrameSet set;
  int64_t arrived_unix_ns = 0;
  while (NextSet(job, &set, &arrived_unix_ns)) {
    absl::StatusOr<LiveFit> fit = (*follower)->Push(set);
    if (!fit.ok()) {
      ++job.unfitted;
      continue;
    }
    const bool fitted = fit->frame.has_value();
    if (!fitted) ++job.unfitted;
    Publish(job, std::move(*fit), set.sequence(), arrived_unix_ns);
    if (fitted && job.callbacks.progress) job.callbacks.progress(job.followed.load());
  }
  v1::TakeState state;
  {
    std::lock_guard<std::mutex> lock(job.mu);
    if (job.over) return;  // Stopped.
    state = job.end_state;
  }
  if (state == v1::TAKE_STATE_COMPLETE) {
    EndFromThread(job, v1::FOLLOW_END_REASON_TAKE_COMPLETE,
                  absl::StrCat("take ", job.take_id, " is complete"), absl::OkStatus());
  } else {
    EndFromThread(job, v1::FOLLOW_END_REASON_TAKE_INTERRUPTED,
                  absl::StrCat("take ", job.take_id, " stopped recording without being closed"),
                  absl::OkStatus());
  }
}

bool LiveHub::NextSet(Job& job, v1::FrameSet* set, int64_t* arrived_unix_ns) {
  std::unique_lock<std::mutex> lock(job.mu);
  job.wake.wait(lock, [&] { return job.over || job.take_ended || !job.queue.empty(); });
  if (job.over || job.queue.empty()) return false;
  job.skipped += static_cast<int64_t>(job.queue.size()) - 1;
  *set = std::move(job.queue.back().first);
  *arrived_unix_ns = job.queue.back().second;
  job.queue.clear();
  return true;
}

void LiveHub::Publish(Job& job, LiveFit fit, uint64_t sequence, int64_t arrived_unix_ns) {
  std::lock_guard<std::mutex> lock(subscribers_mu_);
  if (job.subscribers_ended) return;
  if (fit.mesh.has_value()) {
    v1::FollowEvent event;
    *event.mutable_mesh() = *fit.mesh;
    meshes_[job.job_id] = std::move(*fit.mesh);
    for (auto& [id, subscriber] : subscribers_) {
      if (subscriber.job_id == job.job_id) subscriber.callback(event, /*last=*/false);
    }
  }
  if (!fit.frame.has_value()) return;
  ++job.followed;
  v1::FollowEvent event;
  *event.mutable_frame() = std::move(*fit.frame);
  event.set_arrived_unix_ns(arrived_unix_ns);
  event.set_sequence(sequence);
  event.set_fit_ms(fit.fit_ms);
  event.set_frames_skipped(job.skipped.load());
  event.set_published_unix_ns(WallNowNs());
  for (auto& [id, subscriber] : subscribers_) {
    if (subscriber.job_id == job.job_id) subscriber.callback(event, /*last=*/false);
  }
}

void LiveHub::EndFromThread(Job& job, v1::FollowEndReason reason, const std::string& message,
                            const absl::Status& error) {
  {
    std::lock_guard<std::mutex> lock(job.mu);
    if (job.over) return;
    job.over = true;
  }
  Forget(job);
  LiveFollowSummary summary = job.Summary(reason, message);
  summary.error = error;
  EndSubscribers(job, summary);
  if (job.callbacks.ended) job.callbacks.ended(summary);
}

bool LiveHub::Forget(const Job& job) {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = jobs_.find(job.job_id);
  if (it == jobs_.end() || it->second.get() != &job) return false;
  jobs_.erase(it);
  if (const auto take = takes_.find(job.take_id); take != takes_.end()) {
    std::vector<std::shared_ptr<Job>>& followers = take->second->followers;
    std::erase_if(followers, [&](const std::shared_ptr<Job>& f) { return f.get() == &job; });
  }
  return true;
}

void LiveHub::Stop(const std::string& job_id, v1::FollowEndReason reason,
                   const std::string& message) {
  std::shared_ptr<Job> job;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = jobs_.find(job_id);
    if (it == jobs_.end()) return;
    job = it->second;
  }
  {
    std::lock_guard<std::mutex> lock(job->mu);
    if (job->over) return;
    job->over = true;
    job->queue.clear();
    job->wake.notify_one();
  }
  Forget(*job);
  EndSubscribers(*job, job->Summary(reason, message));
}

void LiveHub::EndSubscribers(Job& job, const LiveFollowSummary& summary) {
  v1::FollowEvent event;
  v1::FollowEnd* end = event.mutable_end();
  end->set_reason(summary.reason);
  end->set_message(summary.message);
  end->set_frames_received(summary.frames_received);
  end->set_frames_followed(summary.frames_followed);
  end->set_frames_skipped(summary.frames_skipped);
  end->set_frames_unfitted(summary.frames_unfitted);
  std::lock_guard<std::mutex> lock(subscribers_mu_);
  job.subscribers_ended = true;
  meshes_.erase(job.job_id);
  for (auto it = subscribers_.begin(); it != subscribers_.end();) {
    if (it->second.job_id != job.job_id) {
      ++it;
      continue;
    }
    it->second.callback(event, /*last=*/true);
    it = subscribers_.erase(it);
  }
}

absl::StatusOr<uint64_t> LiveHub::Subscribe(const std::string& job_id,
                                            FollowEventCallback callback) {
  std::shared_ptr<Job> job;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = jobs_.find(job_id);
    if (it != jobs_.end()) job = it->second;
  }
  std::lock_guard<std::mutex> lock(subscribers_mu_);
  if (job == nullptr || job->subscribers_ended) {
    return absl::NotFoundError(absl::StrCat("job ", job_id, " follows no take now"));
  }
  if (const auto mesh = meshes_.find(job_id); mesh != meshes_.end()) {
    v1::FollowEvent event;
    *event.mutable_mesh() = mesh->second;
    callback(event, /*last=*/false);
  }
  const uint64_t id = next_subscription_id_++;
  subscribers_.emplace(id, Subscriber{job_id, std::move(callback)});
  return id;
}

void LiveHub::Unsubscribe(uint64_t subscription_id) {
  std::lock_guard<std::mutex> lock(subscribers_mu_);
  subscribers_.erase(subscription_id);
}

void LiveHub::ReapThreads() {
  std::vector<std::shared_ptr<Job>> done;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto it = threads_.begin(); it != threads_.end();) {
      if ((*it)->exited.load()) {
        done.push_back(std::move(*it));
        it = threads_.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (const std::shared_ptr<Job>& job : done) job->thread.join();
}

void LiveHub::Shutdown() {
  std::vector<std::string> following;
  std::vector<std::shared_ptr<Job>> threads;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (shut_down_) return;
    shut_down_ = true;
    for (const auto& [id, job] : jobs_) following.push_back(id);
  }
  for (const std::string& id : following) {
    Stop(id, v1::FOLLOW_END_REASON_SHUTDOWN, "the server is shutting down");
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    threads.swap(threads_);
    takes_.clear();
  }
  for (const std::shared_ptr<Job>& job : threads) job->thread.join();
}

}  // namespace reenact::server
