#include "server/rpc/ingest_service.h"

#include <algorithm>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"
#include "proto/grpc_status.h"
#include "server/live/live_hub.h"
#include "server/metrics/server_metrics.h"
#include "server/rpc/rpc_auth.h"
#include "server/store/frame_set_validation.h"

namespace reenact::server {
namespace {

using Reactor = grpc::ServerBidiReactor<v1::IngestRequest, v1::IngestResponse>;

v1::IngestResponse Closed(const v1::Take& take) {
  v1::IngestResponse response;
  v1::TakeClosed* closed = response.mutable_closed();
  closed->set_take_id(take.take_id());
  closed->set_durable_sequence(take.durable_sequence());
  closed->set_frame_set_count(take.frame_set_count());
  int64_t frames = 0;
  for (const v1::TakeSensor& s : take.sensors()) frames += s.frame_count();
  closed->set_frame_count(frames);
  closed->set_size_bytes(take.size_bytes());
  return response;
}

// One Ingest stream. Reads one request at a time; answers go out one write
// at a time from an outbox, acks coalesced to the latest durable sequence.
// The gRPC stream is finished only after the take's recorder (if any) has
// called OnFinished, so the recorder never calls a deleted reactor.
class IngestStream final : public Reactor, public RecorderObserver {
 public:
  IngestStream(ServerContext& context, rpc::Principal principal)
      : context_(context), principal_(std::move(principal)) {
    ReadNext();
  }

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override { delete this; }
  void OnDurable(uint64_t durable_sequence) override;
  void OnFinished(const RecordingResult& result) override;

 private:
  enum class Phase { kAwaitOpen, kOpening, kRecording, kComplete, kEnding };

  void HandleOpen(const v1::OpenTake& open);
  void OpenDone(absl::StatusOr<TakeOpenResult> result);
  void HandleFrameSet(v1::FrameSet set, int64_t arrived_unix_ns);
  void HandleSensorLost(const v1::SensorLost& lost);
  void HandleClose(const v1::CloseTake& close);
  void HandleEndOfInput();
  // Ends the stream with `status`; a recording take is interrupted first.
  void Fail(const absl::Status& status);
  // Starts the next read unless the take's queue is full (then OnDurable
  // resumes reading).
  void ReadNext();
  // Starts the next write, or finishes the stream when all is said.
  void Pump();
  Phase phase() {
    std::lock_guard<std::mutex> lock(mu_);
    return phase_;
  }
  // The phase and recorder for a `what` message (e.g. "FrameSet"). Fails the
  // stream (FailedPrecondition) when no take was opened yet and returns
  // kAwaitOpen then.
  std::pair<Phase, std::shared_ptr<TakeRecorder>> PhaseFor(std::string_view what);

  ServerContext& context_;
  // Who opened the stream: the take it creates is theirs.
  const rpc::Principal principal_;
  v1::IngestRequest request_;  // Target of the one outstanding read.

  std::mutex mu_;
  Phase phase_ = Phase::kAwaitOpen;
  bool cancelled_ = false;
  std::string take_id_;
  v1::TakeInfo info_;  // OpenTake's, for the live hub.
  std::shared_ptr<TakeRecorder> recorder_;
  v1::Take complete_take_;  // kComplete: the stored take.
  absl::Status own_error_;  // Why this stream stopped its recording.
  bool close_asked_ = false;
  bool read_paused_ = false;
  bool acks_on_ = false;
  uint64_t durable_ = 0;
  uint64_t acked_ = 0;
  std::deque<v1::IngestResponse> outbox_;
  v1::IngestResponse in_flight_;
  bool writing_ = false;
  bool writes_broken_ = false;
  std::optional<grpc::Status> final_status_;
  bool finished_ = false;
};

void IngestStream::ReadNext() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (phase_ == Phase::kOpening || phase_ == Phase::kEnding || cancelled_) return;
    if (recorder_ && recorder_->queued_bytes() > context_.ingest_queue_limit_bytes) {
      read_paused_ = true;
      return;
    }
  }
  StartRead(&request_);
}

void IngestStream::OnReadDone(bool ok) {
  if (!ok) {
    HandleEndOfInput();
    return;
  }
  v1::IngestRequest request = std::move(request_);
  request_.Clear();
  switch (request.kind_case()) {
    case v1::IngestRequest::kOpen:
      HandleOpen(request.open());
      break;
    case v1::IngestRequest::kFrameSet:
      HandleFrameSet(std::move(*request.mutable_frame_set()), WallNowNs());
      break;
    case v1::IngestRequest::kSensorLost:
      HandleSensorLost(request.sensor_lost());
      break;
    case v1::IngestRequest::kClose:
      HandleClose(request.close());
      break;
    default:
      Fail(absl::InvalidArgumentError(
          "IngestRequest holds none of open, frame_set, sensor_lost, close"));
  }
}

