#include "capture_daemon/capture_control_service.h"

#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/rpc/refused_reactor.h"
#include "proto/grpc_status.h"
#include "proto/write_pump.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {

// The callback by value: overrides keep it.
absl::StatusOr<uint64_t> CaptureController::SubscribeFrames(
    const v1::StreamFramesRequest&,
    LiveFrames::Callback) {  // NOLINT(performance-unnecessary-value-param)
  return absl::UnimplementedError("this daemon streams no frames");
}

void CaptureController::UnsubscribeFrames(uint64_t) {}

namespace {

// The reactor of one StreamFrames call: keeps the newest set not yet
// written (an older one is dropped and counted), writes one at a time, and
// ends OK when the daemon ends the stream, CANCELLED when the client goes.
class FrameStream final : public PumpedWriteReactor<v1::LiveFrameSet> {
 public:
  FrameStream(CaptureController* controller, const v1::StreamFramesRequest& request)
      : PumpedWriteReactor("the stream"), controller_(controller) {
    absl::StatusOr<uint64_t> id = controller_->SubscribeFrames(
        request, [this](std::shared_ptr<const v1::LiveFrameSet> set) { OnSet(std::move(set)); });
    if (!id.ok()) {
      FinishNow(ToGrpcStatus(id.status()));
      return;
    }
    std::lock_guard<std::mutex> lock(mutex());
    subscription_ = *id;
  }

  void OnDone() override {
    std::optional<uint64_t> subscription;
    {
      std::lock_guard<std::mutex> lock(mutex());
      subscription = subscription_;
    }
    if (subscription) controller_->UnsubscribeFrames(*subscription);
    delete this;
  }

 private:
  void OnSet(std::shared_ptr<const v1::LiveFrameSet> set) {
    {
      std::lock_guard<std::mutex> lock(mutex());
      if (set == nullptr) {
        MarkEndedLocked();
        next_.reset();  // Nothing is written after the end.
      } else if (!ended_locked()) {
        next_ = std::move(set);
      }
    }
    Pump();
  }

  bool TakeNextLocked(v1::LiveFrameSet* next) override {
    if (next_ == nullptr) return false;
    *next = *next_;
    next_.reset();
    if (first_index_ == 0) first_index_ = next->set_index();
    ++written_;
    next->set_dropped_sets(next->set_index() - first_index_ + 1 - written_);
    return true;
  }
  grpc::Status EndStatusLocked() override { return grpc::Status::OK; }

  CaptureController* controller_;
  std::optional<uint64_t> subscription_;
  std::shared_ptr<const v1::LiveFrameSet> next_;
  uint64_t first_index_ = 0;
  uint64_t written_ = 0;
};

// Callback-API handlers; each finishes its reactor at once (the controller
// answers without waiting on devices or the network).
class CaptureControlService final : public v1::CaptureControl::CallbackService {
 public:
  CaptureControlService(CaptureController* controller, const rpc::Authorizer* auth)
      : controller_(controller), auth_(auth) {}

  grpc::ServerUnaryReactor* ListSensors(grpc::CallbackServerContext* context,
                                        const v1::ListSensorsRequest*,
                                        v1::ListSensorsResponse* response) override {
    if (absl::Status allowed = Allowed(*context, "ListSensors"); !allowed.ok()) {
      return Finish(context, allowed);
    }
    for (v1::SensorInfo& info : controller_->ListSensors())
      *response->add_sensors() = std::move(info);
    return Finish(context, absl::OkStatus());
  }

  grpc::ServerUnaryReactor* StartTake(grpc::CallbackServerContext* context,
                                      const v1::StartTakeRequest* request,
                                      v1::StartTakeResponse* response) override {
    if (absl::Status allowed = Allowed(*context, "StartTake"); !allowed.ok()) {
      return Finish(context, allowed);
    }
    absl::StatusOr<std::string> take_id = controller_->StartTake(*request);
    if (take_id.ok()) response->set_take_id(*take_id);
    return Finish(context, take_id.status());
  }

  grpc::ServerUnaryReactor* StopTake(grpc::CallbackServerContext* context,
                                     const v1::StopTakeRequest*,
                                     v1::StopTakeResponse* response) override {
    if (absl::Status allowed = Allowed(*context, "StopTake"); !allowed.ok()) {
      return Finish(context, allowed);
    }
    absl::StatusOr<v1::StopTakeResponse> stopped = controller_->StopTake();
    if (stopped.ok()) *response = std::move(*stopped);
    return Finish(context, stopped.status());
  }

  grpc::ServerWriteReactor<v1::LiveFrameSet>* StreamFrames(
      grpc::CallbackServerContext* context, const v1::StreamFramesRequest* request) override {
    if (absl::Status allowed = Allowed(*context, "StreamFrames"); !allowed.ok()) {
      return new rpc::RefusedWriter<v1::LiveFrameSet>(ToGrpcStatus(allowed));
    }
    return new FrameStream(controller_, *request);
  }

  grpc::ServerUnaryReactor* Status(grpc::CallbackServerContext* context, const v1::StatusRequest*,
                                   v1::DaemonStatus* response) override {
    if (absl::Status allowed = Allowed(*context, "Status"); !allowed.ok()) {
      return Finish(context, allowed);
    }
    *response = controller_->Status();
    return Finish(context, absl::OkStatus());
  }

 private:
  absl::Status Allowed(const grpc::CallbackServerContext& context, const char* rpc) const {
    if (auth_ == nullptr) return absl::OkStatus();
    return auth_->Authorize(context, absl::StrCat("/reenact.v1.CaptureControl/", rpc)).status();
  }

  static grpc::ServerUnaryReactor* Finish(grpc::CallbackServerContext* context,
                                          const absl::Status& status) {
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(ToGrpcStatus(status));
    return reactor;
  }

  CaptureController* controller_;
  const rpc::Authorizer* auth_;
};

}  // namespace

const rpc::Authorizer::MethodTable& CaptureControlMethodAccess() {
  static const auto* const table = new rpc::Authorizer::MethodTable{
      {"/reenact.v1.CaptureControl/ListSensors", rpc::kRead},
      {"/reenact.v1.CaptureControl/Status", rpc::kRead},
      {"/reenact.v1.CaptureControl/StreamFrames", rpc::kRead},
      {"/reenact.v1.CaptureControl/StartTake", rpc::kIngest | rpc::kManage},
      {"/reenact.v1.CaptureControl/StopTake", rpc::kIngest | rpc::kManage},
  };
  return *table;
}

std::unique_ptr<grpc::Service> CreateCaptureControlService(CaptureController* controller,
                                                           const rpc::Authorizer* auth) {
  return std::make_unique<CaptureControlService>(controller, auth);
}

}  // namespace reenact::capture
