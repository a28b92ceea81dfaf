// The CaptureControl gRPC service of reenactd
// (proto/reenact/v1/capture_control_service.proto). Each RPC has one short
// handler that reaches the daemon only through the CaptureController
// interface, so that tests drive the handlers with a fake controller over an
// in-process channel.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <grpcpp/impl/service_type.h>

#include "absl/status/statusor.h"
#include "capture_daemon/live_frames.h"
#include "common/rpc/auth.h"
#include "reenact/v1/capture_control_service.pb.h"

namespace reenact::capture {

// What the control service asks of the daemon. Methods are called on gRPC
// threads, concurrently.
class CaptureController {
 public:
  virtual ~CaptureController() = default;
  virtual std::vector<v1::SensorInfo> ListSensors() = 0;
  // The new take's id. FailedPrecondition when a take is being recorded or
  // no sensor streams.
  virtual absl::StatusOr<std::string> StartTake(const v1::StartTakeRequest& request) = 0;
  // FailedPrecondition when no take is being recorded.
  virtual absl::StatusOr<v1::StopTakeResponse> StopTake() = 0;
  virtual v1::DaemonStatus Status() = 0;
  // StreamFrames: `on_set` receives each live set for `request`, and nullptr
  // when the stream ends (LiveFrames::Callback); returns the subscription.
  // InvalidArgument naming an unknown sensor id; Unimplemented by default.
  virtual absl::StatusOr<uint64_t> SubscribeFrames(const v1::StreamFramesRequest& request,
                                                   LiveFrames::Callback on_set);
  // No call of the subscription's `on_set` starts after this returns.
  virtual void UnsubscribeFrames(uint64_t subscription);
};

// The access each CaptureControl RPC needs (common/rpc/auth.h): read
// (viewer, coach, admin) for ListSensors, Status and StreamFrames; ingest or
// manage (capture, coach, admin) for StartTake and StopTake.
const rpc::Authorizer::MethodTable& CaptureControlMethodAccess();

// The service, ready for grpc::ServerBuilder::RegisterService. `controller`
// (and `auth`, when not null: then every call needs a token allowing it)
// must outlive it.
std::unique_ptr<grpc::Service> CreateCaptureControlService(CaptureController* controller,
                                                           const rpc::Authorizer* auth = nullptr);

}  // namespace reenact::capture
