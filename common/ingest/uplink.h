// Uplink of reenactd: the client of the server's Ingest service
// (proto/reenact/v1/ingest_service.proto) for one take.
//
// A TakeUplink runs on its own thread. Once it has the take's OpenTake it
// connects, sends OpenTake, and streams the take's FrameSets out of the disk
// spool from TakeOpened.durable_sequence + 1 on, with the SensorLost notices;
// a reader thread takes the server's Acks and releases the acknowledged sets
// from the spool. After Close() it sends CloseTake once every set up to the
// close's last_sequence is sent, and finishes when TakeClosed arrives.
//
// Any failure of the stream (server down, UNAVAILABLE, reset, a deadline)
// reconnects with exponential backoff (initial_backoff doubling to
// max_backoff, each wait drawn from [half, all] of it) and resumes from the
// durable sequence the server reports. Statuses that retrying cannot fix
// (INVALID_ARGUMENT, PERMISSION_DENIED, ALREADY_EXISTS, UNAUTHENTICATED,
// UNIMPLEMENTED) and a spool that lacks what the server needs (DATA_LOSS)
// stop the take with that error; the spool stays on disk.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/ingest/spool.h"
#include "common/rpc/channel.h"
#include "reenact/v1/ingest_service.grpc.pb.h"

namespace reenact::ingest {

struct UplinkOptions {
  // Largest gRPC message either way; matches the server (64 MiB).
  int max_message_bytes = 64 << 20;
  // TLS trust and the bearer token for the server (common/rpc/channel.h).
  rpc::ClientSecurity security{};
  // Reconnect backoff: first wait, and the cap it doubles up to, ms.
  int64_t initial_backoff_ms = 50;
  int64_t max_backoff_ms = 2000;
  // How long to wait for TakeOpened after sending OpenTake, seconds.
  double open_timeout_s = 10.0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// A channel to the Ingest service at `address` ("host:port") with the
// message size limits of `options`.
std::shared_ptr<grpc::Channel> MakeIngestChannel(const std::string& address,
                                                 const UplinkOptions& options);

// True for statuses that reconnecting cannot fix (see the header comment).
bool IsNonRetryable(absl::StatusCode code);

// Figures of one take's uplink.
struct UplinkStats {
  bool connected = false;         // A stream is open and TakeOpened arrived.
  bool done = false;              // Finished (closed, failed or aborted).
  uint64_t sent_sequence = 0;     // Highest sequence written to the stream.
  uint64_t durable_sequence = 0;  // Highest sequence the server acknowledged.
  int64_t reconnects = 0;         // Streams begun after the first.
  int64_t frame_sets_sent = 0;    // Writes of FrameSets, resends included.
  std::string last_error;         // Why the last stream ended, when it failed.
  // The server's answer to the first OpenTake that it accepted: how much of
  // the take it already held, and whether the take existed.
  bool opened_once = false;
  uint64_t first_open_durable_sequence = 0;
  bool first_open_resumed = false;
};

class TakeUplink {
 public:
  // Called on the reader thread with each Ack's durable sequence and its
  // arrival time on the host clock (WallNowNs).
  using AckCallback = std::function<void(uint64_t durable_sequence, int64_t arrival_ns)>;

  // Starts the thread; it waits for SetOpen(). `spool` must outlive the
  // uplink.
  TakeUplink(const std::shared_ptr<grpc::Channel>& channel, const UplinkOptions& options,
             Spool* spool, AckCallback on_ack = {});
  // Aborts and joins.
  ~TakeUplink();
  TakeUplink(const TakeUplink&) = delete;
  TakeUplink& operator=(const TakeUplink&) = delete;

  // The OpenTake sent on every (re)connect. Only the first call counts.
  void SetOpen(const v1::OpenTake& open);
  // New sets were appended to the spool.
  void Notify();
  // Sends a SensorLost notice (again after every reconnect).
  void SensorLost(const v1::SensorLost& lost);
  // Ends the take once every set up to close.last_sequence is sent.
  void Close(const v1::CloseTake& close);
  // Gives up: cancels the stream, leaves the spool as it is. Done() then
  // reports Aborted.
  void Abort();

  // Waits up to `timeout_s` (negative: forever) for the uplink to finish.
  // Returns false on timeout.
  bool WaitDone(double timeout_s);
  // OK once TakeClosed arrived; the error that stopped the take otherwise.
  // Unknown while still running.
  absl::Status result() const;
  std::optional<v1::TakeClosed> closed() const;
  std::string take_id() const;
  UplinkStats stats() const;

 private:
  struct Attempt {
    absl::Status status;
    bool opened = false;
  };
  void Run();
  Attempt RunAttempt();
  void ReadResponses(grpc::ClientReaderWriter<v1::IngestRequest, v1::IngestResponse>* stream);
  // Sends sets, notices and the close while the stream lives.
  absl::Status Pump(grpc::ClientReaderWriter<v1::IngestRequest, v1::IngestResponse>* stream,
                    uint64_t next);

  std::unique_ptr<v1::Ingest::Stub> stub_;
  UplinkOptions options_;
  Spool* spool_;
  AckCallback on_ack_;
  std::string take_id_;

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<v1::OpenTake> open_;
  std::vector<v1::SensorLost> lost_;
  std::optional<v1::CloseTake> close_;
  bool abort_ = false;
  bool notified_ = false;
  grpc::ClientContext* context_ = nullptr;  // Of the live attempt.
  // Per attempt, set by the reader thread.
  bool reader_done_ = false;
  std::optional<v1::TakeOpened> opened_;
  std::optional<v1::TakeClosed> take_closed_;
  std::string protocol_error_;
  UplinkStats stats_;
  absl::Status result_ = absl::UnknownError("uplink still running");
  std::thread thread_;
};

}  // namespace reenact::ingest