void IngestStream::HandleOpen(const v1::OpenTake& open) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (phase_ == Phase::kAwaitOpen) {
      phase_ = Phase::kOpening;
      take_id_ = open.take_id();
      info_ = open.info();
    }
  }
  if (phase() != Phase::kOpening) {
    Fail(absl::FailedPreconditionError("OpenTake sent twice on one stream"));
    return;
  }
  TakeOpenRequest request{
      open.take_id(),   open.info(),     {open.sensors().begin(), open.sensors().end()},
      open.daemon_id(), principal_.name, principal_.admin()};
  context_.blocking->Schedule(
      [this, request = std::move(request)] { OpenDone(context_.takes->OpenTake(request, this)); });
}

void IngestStream::OpenDone(absl::StatusOr<TakeOpenResult> result) {
  if (!result.ok()) {
    Fail(result.status());
    return;
  }
  // Before the stream can end the recording, so that the hub hears the
  // take's end after its opening.
  if (context_.live != nullptr && result->recorder != nullptr) {
    std::vector<v1::SensorCalibration> sensors;
    for (const auto& [id, calibration] : result->recorder->sensors()) {
      sensors.push_back(calibration);
    }
    context_.live->TakeOpened(take_id_, info_, std::move(sensors));
  }
  bool cancelled = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    recorder_ = result->recorder;
    cancelled = cancelled_;
    if (!cancelled) {
      phase_ = recorder_ ? Phase::kRecording : Phase::kComplete;
      complete_take_ = result->row.take;
      durable_ = acked_ = result->durable_sequence;
      acks_on_ = recorder_ != nullptr;
      v1::IngestResponse response;
      v1::TakeOpened* opened = response.mutable_opened();
      opened->set_take_id(take_id_);
      opened->set_durable_sequence(result->durable_sequence);
      opened->set_resumed(result->resumed);
      outbox_.push_back(std::move(response));
    }
  }
  if (cancelled) {
    Fail(absl::CancelledError("the ingest stream was cancelled"));
    return;
  }
  Pump();
  ReadNext();
}

std::pair<IngestStream::Phase, std::shared_ptr<TakeRecorder>> IngestStream::PhaseFor(
    std::string_view what) {
  Phase p;
  std::shared_ptr<TakeRecorder> recorder;
  {
    std::lock_guard<std::mutex> lock(mu_);
    p = phase_;
    recorder = recorder_;
  }
  if (p == Phase::kAwaitOpen) {
    Fail(absl::FailedPreconditionError(
        absl::StrCat(std::string(what), " before OpenTake: open the take first")));
  }
  return {p, std::move(recorder)};
}

void IngestStream::HandleFrameSet(v1::FrameSet set, int64_t arrived_unix_ns) {
  auto [p, recorder] = PhaseFor("FrameSet");
  if (p == Phase::kAwaitOpen) return;
  if (p == Phase::kComplete) {
    Fail(absl::AlreadyExistsError(
        absl::StrCat("take ", take_id_, " is complete; it takes no more frame sets")));
    return;
  }
  if (p != Phase::kRecording) return;
  absl::Status status = recorder->CheckNextSequence(set.sequence());
  if (status.ok()) {
    status = ValidateFrameSet(set, recorder->sensors(), context_.takes->limits());
    if (!status.ok()) {
      LimitHit("frame_set", {{"take_id", take_id_}, {"sequence", set.sequence()}},
               status.message());
    }
  }
  const size_t bytes = set.ByteSizeLong();
  // A followed take's sets go to the live hub too: a copy, queued there for
  // the follower's thread (the fit never runs here).
  std::optional<v1::FrameSet> live;
  if (status.ok() && context_.live != nullptr && context_.live->Follows(take_id_)) live = set;
  if (status.ok()) status = recorder->Enqueue(std::move(set));
  if (!status.ok()) {
    Fail(status);
    return;
  }
  IngestFrameSetsCounter().Increment();
  IngestBytesCounter().Increment(static_cast<double>(bytes));
  if (live.has_value()) context_.live->FrameSetArrived(take_id_, std::move(*live), arrived_unix_ns);
  ReadNext();
}

void IngestStream::HandleSensorLost(const v1::SensorLost& lost) {
  auto [p, recorder] = PhaseFor("SensorLost");
  if (p == Phase::kAwaitOpen) return;
  if (p == Phase::kComplete) {
    Fail(absl::AlreadyExistsError(absl::StrCat("take ", take_id_, " is complete")));
    return;
  }
  if (p != Phase::kRecording) return;
  v1::SensorLostRecord record;
  record.set_sensor_id(lost.sensor_id());
  record.set_stamp_ns(lost.stamp_ns());
  record.set_reason(lost.reason());
  if (absl::Status status = recorder->EnqueueSensorLost(std::move(record)); !status.ok()) {
    Fail(status);
    return;
  }
  ReadNext();
}

