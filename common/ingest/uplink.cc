#include "common/ingest/uplink.h"

#include <algorithm>
#include <chrono>
#include <random>
#include <utility>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "proto/grpc_status.h"

namespace reenact::ingest {

using IngestStream = grpc::ClientReaderWriter<v1::IngestRequest, v1::IngestResponse>;

absl::Status UplinkOptions::Validate() const {
  if (max_message_bytes < (1 << 20)) {
    return absl::InvalidArgumentError("UplinkOptions.max_message_bytes below 1 MiB");
  }
  if (initial_backoff_ms < 1 || max_backoff_ms < initial_backoff_ms) {
    return absl::InvalidArgumentError(
        "UplinkOptions: need 1 <= initial_backoff_ms <= max_backoff_ms");
  }
  if (!(open_timeout_s > 0.0))
    return absl::InvalidArgumentError("UplinkOptions.open_timeout_s <= 0");
  return absl::OkStatus();
}

std::shared_ptr<grpc::Channel> MakeIngestChannel(const std::string& address,
                                                 const UplinkOptions& options) {
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(options.max_message_bytes);
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  // Notice a dead server within seconds even while idle.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 10'000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 5'000);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 0);
  // Reconnect pacing is ours; keep the channel's own short.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, static_cast<int>(options.initial_backoff_ms));
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, static_cast<int>(options.max_backoff_ms));
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, static_cast<int>(options.initial_backoff_ms));
  return rpc::MakeClientChannel(address, args, options.security);
}

bool IsNonRetryable(absl::StatusCode code) {
  switch (code) {
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kPermissionDenied:
    case absl::StatusCode::kAlreadyExists:
    case absl::StatusCode::kUnauthenticated:
    case absl::StatusCode::kUnimplemented:
    case absl::StatusCode::kDataLoss:
      return true;
    default:
      return false;
  }
}

TakeUplink::TakeUplink(const std::shared_ptr<grpc::Channel>& channel, const UplinkOptions& options,
                       Spool* spool, AckCallback on_ack)
    : stub_(v1::Ingest::NewStub(channel)),
      options_(options),
      spool_(spool),
      on_ack_(std::move(on_ack)) {
  thread_ = std::thread([this] { Run(); });
}

TakeUplink::~TakeUplink() {
  Abort();
  if (thread_.joinable()) thread_.join();
}

void TakeUplink::SetOpen(const v1::OpenTake& open) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (open_) return;
  open_ = open;
  take_id_ = open.take_id();
  cv_.notify_all();
}

void TakeUplink::Notify() {
  std::lock_guard<std::mutex> lock(mutex_);
  notified_ = true;
  cv_.notify_all();
}

void TakeUplink::SensorLost(const v1::SensorLost& lost) {
  std::lock_guard<std::mutex> lock(mutex_);
  lost_.push_back(lost);
  cv_.notify_all();
}

void TakeUplink::Close(const v1::CloseTake& close) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!close_) close_ = close;
  cv_.notify_all();
}

void TakeUplink::Abort() {
  std::lock_guard<std::mutex> lock(mutex_);
  abort_ = true;
  if (context_ != nullptr) context_->TryCancel();
  cv_.notify_all();
}

bool TakeUplink::WaitDone(double timeout_s) {
  std::unique_lock<std::mutex> lock(mutex_);
  auto done = [this] { return stats_.done; };
  if (timeout_s < 0) {
    cv_.wait(lock, done);
    return true;
  }
  return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), done);
}

absl::Status TakeUplink::result() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return result_;
}

std::optional<v1::TakeClosed> TakeUplink::closed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return take_closed_;
}

std::string TakeUplink::take_id() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return take_id_;
}

UplinkStats TakeUplink::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

