// Client side of the server's Takes service and the capture daemon's
// CaptureControl service: what the `reenact` tool, the viewer and scripts use
// to list, inspect, download and delete stored takes and to drive a daemon.
// Every call has a deadline; errors carry the address they were sent to.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/rpc/channel.h"
#include "proto/state_names.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"

namespace reenact::client {

struct ConnectionOptions {
  // HOST:PORT of the server or daemon.
  std::string address;
  // Deadline of unary calls, seconds.
  double timeout_s = 10.0;
  // Largest message accepted, bytes.
  int max_message_bytes = 64 << 20;
  // TLS trust and the bearer token (common/rpc/channel.h); none by default.
  rpc::ClientSecurity security{};
};

// A channel with `options.security`: TLS when it holds a CA, the token on
// every call when it holds one.
std::shared_ptr<grpc::Channel> MakeChannel(const ConnectionOptions& options);

class TakesClient {
 public:
  explicit TakesClient(const ConnectionOptions& options);
  TakesClient(std::shared_ptr<grpc::Channel> channel, const ConnectionOptions& options);

  // Newest first; `state` UNSPECIFIED lists every take. Fetched a page at a
  // time (`page_size` takes a call; 0: the server's default).
  absl::StatusOr<std::vector<v1::Take>> List(v1::TakeState state = v1::TAKE_STATE_UNSPECIFIED,
                                             int page_size = 0) const;
  absl::StatusOr<v1::Take> Get(const std::string& take_id) const;
  // Bytes freed on the server, and the reenactments and jobs deleted with
  // the take.
  absl::StatusOr<v1::DeleteTakeResponse> Delete(const std::string& take_id) const;
  // Streams the take's MCAP file into `out_path` (through `out_path`.partial,
  // renamed once every byte arrived in order), returns its size. DataLoss
  // when chunks arrive out of order or the size does not add up.
  absl::StatusOr<int64_t> Download(const std::string& take_id, const std::string& out_path,
                                   const ProgressCallback& progress = {}) const;

 private:
  ConnectionOptions options_;
  std::unique_ptr<v1::Takes::Stub> stub_;
};

// Ends a running CaptureClient::StreamFrames from another thread at once,
// even while the daemon sends nothing (a sensor that stopped, a paused
// stream). Cancel may come before, during or after the call; a cancelled
// stream returns OK. One StreamCancel serves one call at a time.
class StreamCancel {
 public:
  void Cancel();
  bool cancelled() const;

 private:
  friend class CaptureClient;
  // Registers the call's context; false (nothing registered) when already
  // cancelled.
  bool Attach(grpc::ClientContext* context);
  void Detach();

  mutable std::mutex mutex_;
  grpc::ClientContext* context_ = nullptr;
  bool cancelled_ = false;
};

class CaptureClient {
 public:
  explicit CaptureClient(const ConnectionOptions& options);

  absl::StatusOr<std::vector<v1::SensorInfo>> ListSensors() const;
  absl::StatusOr<std::string> StartTake(const std::string& name, const std::string& notes,
                                        double max_seconds) const;
  absl::StatusOr<v1::StopTakeResponse> StopTake() const;
  absl::StatusOr<v1::DaemonStatus> Status() const;
  // The daemon's live frame sets (CaptureControl.StreamFrames): `callback`
  // gets each set in order and returns false to stop. Returns when the
  // stream ends (OK: the daemon ended it, or the callback stopped it) or
  // fails (InvalidArgument for an unknown sensor id, Unavailable when the
  // daemon cannot be reached within timeout_s). No deadline otherwise: the
  // stream lasts as long as both sides want, or until `cancel` (optional)
  // is cancelled.
  absl::Status StreamFrames(const v1::StreamFramesRequest& request,
                            const std::function<bool(const v1::LiveFrameSet&)>& callback,
                            StreamCancel* cancel = nullptr) const;

 private:
  ConnectionOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::CaptureControl::Stub> stub_;
};

// "RECORDING" -> TAKE_STATE_RECORDING etc. (case-insensitive);
// InvalidArgument for anything else.
absl::StatusOr<v1::TakeState> ParseTakeState(const std::string& name);
// "recording", ... (proto/state_names.h).
using ::reenact::TakeStateName;

}  // namespace reenact::client
