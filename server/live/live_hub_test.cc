// The live hub with a scripted follower: which takes it follows, the order
// of what subscribers get, skipping when the fit is behind, the ends.
#include "server/live/live_hub.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace reenact::server {
namespace {

// Every wait is bounded by this.
constexpr auto kWait = std::chrono::seconds(20);

// A follower that makes a mesh at the first set and a frame per set (none
// for sequences in `unfitted`), taking `fit_ms` per set.
struct Script {
  int fit_ms = 0;
  std::vector<uint64_t> unfitted;
  // Counts the sets pushed (when set).
  std::shared_ptr<std::atomic<int>> pushed;
};

// Waits until `counter` reaches `n`.
void WaitCount(const std::atomic<int>& counter, int n) {
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (counter.load() < n && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_GE(counter.load(), n);
}

class ScriptedFollower final : public LiveFollower {
 public:
  explicit ScriptedFollower(Script script) : script_(std::move(script)) {}

  absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) override {
    std::this_thread::sleep_for(std::chrono::milliseconds(script_.fit_ms));
    if (script_.pushed) ++*script_.pushed;
    LiveFit fit;
    fit.fit_ms = script_.fit_ms;
    if (pushed_ == 0) {
      fit.mesh.emplace();
      fit.mesh->set_model_name("scripted");
    }
    for (uint64_t s : script_.unfitted) {
      if (s == set.sequence()) return fit;
    }
    fit.frame.emplace();
    fit.frame->set_frame_index(pushed_++);
    fit.frame->set_stamp_ns(set.stamp_ns());
    fit.frame->mutable_body()->set_valid(true);
    return fit;
  }

 private:
  Script script_;
  int pushed_ = 0;
};

LiveHubOptions ScriptedOptions(Script script = {}) {
  LiveHubOptions options;
  options.factory = [script](const std::string& method, const v1::TakeInfo&,
                             const std::vector<v1::SensorCalibration>&,
                             const std::map<std::string, std::string>& job_options)
      -> absl::StatusOr<std::unique_ptr<LiveFollower>> {
    // The method's own follower: this one follows for "body" only.
    if (method != "body") {
      return absl::UnimplementedError("method " + method + " cannot follow a take");
    }
    if (job_options.contains("bad")) return absl::InvalidArgumentError("unknown option bad");
    return std::make_unique<ScriptedFollower>(script);
  };
  return options;
}

v1::FrameSet Set(uint64_t sequence) {
  v1::FrameSet set;
  set.set_sequence(sequence);
  set.set_stamp_ns(static_cast<int64_t>(sequence) * 33'333'333);
  return set;
}

// Collects a subscriber's events.
class Subscriber {
 public:
  FollowEventCallback Callback() {
    return [this](const v1::FollowEvent& event, bool last) {
      std::lock_guard<std::mutex> lock(mu_);
      events_.push_back(event);
      ended_ = ended_ || last;
      changed_.notify_all();
    };
  }
  // The events once the end came (fails the test on timeout).
  std::vector<v1::FollowEvent> WaitEnd() {
    std::unique_lock<std::mutex> lock(mu_);
    EXPECT_TRUE(changed_.wait_for(lock, kWait, [&] { return ended_; }));
    return events_;
  }
  // Waits until `n` frames came.
  void WaitFrames(int n) {
    std::unique_lock<std::mutex> lock(mu_);
    EXPECT_TRUE(changed_.wait_for(lock, kWait, [&] {
      int frames = 0;
      for (const auto& e : events_) frames += e.has_frame() ? 1 : 0;
      return frames >= n;
    }));
  }

 private:
  std::mutex mu_;
  std::condition_variable changed_;
  std::vector<v1::FollowEvent> events_;
  bool ended_ = false;
};

// What a job's callbacks heard.
struct JobLog {
  std::mutex mu;
  std::condition_variable changed;
  int64_t last_progress = 0;
  std::vector<LiveFollowSummary> ends;