void TakeUplink::Run() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return abort_ || open_.has_value(); });
  }
  std::mt19937_64 rng(std::random_device{}());
  int64_t backoff_ms = options_.initial_backoff_ms;
  absl::Status final_status;
  // One uplink_unreachable line per outage, not one per retry.
  bool down_reported = false;
  while (true) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (abort_) {
        final_status = absl::AbortedError(
            absl::StrCat("uplink of take ", take_id_, " stopped before the take was closed; ",
                         spool_->frame_sets(), " frame sets remain in ", spool_->dir()));
        break;
      }
    }
    const Attempt attempt = RunAttempt();
    if (attempt.opened) down_reported = false;
    if (attempt.status.ok()) {
      final_status = absl::OkStatus();
      break;
    }
    if (IsNonRetryable(attempt.status.code())) {
      final_status = attempt.status;
      log::Error("uplink_failed",
                 {{"take_id", take_id()},
                  {"status", absl::StatusCodeToString(attempt.status.code())},
                  {"error", attempt.status.message()}},
                 "the server refused the take; retrying cannot help, the spool stays on disk");
      break;
    }
    if (attempt.opened) {
      log::Warn("uplink_lost",
                {{"take_id", take_id()},
                 {"status", absl::StatusCodeToString(attempt.status.code())},
                 {"error", attempt.status.message()}},
                "the stream to the server ended; reconnecting");
    } else if (!down_reported && !absl::IsAborted(attempt.status)) {
      down_reported = true;
      log::Warn("uplink_unreachable",
                {{"take_id", take_id()},
                 {"status", absl::StatusCodeToString(attempt.status.code())},
                 {"error", attempt.status.message()}},
                "the server cannot be reached; retrying with backoff");
    }
    if (attempt.opened) backoff_ms = options_.initial_backoff_ms;
    std::uniform_int_distribution<int64_t> jitter(backoff_ms / 2, backoff_ms);
    const auto wait = std::chrono::milliseconds(jitter(rng));
    backoff_ms = std::min(2 * backoff_ms, options_.max_backoff_ms);
    std::unique_lock<std::mutex> lock(mutex_);
    stats_.last_error = std::string(attempt.status.message());
    cv_.wait_for(lock, wait, [this] { return abort_; });
    if (!abort_) ++stats_.reconnects;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  result_ = final_status;
  if (!final_status.ok()) stats_.last_error = std::string(final_status.message());
  stats_.connected = false;
  stats_.done = true;
  cv_.notify_all();
}

TakeUplink::Attempt TakeUplink::RunAttempt() {
  Attempt attempt;
  grpc::ClientContext context;
  v1::OpenTake open;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (abort_) {
      attempt.status = absl::AbortedError("uplink stopped");
      return attempt;
    }
    context_ = &context;
    reader_done_ = false;
    opened_.reset();
    protocol_error_.clear();
    open = *open_;
  }
  std::unique_ptr<IngestStream> stream = stub_->Ingest(&context);
  std::thread reader([this, &stream] { ReadResponses(stream.get()); });

  v1::IngestRequest request;
  *request.mutable_open() = open;
  absl::Status pumped = absl::OkStatus();
  if (stream->Write(request)) {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool answered =
        cv_.wait_for(lock, std::chrono::duration<double>(options_.open_timeout_s),
                     [this] { return abort_ || reader_done_ || opened_.has_value(); });
    if (!answered) pumped = absl::DeadlineExceededError("no TakeOpened from the server in time");
    if (opened_ && !abort_ && !reader_done_) {
      attempt.opened = true;
      stats_.connected = true;
      const uint64_t durable = opened_->durable_sequence();
      const int64_t reconnects = stats_.reconnects;
      const bool resumed = opened_->resumed();
      if (!stats_.opened_once) {
        stats_.opened_once = true;
        stats_.first_open_durable_sequence = durable;
        stats_.first_open_resumed = resumed;
      }
      lock.unlock();
      log::Info("uplink_connected",
                {{"take_id", take_id_},
                 {"durable_sequence", durable},
                 {"resumed", resumed},
                 {"reconnects", reconnects}},
                "streaming the take to the server");
      pumped = Pump(stream.get(), durable + 1);
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!reader_done_) context.TryCancel();
  }
  reader.join();
  const absl::Status finished = FromGrpcStatus(stream->Finish());
  std::lock_guard<std::mutex> lock(mutex_);
  context_ = nullptr;
  stats_.connected = false;
  if (take_closed_) {
    attempt.status = absl::OkStatus();
  } else if (!protocol_error_.empty()) {
    attempt.status = absl::InvalidArgumentError(protocol_error_);
  } else if (!pumped.ok()) {
    attempt.status = pumped;
  } else if (!finished.ok()) {
    attempt.status = finished;
  } else {
    attempt.status = absl::UnavailableError("the server ended the stream before TakeClosed");
  }
  if (abort_ && !take_closed_) attempt.status = absl::AbortedError("uplink stopped");
  return attempt;
}

