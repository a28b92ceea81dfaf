// The live hub of reenact-server: follows takes while they are recorded and
// publishes each fitted FrameSet to the Follow subscribers of the job that
// asked for it (a live job of a method that can follow takes).
//
// Ingest tells the hub of every recording take: its opening (info and
// calibrations), each accepted FrameSet with the wall-clock time it reached
// the Ingest handler, and its end. A take nobody follows costs a map lookup
// per FrameSet. For a followed take the FrameSet is moved into the
// follower's queue and ingest goes on: the fit runs on the follower's own
// thread (one per live job), never on the ingest path.
//
// The follower thread creates its LiveFollower (LiveFollowerFactory, given
// the job's method: the server's main plugs in the method registry's
// followers, server/live/live_method_follower.h; the hub itself has no
// reconstruction code), then fits FrameSets as they come. When the fit falls
// behind, it skips to the newest queued FrameSet; the skipped ones are
// counted. Each result goes to the job's subscribers as FollowEvents
// (reenactments_service.proto): a mesh when the follower makes one, then the
// frame with its arrival and publication times. A subscriber that joins late
// gets the newest mesh first.
//
// The end of a follow: the take stops recording (the queue is fitted to its
// end first, then LiveJobCallbacks::ended tells the job scheduler, which runs
// the offline method on the whole take), the follower cannot be created
// (ended with the error), Stop (a cancelled job) or Shutdown (neither of
// these two calls `ended`). Subscribers then get a FollowEnd and no more.
//
// Thread-safe. Callbacks are never called with the hub's locks held, except
// subscriber callbacks (FollowEventCallback), which must not block nor call
// the hub.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "reenact/v1/frame.pb.h"
#include "reenact/v1/reenactment.pb.h"
#include "reenact/v1/reenactments_service.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"
#include "reenact/v1/takes_service.pb.h"

namespace reenact::server {

// What a follower made of one FrameSet (recon::LiveUpdate, without the
// reconstruction library).
struct LiveFit {
  // A new mesh (the first FrameSet's, and once the shape has settled).
  std::optional<v1::BodyMesh> mesh;
  // The fitted instant; unset when the FrameSet could not be fitted.
  std::optional<v1::PartFrame> frame;
  // Decode, cloud and fit of this FrameSet, milliseconds.
  double fit_ms = 0.0;
};

// Fits the FrameSets of one take, one after the other.
class LiveFollower {
 public:
  virtual ~LiveFollower() = default;
  // An error is counted as an unfitted FrameSet; the follow goes on.
  virtual absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) = 0;
};

// Makes the follower of a take for a job of `method` from the take's info,
// its sensors' calibrations and the job's options. Its errors end the follow
// (FAILED).
using LiveFollowerFactory = std::function<absl::StatusOr<std::unique_ptr<LiveFollower>>(
    const std::string& method, const v1::TakeInfo& info,
    const std::vector<v1::SensorCalibration>& sensors,
    const std::map<std::string, std::string>& options)>;

struct LiveHubOptions {
  // Makes followers; empty: this server cannot follow takes (live jobs of a
  // recording take are refused).
  LiveFollowerFactory factory;
  // FrameSets a follower's queue holds; beyond, the oldest is dropped (and
  // counted as skipped), so a stalled fit cannot hold much memory.
  int max_queued_sets = 8;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// How a follow ended (what the FollowEnd says).
struct LiveFollowSummary {
  v1::FollowEndReason reason = v1::FOLLOW_END_REASON_UNSPECIFIED;
  std::string message;
  int64_t frames_received = 0;
  int64_t frames_followed = 0;
  int64_t frames_skipped = 0;
  int64_t frames_unfitted = 0;
  // FAILED: why the follower could not be made.
  absl::Status error;
};

// What a live job hears from its follow, on the follower's thread.
struct LiveJobCallbacks {
  // After each fitted FrameSet: the FrameSets followed so far.
  std::function<void(int64_t frames_followed)> progress;
  // Once, when the take stopped recording or the follower could not be
  // made; not after Stop or Shutdown.
  std::function<void(const LiveFollowSummary& summary)> ended;
};

// Gets a subscriber's events; `last` is true on the FollowEnd. Called with
// the hub's subscriber lock held: must not block, nor call the hub.
using FollowEventCallback = std::function<void(const v1::FollowEvent& event, bool last)>;

class LiveHub {
 public:
  explicit LiveHub(LiveHubOptions options);
  // Shutdown().
  ~LiveHub();
  LiveHub(const LiveHub&) = delete;
  LiveHub& operator=(const LiveHub&) = delete;