  LiveJobCallbacks Callbacks() {
    LiveJobCallbacks callbacks;
    callbacks.progress = [this](int64_t frames) {
      std::lock_guard<std::mutex> lock(mu);
      last_progress = frames;
    };
    callbacks.ended = [this](const LiveFollowSummary& summary) {
      std::lock_guard<std::mutex> lock(mu);
      ends.push_back(summary);
      changed.notify_all();
    };
    return callbacks;
  }
  LiveFollowSummary WaitEnd() {
    std::unique_lock<std::mutex> lock(mu);
    EXPECT_TRUE(changed.wait_for(lock, kWait, [&] { return !ends.empty(); }));
    return ends.empty() ? LiveFollowSummary{} : ends.front();
  }
};

TEST(LiveHub, FollowsOnlyTakesIngestCallsRecording) {
  LiveHub hub(ScriptedOptions());
  JobLog log;
  EXPECT_EQ(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).code(),
            absl::StatusCode::kFailedPrecondition);
  hub.TakeOpened("t1", {}, {});
  EXPECT_TRUE(hub.Recording("t1"));
  EXPECT_FALSE(hub.Follows("t1"));
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).ok());
  EXPECT_TRUE(hub.Follows("t1"));
  EXPECT_EQ(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).code(),
            absl::StatusCode::kAlreadyExists);
  hub.TakeEnded("t1", v1::TAKE_STATE_COMPLETE);
  EXPECT_FALSE(hub.Recording("t1"));
  EXPECT_EQ(log.WaitEnd().reason, v1::FOLLOW_END_REASON_TAKE_COMPLETE);
  EXPECT_EQ(hub.Follow("j2", "t1", "body", {}, log.Callbacks()).code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST(LiveHub, WithoutFactoryFollowsNothing) {
  LiveHub hub(LiveHubOptions{});
  EXPECT_FALSE(hub.enabled());
  hub.TakeOpened("t1", {}, {});
  EXPECT_EQ(hub.Follow("j1", "t1", "body", {}, {}).code(), absl::StatusCode::kUnimplemented);
}

TEST(LiveHub, MeshFirstThenFramesInOrderThenTheEnd) {
  auto pushed = std::make_shared<std::atomic<int>>(0);
  Script script;
  script.unfitted = {3};
  script.pushed = pushed;
  LiveHub hub(ScriptedOptions(script));
  hub.TakeOpened("t1", {}, {});
  JobLog log;
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).ok());
  Subscriber subscriber;
  ASSERT_TRUE(hub.Subscribe("j1", subscriber.Callback()).ok());
  for (uint64_t s = 1; s <= 6; ++s) {
    hub.FrameSetArrived("t1", Set(s), 1000 + static_cast<int64_t>(s));
    WaitCount(*pushed, static_cast<int>(s));  // One at a time: nothing skipped.
  }
  hub.TakeEnded("t1", v1::TAKE_STATE_COMPLETE);
  const std::vector<v1::FollowEvent> events = subscriber.WaitEnd();
  ASSERT_EQ(events.size(), 1u + 5u + 1u);
  EXPECT_EQ(events.front().mesh().model_name(), "scripted");
  uint64_t previous = 0;
  for (size_t i = 1; i + 1 < events.size(); ++i) {
    const v1::FollowEvent& e = events[i];
    ASSERT_TRUE(e.has_frame());
    EXPECT_EQ(e.frame().frame_index(), static_cast<int>(i) - 1);
    EXPECT_GT(e.sequence(), previous);
    EXPECT_NE(e.sequence(), 3u);
    EXPECT_EQ(e.arrived_unix_ns(), 1000 + static_cast<int64_t>(e.sequence()));
    EXPECT_GT(e.published_unix_ns(), 0);
    previous = e.sequence();
  }
  const v1::FollowEnd& end = events.back().end();
  EXPECT_EQ(end.reason(), v1::FOLLOW_END_REASON_TAKE_COMPLETE);
  EXPECT_EQ(end.frames_received(), 6);
  EXPECT_EQ(end.frames_followed(), 5);
  EXPECT_EQ(end.frames_unfitted(), 1);
  EXPECT_EQ(end.frames_skipped(), 0);
  const LiveFollowSummary summary = log.WaitEnd();
  EXPECT_EQ(summary.frames_followed, 5);
  std::lock_guard<std::mutex> lock(log.mu);
  EXPECT_EQ(log.last_progress, 5);
}

TEST(LiveHub, SkipsToTheNewestSetWhenTheFitIsBehind) {
  Script script;
  script.fit_ms = 30;
  LiveHub hub(ScriptedOptions(script));
  hub.TakeOpened("t1", {}, {});
  JobLog log;
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).ok());
  Subscriber subscriber;
  ASSERT_TRUE(hub.Subscribe("j1", subscriber.Callback()).ok());
  for (uint64_t s = 1; s <= 20; ++s) hub.FrameSetArrived("t1", Set(s), 0);
  hub.TakeEnded("t1", v1::TAKE_STATE_INTERRUPTED);
  const std::vector<v1::FollowEvent> events = subscriber.WaitEnd();
  const v1::FollowEnd& end = events.back().end();
  EXPECT_EQ(end.reason(), v1::FOLLOW_END_REASON_TAKE_INTERRUPTED);
  EXPECT_EQ(end.frames_received(), 20);
  EXPECT_GT(end.frames_skipped(), 0);
  EXPECT_EQ(end.frames_followed() + end.frames_skipped() + end.frames_unfitted(), 20);
  uint64_t previous = 0;
  for (const v1::FollowEvent& e : events) {
    if (!e.has_frame()) continue;
    EXPECT_GT(e.sequence(), previous);
    previous = e.sequence();
  }
  EXPECT_EQ(previous, 20u) << "the newest set is always fitted";
  // The end reaches the subscriber before the job's ended callback: wait for
  // the callback too, or the follow's thread may still write to `log` as
  // the test returns and destroys it.
  EXPECT_EQ(log.WaitEnd().reason, v1::FOLLOW_END_REASON_TAKE_INTERRUPTED);
}

