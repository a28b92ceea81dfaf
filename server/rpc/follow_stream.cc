#include "server/rpc/follow_stream.h"

#include <deque>
#include <mutex>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "proto/grpc_status.h"
#include "proto/write_pump.h"
#include "server/jobs/job_scheduler.h"
#include "server/live/live_hub.h"

namespace reenact::server {
namespace {

// Why `job` follows nothing, for people.
std::string NotFollowingMessage(const v1::Job& job) {
  if (!job.live()) {
    return absl::StrCat("job ", job.job_id(),
                        " is not live (submit it with --live while its take records to follow "
                        "the take)");
  }
  if (IsFinished(job.state())) {
    return absl::StrCat("job ", job.job_id(), " has ended (", v1::JobState_Name(job.state()), ")");
  }
  return absl::StrCat("job ", job.job_id(), " follows no take now: its take ", job.take_id(),
                      " was not being recorded when it was submitted, or has stopped");
}

class FollowStream final : public PumpedWriteReactor<v1::FollowEvent> {
 public:
  FollowStream(ServerContext& context, const v1::FollowRequest& request)
      : PumpedWriteReactor("the follow"), context_(context) {
    if (context_.jobs == nullptr) {
      FinishNow(ToGrpcStatus(absl::UnavailableError("this server runs no jobs")));
      return;
    }
    const absl::StatusOr<v1::Job> job = context_.jobs->Get(request.job_id());
    if (!job.ok()) {
      FinishNow(ToGrpcStatus(job.status()));
      return;
    }
    absl::StatusOr<uint64_t> id = absl::NotFoundError("no live hub");
    if (context_.live != nullptr) {
      id = context_.live->Subscribe(request.job_id(), [this](const v1::FollowEvent& event,
                                                             bool last) { OnEvent(event, last); });
    }
    if (!id.ok()) {
      v1::FollowEvent end;
      end.mutable_end()->set_reason(v1::FOLLOW_END_REASON_NOT_FOLLOWING);
      end.mutable_end()->set_message(NotFollowingMessage(*job));
      OnEvent(end, /*last=*/true);
      return;
    }
    std::lock_guard<std::mutex> lock(mutex());
    subscription_ = *id;
  }

  void OnDone() override {
    uint64_t subscription = 0;
    {
      std::lock_guard<std::mutex> lock(mutex());
      // After the FollowEnd the hub has dropped the subscription already.
      if (!ended_locked()) subscription = subscription_;
    }
    if (subscription != 0) context_.live->Unsubscribe(subscription);
    delete this;
  }

 private:
  // From the hub (its subscriber lock held): queue and write. Frames beyond
  // kFollowMaxQueuedFrames drop the oldest queued frame; other events stay.
  void OnEvent(const v1::FollowEvent& event, bool last) {
    {
      std::lock_guard<std::mutex> lock(mutex());
      if (event.has_frame()) {
        if (queued_frames_ >= kFollowMaxQueuedFrames) DropOldestFrame();
        ++queued_frames_;
      }
      outbox_.push_back(event);
      if (last) {
        MarkEndedLocked();
        if (event.end().reason() == v1::FOLLOW_END_REASON_SHUTDOWN) {
          end_status_ = grpc::Status(grpc::StatusCode::UNAVAILABLE, event.end().message());
        }
      }
    }
    Pump();
  }

  void DropOldestFrame() {
    for (auto it = outbox_.begin(); it != outbox_.end(); ++it) {
      if (it->has_frame()) {
        outbox_.erase(it);
        --queued_frames_;
        return;
      }
    }
  }

  bool TakeNextLocked(v1::FollowEvent* next) override {
    if (outbox_.empty()) return false;
    *next = std::move(outbox_.front());
    outbox_.pop_front();
    if (next->has_frame()) --queued_frames_;
    return true;
  }
  grpc::Status EndStatusLocked() override { return end_status_; }

  ServerContext& context_;
  uint64_t subscription_ = 0;
  std::deque<v1::FollowEvent> outbox_;
  int queued_frames_ = 0;
  grpc::Status end_status_;  // OK, or UNAVAILABLE at a server shutdown.
};

}  // namespace

grpc::ServerWriteReactor<v1::FollowEvent>* NewFollowStream(ServerContext& context,
                                                           const v1::FollowRequest& request) {
  return new FollowStream(context, request);
}

}  // namespace reenact::server
