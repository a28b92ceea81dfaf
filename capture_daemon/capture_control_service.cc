#include "capture_daemon/capture_control_service.h"

#include "proto/grpc_status.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {

namespace {

// Callback-API handlers; each finishes its reactor at once (the controller
// answers without waiting on devices or the network).
class CaptureControlService final : public v1::CaptureControl::CallbackService {
 public:
  explicit CaptureControlService(CaptureController* controller) : controller_(controller) {}

  grpc::ServerUnaryReactor* ListSensors(grpc::CallbackServerContext* context,
                                        const v1::ListSensorsRequest*,
                                        v1::ListSensorsResponse* response) override {
    for (v1::SensorInfo& info : controller_->ListSensors()) *response->add_sensors() = std::move(info);
    return Finish(context, absl::OkStatus());
  }

  grpc::ServerUnaryReactor* StartTake(grpc::CallbackServerContext* context,
                                      const v1::StartTakeRequest* request,
                                      v1::StartTakeResponse* response) override {
    absl::StatusOr<std::string> take_id = controller_->StartTake(*request);
    if (take_id.ok()) response->set_take_id(*take_id);
    return Finish(context, take_id.status());
  }

  grpc::ServerUnaryReactor* StopTake(grpc::CallbackServerContext* context,
                                     const v1::StopTakeRequest*,
                                     v1::StopTakeResponse* response) override {
    absl::StatusOr<v1::StopTakeResponse> stopped = controller_->StopTake();
    if (stopped.ok()) *response = std::move(*stopped);
    return Finish(context, stopped.status());
  }

  grpc::ServerUnaryReactor* Status(grpc::CallbackServerContext* context,
                                   const v1::StatusRequest*,
                                   v1::DaemonStatus* response) override {
    *response = controller_->Status();
    return Finish(context, absl::OkStatus());
  }

 private:
  static grpc::ServerUnaryReactor* Finish(grpc::CallbackServerContext* context,
                                          const absl::Status& status) {
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(ToGrpcStatus(status));
    return reactor;
  }

  CaptureController* controller_;
};

}  // namespace

std::unique_ptr<grpc::Service> CreateCaptureControlService(CaptureController* controller) {
  return std::make_unique<CaptureControlService>(controller);
}

}  // namespace reenact::capture
