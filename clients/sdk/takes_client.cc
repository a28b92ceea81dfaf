#include "clients/sdk/takes_client.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <grpcpp/client_context.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "clients/sdk/call_util.h"
#include "common/base/status_macros.h"
#include "proto/grpc_status.h"

namespace reenact::client {
namespace {

using internal::ForEachPage;
using internal::SetDeadline;
using internal::WithAddress;

}  // namespace

std::shared_ptr<grpc::Channel> MakeChannel(const ConnectionOptions& options) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  return rpc::MakeClientChannel(options.address, args, options.security);
}

TakesClient::TakesClient(const ConnectionOptions& options)
    : TakesClient(MakeChannel(options), options) {}

TakesClient::TakesClient(std::shared_ptr<grpc::Channel> channel, const ConnectionOptions& options)
    : options_(options), stub_(v1::Takes::NewStub(std::move(channel))) {}

absl::StatusOr<std::vector<v1::Take>> TakesClient::List(v1::TakeState state, int page_size) const {
  v1::ListTakesRequest request;
  request.set_state(state);
  request.set_page_size(page_size);
  std::vector<v1::Take> takes;
  RETURN_IF_ERROR(
      ForEachPage(request, [&](const v1::ListTakesRequest& page) -> absl::StatusOr<std::string> {
        grpc::ClientContext context;
        SetDeadline(context, options_.timeout_s);
        v1::ListTakesResponse response;
        const grpc::Status status = stub_->List(&context, page, &response);
        if (!status.ok()) return WithAddress(status, options_.address);
        takes.insert(takes.end(), response.takes().begin(), response.takes().end());
        return response.next_page_token();
      }));
  return takes;
}

absl::StatusOr<v1::Take> TakesClient::Get(const std::string& take_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::GetTakeRequest request;
  request.set_take_id(take_id);
  v1::Take take;
  const grpc::Status status = stub_->Get(&context, request, &take);
  if (!status.ok()) return WithAddress(status, options_.address);
  return take;
}