void TakeUplink::ReadResponses(IngestStream* stream) {
  v1::IngestResponse response;
  while (stream->Read(&response)) {
    const int64_t arrival_ns = WallNowNs();
    uint64_t durable = 0;
    bool ack = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      switch (response.kind_case()) {
        case v1::IngestResponse::kOpened:
          if (response.opened().take_id() != take_id_) {
            protocol_error_ = absl::StrCat("server opened take \"", response.opened().take_id(),
                                           "\", not \"", take_id_, "\"");
            break;
          }
          opened_ = response.opened();
          durable = response.opened().durable_sequence();
          ack = true;
          break;
        case v1::IngestResponse::kAck:
          durable = response.ack().durable_sequence();
          ack = true;
          break;
        case v1::IngestResponse::kClosed:
          take_closed_ = response.closed();
          durable = response.closed().durable_sequence();
          ack = true;
          break;
        default:
          break;
      }
      if (ack) stats_.durable_sequence = std::max(stats_.durable_sequence, durable);
      cv_.notify_all();
    }
    if (ack && durable > 0) {
      // The spool's own bound check makes a wild durable_sequence harmless:
      // it only releases what it holds.
      (void)spool_->Ack(durable);
      if (on_ack_) on_ack_(durable, arrival_ns);
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  reader_done_ = true;
  cv_.notify_all();
}

absl::Status TakeUplink::Pump(IngestStream* stream, uint64_t next) {
  // Resume point: the server must hold everything the spool already released.
  const uint64_t acked = spool_->acked_sequence();
  if (next <= acked) {
    return absl::DataLossError(absl::StrCat(
        "the server has take ", take_id(), " only up to frame set ", next - 1,
        " but had acknowledged it up to ", acked, " (released from the spool); cannot resend"));
  }
  size_t lost_sent = 0;
  bool close_sent = false;
  while (true) {
    std::vector<v1::SensorLost> lost;
    std::optional<v1::CloseTake> close;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] {
        return abort_ || reader_done_ || notified_ || lost_.size() > lost_sent ||
               (close_ && !close_sent) || next <= spool_->last_sequence();
      });
      notified_ = false;
      if (abort_ || reader_done_) return absl::OkStatus();
      lost.assign(lost_.begin() + static_cast<std::ptrdiff_t>(lost_sent), lost_.end());
      lost_sent = lost_.size();
      if (!close_sent) close = close_;
    }
    for (const v1::SensorLost& notice : lost) {
      v1::IngestRequest request;
      *request.mutable_sensor_lost() = notice;
      if (!stream->Write(request)) return absl::OkStatus();
    }
    while (next <= spool_->last_sequence()) {
      absl::StatusOr<v1::FrameSet> set = spool_->Take(next);
      if (!set.ok()) {
        if (absl::IsNotFound(set.status()) && next <= spool_->acked_sequence()) {
          ++next;  // Acknowledged meanwhile (a late Ack of an earlier stream).
          continue;
        }
        return absl::DataLossError(absl::StrCat("take ", take_id(), ": ", set.status().message()));
      }
      v1::IngestRequest request;
      request.mutable_frame_set()->Swap(&*set);
      if (!stream->Write(request)) return absl::OkStatus();
      std::lock_guard<std::mutex> lock(mutex_);
      stats_.sent_sequence = std::max(stats_.sent_sequence, next);
      ++stats_.frame_sets_sent;
      ++next;
    }
    // A take resumed after a restart may not know its last sequence; the
    // server's durable sequence bounds it from below.
    if (close && close->last_sequence() < next - 1) close->set_last_sequence(next - 1);
    if (close && next > close->last_sequence()) {
      v1::IngestRequest request;
      *request.mutable_close() = *close;
      if (!stream->Write(request)) return absl::OkStatus();
      stream->WritesDone();
      close_sent = true;
      // The server answers TakeClosed and ends the stream; the reader notices.
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return abort_ || reader_done_ || take_closed_.has_value(); });
      if (take_closed_) {
        cv_.wait_for(lock, std::chrono::seconds(2), [this] { return abort_ || reader_done_; });
      }
      return absl::OkStatus();
    }
  }
}

}  // namespace reenact::ingest