  // False when no factory was given.
  bool enabled() const { return static_cast<bool>(options_.factory); }

  // Ingest: take `take_id` is recording with `info` and `sensors`.
  void TakeOpened(const std::string& take_id, const v1::TakeInfo& info,
                  std::vector<v1::SensorCalibration> sensors);
  // Ingest: whether a live job follows the take (worth copying its sets).
  bool Follows(const std::string& take_id) const;
  // Whether ingest told the hub that the take is recording (opened and not
  // yet ended).
  bool Recording(const std::string& take_id) const;
  // Ingest: an accepted FrameSet of the take and when it reached the Ingest
  // handler (wall clock, ns since the Unix epoch). Queued for each follower
  // of the take; dropped when none follows it.
  void FrameSetArrived(const std::string& take_id, v1::FrameSet set, int64_t arrived_unix_ns);
  // Ingest: the take stopped recording in `state` (COMPLETE or INTERRUPTED;
  // the store has its final row). Its followers fit what is queued, then end.
  void TakeEnded(const std::string& take_id, v1::TakeState state);

  // Jobs: starts following `take_id` for `job_id`, a job of `method` with
  // `options`. Unimplemented when the hub is not enabled; FailedPrecondition
  // when the take is not recording (as far as ingest told the hub);
  // AlreadyExists when the job follows already; Unavailable after Shutdown.
  absl::Status Follow(const std::string& job_id, const std::string& take_id,
                      const std::string& method, const std::map<std::string, std::string>& options,
                      LiveJobCallbacks callbacks);
  // Jobs: ends the job's follow at once (subscribers get `reason` and
  // `message`; the follower thread stops after the FrameSet it is fitting).
  // `ended` is not called for it; a `progress` call under way may still
  // come, which the caller ignores. Nothing when the job does not follow.
  void Stop(const std::string& job_id, v1::FollowEndReason reason, const std::string& message);

  // Follow RPC: calls `callback` with the newest mesh (if any) at once, then
  // with every event of the job's follow. NotFound when the job follows
  // nothing now (the caller ends the stream with NOT_FOLLOWING).
  absl::StatusOr<uint64_t> Subscribe(const std::string& job_id, FollowEventCallback callback);
  // Stops the calls of a subscription; none is running or comes once it
  // returns.
  void Unsubscribe(uint64_t subscription_id);

  // Ends every follow (SHUTDOWN) and joins the follower threads; later
  // calls are ignored. Idempotent.
  void Shutdown();

 private:
  struct Job;
  struct Take;

  // The follower thread.
  void Run(Job& job);
  // The next FrameSet to fit: the newest queued (the older ones skipped).
  // False once the follow is over (stopped, or the take ended and the queue
  // is empty).
  bool NextSet(Job& job, v1::FrameSet* set, int64_t* arrived_unix_ns);
  // Hands what one FrameSet made to the job's subscribers.
  void Publish(Job& job, LiveFit fit, uint64_t sequence, int64_t arrived_unix_ns);
  // Ends the follow from its own thread (take ended, or the follower could
  // not be made), unless Stop ended it first.
  void EndFromThread(Job& job, v1::FollowEndReason reason, const std::string& message,
                     const absl::Status& error);
  // Removes the job from the maps; false when it was gone already.
  bool Forget(const Job& job);
  // Sends the FollowEnd to the job's subscribers and drops them.
  void EndSubscribers(Job& job, const LiveFollowSummary& summary);
  // Joins the threads of follows that are over.
  void ReapThreads();

  const LiveHubOptions options_;

  // Takes and jobs.
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Take>> takes_;
  std::map<std::string, std::shared_ptr<Job>> jobs_;
  // Every job whose thread has not been joined yet.
  std::vector<std::shared_ptr<Job>> threads_;
  bool shut_down_ = false;

  // Subscribers; taken after mu_ when both are held.
  std::mutex subscribers_mu_;
  struct Subscriber {
    std::string job_id;
    FollowEventCallback callback;
  };
  std::map<uint64_t, Subscriber> subscribers_;
  // The newest mesh of each following job.
  std::map<std::string, v1::BodyMesh> meshes_;
  uint64_t next_subscription_id_ = 1;
};

}  // namespace reenact::server