absl::StatusOr<v1::DeleteTakeResponse> TakesClient::Delete(const std::string& take_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::DeleteTakeRequest request;
  request.set_take_id(take_id);
  v1::DeleteTakeResponse response;
  const grpc::Status status = stub_->Delete(&context, request, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return response;
}

absl::StatusOr<int64_t> TakesClient::Download(const std::string& take_id,
                                              const std::string& out_path,
                                              const ProgressCallback& progress) const {
  const std::string partial = out_path + ".partial";
  std::ofstream out(partial, std::ios::binary | std::ios::trunc);
  if (!out) return absl::PermissionDeniedError(absl::StrCat(partial, ": cannot write"));
  grpc::ClientContext context;
  v1::DownloadTakeRequest request;
  request.set_take_id(take_id);
  auto reader = stub_->Download(&context, request);
  v1::TakeFileChunk chunk;
  int64_t received = 0, total = -1;
  absl::Status failure;
  while (reader->Read(&chunk)) {
    if (chunk.offset() != received || (total >= 0 && chunk.total_bytes() != total) ||
        chunk.total_bytes() < received + static_cast<int64_t>(chunk.data().size())) {
      failure = absl::DataLossError(
          absl::StrCat(options_.address, ": download of ", take_id, " sent bytes at offset ",
                       chunk.offset(), " of ", chunk.total_bytes(), " after ", received, " bytes"));
      context.TryCancel();
      break;
    }
    total = chunk.total_bytes();
    out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
    received += static_cast<int64_t>(chunk.data().size());
    if (progress) {
      Progress p;
      p.stage = "download";
      p.items_done = received;
      p.items_total = total;
      p.fraction = total > 0 ? static_cast<double>(received) / static_cast<double>(total) : 1.0;
      if (!progress(p)) {
        failure = absl::CancelledError("download cancelled");
        context.TryCancel();
        break;
      }
    }
  }
  const grpc::Status status = reader->Finish();
  out.close();
  auto discard = [&](absl::Status s) {
    std::error_code ec;
    std::filesystem::remove(partial, ec);
    return s;
  };
  if (!failure.ok()) return discard(failure);
  if (!status.ok()) return discard(WithAddress(status, options_.address));
  if (!out) return discard(absl::DataLossError(absl::StrCat(partial, ": write failed")));
  if (total < 0) total = 0;
  if (received != total) {
    return discard(
        absl::DataLossError(absl::StrCat(options_.address, ": download of ", take_id,
                                         " ended after ", received, " of ", total, " bytes")));
  }
  std::error_code ec;
  std::filesystem::rename(partial, out_path, ec);
  if (ec) return discard(absl::PermissionDeniedError(absl::StrCat(out_path, ": ", ec.message())));
  return received;
}

CaptureClient::CaptureClient(const ConnectionOptions& options)
    : options_(options),
      channel_(MakeChannel(options)),
      stub_(v1::CaptureControl::NewStub(channel_)) {}

absl::StatusOr<std::vector<v1::SensorInfo>> CaptureClient::ListSensors() const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::ListSensorsResponse response;
  const grpc::Status status = stub_->ListSensors(&context, {}, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return std::vector<v1::SensorInfo>(response.sensors().begin(), response.sensors().end());
}

absl::StatusOr<std::string> CaptureClient::StartTake(const std::string& name,
                                                     const std::string& notes,
                                                     double max_seconds) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::StartTakeRequest request;
  request.set_name(name);
  request.set_notes(notes);
  request.set_max_seconds(max_seconds);
  v1::StartTakeResponse response;
  const grpc::Status status = stub_->StartTake(&context, request, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return response.take_id();
}

absl::StatusOr<v1::StopTakeResponse> CaptureClient::StopTake() const {
  grpc::ClientContext context;
  // Stopping waits until the take is durable on the server or spooled.
  SetDeadline(context, options_.timeout_s * 6);
  v1::StopTakeResponse response;
  const grpc::Status status = stub_->StopTake(&context, {}, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return response;
}

absl::StatusOr<v1::DaemonStatus> CaptureClient::Status() const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::DaemonStatus response;
  const grpc::Status status = stub_->Status(&context, {}, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return response;
}

void StreamCancel::Cancel() {
  std::lock_guard<std::mutex> lock(mutex_);
  cancelled_ = true;
  if (context_ != nullptr) context_->TryCancel();
}

bool StreamCancel::cancelled() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return cancelled_;
}

bool StreamCancel::Attach(grpc::ClientContext* context) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (cancelled_) return false;
  context_ = context;
  return true;
}

void StreamCancel::Detach() {
  std::lock_guard<std::mutex> lock(mutex_);
  context_ = nullptr;
}

absl::Status CaptureClient::StreamFrames(
    const v1::StreamFramesRequest& request,
    const std::function<bool(const v1::LiveFrameSet&)>& callback, StreamCancel* cancel) const {
  const auto connect_deadline =
      std::chrono::system_clock::now() +
      std::chrono::microseconds(static_cast<int64_t>(options_.timeout_s * 1e6));
  if (!channel_->WaitForConnected(connect_deadline)) {
    return WithAddress(absl::UnavailableError("cannot reach the capture daemon"), options_.address);
  }
  grpc::ClientContext context;
  if (cancel != nullptr && !cancel->Attach(&context)) return absl::OkStatus();
  std::unique_ptr<grpc::ClientReader<v1::LiveFrameSet>> reader =
      stub_->StreamFrames(&context, request);
  v1::LiveFrameSet set;
  bool stopped = false;
  while (reader->Read(&set)) {
    if (!callback(set)) {
      stopped = true;
      context.TryCancel();
      break;
    }
  }
  while (stopped && reader->Read(&set)) {
  }
  const grpc::Status status = reader->Finish();
  if (cancel != nullptr) {
    cancel->Detach();
    if (cancel->cancelled()) stopped = true;
  }
  if (stopped) return absl::OkStatus();
  return WithAddress(status, options_.address);
}

absl::StatusOr<v1::TakeState> ParseTakeState(const std::string& name) {
  const std::string lower = absl::AsciiStrToLower(name);
  if (lower == "all" || lower.empty()) return v1::TAKE_STATE_UNSPECIFIED;
  if (const std::optional<v1::TakeState> state = TakeStateFromName(lower)) return *state;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown take state '", name, "' (recording, complete, interrupted, all)"));
}

}  // namespace reenact::client