TEST(LiveHub, LateSubscriberGetsTheNewestMeshFirst) {
  LiveHub hub(ScriptedOptions());
  hub.TakeOpened("t1", {}, {});
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, {}).ok());
  Subscriber early;
  ASSERT_TRUE(hub.Subscribe("j1", early.Callback()).ok());
  hub.FrameSetArrived("t1", Set(1), 0);
  early.WaitFrames(1);
  Subscriber late;
  ASSERT_TRUE(hub.Subscribe("j1", late.Callback()).ok());
  hub.FrameSetArrived("t1", Set(2), 0);
  late.WaitFrames(1);
  hub.TakeEnded("t1", v1::TAKE_STATE_COMPLETE);
  const std::vector<v1::FollowEvent> events = late.WaitEnd();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_TRUE(events[0].has_mesh());
  EXPECT_EQ(events[1].sequence(), 2u);
  EXPECT_TRUE(events[2].has_end());
}

TEST(LiveHub, StopEndsTheFollowWithoutTheEndedCallback) {
  LiveHub hub(ScriptedOptions());
  hub.TakeOpened("t1", {}, {});
  JobLog log;
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, log.Callbacks()).ok());
  Subscriber subscriber;
  ASSERT_TRUE(hub.Subscribe("j1", subscriber.Callback()).ok());
  hub.Stop("j1", v1::FOLLOW_END_REASON_CANCELLED, "the job was cancelled");
  const std::vector<v1::FollowEvent> events = subscriber.WaitEnd();
  EXPECT_EQ(events.back().end().reason(), v1::FOLLOW_END_REASON_CANCELLED);
  EXPECT_FALSE(hub.Follows("t1"));
  EXPECT_EQ(hub.Subscribe("j1", Subscriber().Callback()).status().code(),
            absl::StatusCode::kNotFound);
  hub.FrameSetArrived("t1", Set(1), 0);
  hub.TakeEnded("t1", v1::TAKE_STATE_COMPLETE);
  hub.Shutdown();  // Joins the thread: no callback can come after.
  std::lock_guard<std::mutex> lock(log.mu);
  EXPECT_TRUE(log.ends.empty());
}

TEST(LiveHub, FactoryErrorEndsTheFollowAsFailed) {
  LiveHub hub(ScriptedOptions());
  hub.TakeOpened("t1", {}, {});
  JobLog log;
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {{"bad", "1"}}, log.Callbacks()).ok());
  const LiveFollowSummary summary = log.WaitEnd();
  EXPECT_EQ(summary.reason, v1::FOLLOW_END_REASON_FAILED);
  EXPECT_EQ(summary.error.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(summary.message.find("unknown option bad"), std::string::npos) << summary.message;
}

TEST(LiveHub, TheJobsMethodChoosesTheFollower) {
  LiveHub hub(ScriptedOptions());
  hub.TakeOpened("t1", {}, {});
  JobLog log;
  ASSERT_TRUE(hub.Follow("j1", "t1", "rigid-carved", {}, log.Callbacks()).ok());
  const LiveFollowSummary summary = log.WaitEnd();
  EXPECT_EQ(summary.reason, v1::FOLLOW_END_REASON_FAILED);
  EXPECT_EQ(summary.error.code(), absl::StatusCode::kUnimplemented);
  EXPECT_NE(summary.message.find("method rigid-carved cannot follow"), std::string::npos)
      << summary.message;
}

TEST(LiveHub, ShutdownEndsEveryFollow) {
  auto hub = std::make_unique<LiveHub>(ScriptedOptions());
  hub->TakeOpened("t1", {}, {});
  ASSERT_TRUE(hub->Follow("j1", "t1", "body", {}, {}).ok());
  Subscriber subscriber;
  ASSERT_TRUE(hub->Subscribe("j1", subscriber.Callback()).ok());
  hub->Shutdown();
  EXPECT_EQ(subscriber.WaitEnd().back().end().reason(), v1::FOLLOW_END_REASON_SHUTDOWN);
  EXPECT_EQ(hub->Follow("j2", "t1", "body", {}, {}).code(), absl::StatusCode::kUnavailable);
  hub.reset();
}

TEST(LiveHub, TwoJobsFollowOneTake) {
  LiveHub hub(ScriptedOptions());
  hub.TakeOpened("t1", {}, {});
  ASSERT_TRUE(hub.Follow("j1", "t1", "body", {}, {}).ok());
  ASSERT_TRUE(hub.Follow("j2", "t1", "body", {}, {}).ok());
  Subscriber a, b;
  ASSERT_TRUE(hub.Subscribe("j1", a.Callback()).ok());
  ASSERT_TRUE(hub.Subscribe("j2", b.Callback()).ok());
  hub.FrameSetArrived("t1", Set(1), 0);
  hub.TakeEnded("t1", v1::TAKE_STATE_COMPLETE);
  for (Subscriber* s : {&a, &b}) {
    const std::vector<v1::FollowEvent> events = s->WaitEnd();
    ASSERT_EQ(events.size(), 3u);
    EXPECT_EQ(events[1].sequence(), 1u);
  }
}

}  // namespace
}  // namespace reenact::server