void IngestStream::HandleClose(const v1::CloseTake& close) {
  auto [p, recorder] = PhaseFor("CloseTake");
  if (p == Phase::kAwaitOpen) return;
  if (p == Phase::kComplete) {
    if (close.last_sequence() != complete_take_.durable_sequence()) {
      Fail(absl::AlreadyExistsError(absl::StrCat(
          "take ", take_id_, " is complete with frame sets 1..", complete_take_.durable_sequence(),
          "; CloseTake.last_sequence is ", close.last_sequence())));
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      phase_ = Phase::kEnding;
      outbox_.push_back(Closed(complete_take_));
      final_status_ = grpc::Status::OK;
    }
    Pump();
    return;
  }
  if (p != Phase::kRecording) return;
  const uint64_t last = recorder->last_sequence();
  if (close.last_sequence() != last) {
    Fail(absl::InvalidArgumentError(absl::StrCat("CloseTake.last_sequence is ",
                                                 close.last_sequence(),
                                                 " but the last FrameSet sent was ", last)));
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    phase_ = Phase::kEnding;
    close_asked_ = true;
  }
  recorder->Finish(true, last, absl::OkStatus());
}

void IngestStream::HandleEndOfInput() {
  switch (phase()) {
    case Phase::kRecording:
      Fail(absl::AbortedError(
          absl::StrCat("the stream ended without CloseTake; take ", take_id_,
                       " is interrupted with its durable frame sets and may be resumed")));
      return;
    case Phase::kAwaitOpen:
    case Phase::kComplete: {
      std::lock_guard<std::mutex> lock(mu_);
      if (phase_ == Phase::kEnding) return;
      phase_ = Phase::kEnding;
      final_status_ = grpc::Status::OK;
      break;
    }
    default:
      return;
  }
  Pump();
}

void IngestStream::OnCancel() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    cancelled_ = true;
    if (phase_ == Phase::kOpening) return;  // OpenDone finishes the job.
  }
  Fail(absl::CancelledError("the ingest stream was cancelled"));
}

void IngestStream::Fail(const absl::Status& status) {
  std::shared_ptr<TakeRecorder> recorder;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (phase_ == Phase::kEnding) return;
    phase_ = Phase::kEnding;
    if (recorder_) {
      own_error_ = status;
      recorder = recorder_;
    } else {
      final_status_ = ToGrpcStatus(status);
    }
  }
  if (recorder) {
    recorder->Finish(false, 0, status);  // OnFinished ends the stream.
  } else {
    Pump();
  }
}

void IngestStream::OnDurable(uint64_t durable_sequence) {
  bool resume = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    durable_ = std::max(durable_, durable_sequence);
    if (read_paused_ && phase_ == Phase::kRecording && !cancelled_ &&
        recorder_->queued_bytes() <= context_.ingest_queue_limit_bytes) {
      read_paused_ = false;
      resume = true;
    }
  }
  Pump();
  if (resume) StartRead(&request_);
}

void IngestStream::OnFinished(const RecordingResult& result) {
  // The store has the take's final row: a live job may now read the file.
  if (context_.live != nullptr) context_.live->TakeEnded(take_id_, result.row.take.state());
  {
    std::lock_guard<std::mutex> lock(mu_);
    phase_ = Phase::kEnding;
    durable_ = std::max(durable_, result.row.take.durable_sequence());
    if (acks_on_ && durable_ > acked_) {
      v1::IngestResponse ack;
      ack.mutable_ack()->set_durable_sequence(durable_);
      outbox_.push_back(std::move(ack));
      acked_ = durable_;
    }
    acks_on_ = false;
    if (close_asked_ && result.row.take.state() == v1::TAKE_STATE_COMPLETE) {
      outbox_.push_back(Closed(result.row.take));
      final_status_ = grpc::Status::OK;
    } else {
      absl::Status why = own_error_.ok() ? result.reason : own_error_;
      if (why.ok()) why = absl::AbortedError(absl::StrCat("take ", take_id_, " was interrupted"));
      final_status_ = ToGrpcStatus(why);
    }
  }
  Pump();
}

void IngestStream::Pump() {
  grpc::Status finish_status;
  bool finish = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (writing_ || finished_) return;
    if (!writes_broken_ && !outbox_.empty()) {
      in_flight_ = std::move(outbox_.front());
      outbox_.pop_front();
      writing_ = true;
    } else if (!writes_broken_ && acks_on_ && durable_ > acked_) {
      in_flight_.Clear();
      in_flight_.mutable_ack()->set_durable_sequence(durable_);
      acked_ = durable_;
      writing_ = true;
    } else if (final_status_) {
      finished_ = true;
      finish = true;
      finish_status = *final_status_;
    } else {
      return;
    }
  }
  if (finish) {
    Finish(finish_status);
  } else {
    StartWrite(&in_flight_);
  }
}

void IngestStream::OnWriteDone(bool ok) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    writing_ = false;
    if (!ok) writes_broken_ = true;
  }
  Pump();
}

}  // namespace

grpc::ServerBidiReactor<v1::IngestRequest, v1::IngestResponse>* IngestService::Ingest(
    grpc::CallbackServerContext* rpc) {
  auto who = Authorize(context_, *rpc, "/reenact.v1.Ingest/Ingest");
  if (!who.ok()) {
    return new RefusedBidi<v1::IngestRequest, v1::IngestResponse>(ToGrpcStatus(who.status()));
  }
  return new IngestStream(context_, *std::move(who));
}

}  // namespace reenact::server
