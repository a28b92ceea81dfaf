#include "clients/sdk/reenactments_client.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include <grpcpp/client_context.h>

#include "absl/strings/str_cat.h"
#include "clients/sdk/call_util.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_fetch.h"
#include "proto/grpc_status.h"

namespace reenact::client {
namespace {

using internal::ForEachPage;
using internal::SetDeadline;
using internal::WithAddress;

// Starts a Fetch of `reenactment_id` on `context`.
std::unique_ptr<grpc::ClientReader<v1::FetchReenactmentChunk>> StartFetch(
    v1::Reenactments::Stub& stub, grpc::ClientContext* context, const std::string& reenactment_id,
    bool skip_keyframes) {
  v1::FetchReenactmentRequest request;
  request.set_reenactment_id(reenactment_id);
  request.set_skip_keyframes(skip_keyframes);
  return stub.Fetch(context, request);
}

}  // namespace

ReenactmentsClient::ReenactmentsClient(const ConnectionOptions& options)
    : ReenactmentsClient(MakeChannel(options), options) {}

ReenactmentsClient::ReenactmentsClient(std::shared_ptr<grpc::Channel> channel,
                                       const ConnectionOptions& options)
    : options_(options), stub_(v1::Reenactments::NewStub(std::move(channel))) {}

absl::StatusOr<std::vector<v1::ReenactmentSummary>> ReenactmentsClient::List(
    const std::string& take_id, int page_size) const {
  v1::ListReenactmentsRequest request;
  request.set_take_id(take_id);
  request.set_page_size(page_size);
  std::vector<v1::ReenactmentSummary> summaries;
  RETURN_IF_ERROR(ForEachPage(
      request, [&](const v1::ListReenactmentsRequest& page) -> absl::StatusOr<std::string> {
        grpc::ClientContext context;
        SetDeadline(context, options_.timeout_s);
        v1::ListReenactmentsResponse response;
        const grpc::Status status = stub_->List(&context, page, &response);
        if (!status.ok()) return WithAddress(status, options_.address);
        summaries.insert(summaries.end(), response.reenactments().begin(),
                         response.reenactments().end());
        return response.next_page_token();
      }));
  return summaries;
}

absl::StatusOr<v1::ReenactmentSummary> ReenactmentsClient::Get(
    const std::string& reenactment_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::GetReenactmentRequest request;
  request.set_reenactment_id(reenactment_id);
  v1::ReenactmentSummary response;
  const grpc::Status status = stub_->Get(&context, request, &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return response;
}

absl::StatusOr<Reenactment> ReenactmentsClient::Fetch(const std::string& reenactment_id,
                                                      bool skip_keyframes,
                                                      const ProgressCallback& progress) const {
  int64_t total = 0;
  if (progress) {
    // The counts make the progress exact.
    absl::StatusOr<v1::ReenactmentSummary> summary = Get(reenactment_id);
    if (!summary.ok()) return summary.status();
    total = summary->part_count() + summary->info().frame_count() +
            (skip_keyframes ? 0 : summary->keyframe_count());
  }
  grpc::ClientContext context;
  auto reader = StartFetch(*stub_, &context, reenactment_id, skip_keyframes);
  ReenactmentData data;
  v1::FetchReenactmentChunk chunk;
  int stage = 0;
  absl::Status failure;
  while (reader->Read(&chunk)) {
    failure = AppendFetchChunk(chunk, &data, &stage);
    if (failure.ok() && progress) {
      Progress p;
      p.stage = "fetch";
      p.items_done =
          static_cast<int64_t>(data.parts.size() + data.frames.size() + data.keyframes.size());
      p.items_total = std::max(total, p.items_done);
      p.fraction = p.items_total > 0
                       ? static_cast<double>(p.items_done) / static_cast<double>(p.items_total)
                       : 0.0;
      if (!progress(p)) failure = absl::CancelledError("fetch cancelled");
    }
    if (!failure.ok()) {
      context.TryCancel();
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (!failure.ok()) return WithAddress(failure, options_.address);
  if (!status.ok()) return WithAddress(status, options_.address);
  absl::StatusOr<Reenactment> converted = ReenactmentFromProto(data);
  if (!converted.ok()) {
    return absl::DataLossError(
        absl::StrCat(options_.address, ": reenactment ", reenactment_id,
                     " arrived incomplete or inconsistent: ", converted.status().message()));
  }
  return converted;
}

absl::StatusOr<v1::BodyMesh> ReenactmentsClient::FetchBodyMesh(
    const std::string& reenactment_id) const {
  grpc::ClientContext context;
  auto reader = StartFetch(*stub_, &context, reenactment_id, /*skip_keyframes=*/true);
  ReenactmentData data;
  v1::FetchReenactmentChunk chunk;
  int stage = 0;
  absl::Status failure;
  // The body mesh comes right after the info, then the pieces of its
  // appearance video; anything else after the info means no body.
  bool ended = false;
  for (int read = 0; failure.ok(); ++read) {
    if (!reader->Read(&chunk)) {
      ended = true;
      break;
    }
    const auto kind = chunk.chunk_case();
    if (read > 0 && kind != v1::FetchReenactmentChunk::kBodyMesh &&
        kind != v1::FetchReenactmentChunk::kAppearanceMp4Piece) {
      break;
    }
    failure = AppendFetchChunk(chunk, &data, &stage);
  }
  if (!ended) context.TryCancel();  // Leaves the frames on the server.
  const grpc::Status status = reader->Finish();
  if (!failure.ok()) return WithAddress(failure, options_.address);
  if (!data.body.empty()) return std::move(data.body.front());
  if (!status.ok() && status.error_code() != grpc::StatusCode::CANCELLED) {
    return WithAddress(status, options_.address);
  }
  return absl::FailedPreconditionError(absl::StrCat(options_.address, ": reenactment ",
                                                    reenactment_id, " (method \"",
                                                    data.info.method(), "\") has no body mesh"));
}

absl::StatusOr<v1::FollowEnd> ReenactmentsClient::Follow(
    const std::string& job_id, const FollowEventCallback& on_event) const {
  grpc::ClientContext context;
  v1::FollowRequest request;
  request.set_job_id(job_id);
  auto reader = stub_->Follow(&context, request);
  v1::FollowEvent event;
  std::optional<v1::FollowEnd> end;
  bool stopped = false;
  while (reader->Read(&event)) {
    if (event.has_end()) end = event.end();
    if (on_event && !on_event(event)) {
      stopped = true;
      context.TryCancel();
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (stopped) return absl::CancelledError(absl::StrCat("stopped following job ", job_id));
  if (!status.ok()) return WithAddress(status, options_.address);
  if (!end.has_value()) {
    return absl::DataLossError(
        absl::StrCat(options_.address, ": the follow of job ", job_id, " ended without its end"));
  }
  return *end;
}

absl::Status ReenactmentsClient::Delete(const std::string& reenactment_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::DeleteReenactmentRequest request;
  request.set_reenactment_id(reenactment_id);
  v1::DeleteReenactmentResponse response;
  const grpc::Status status = stub_->Delete(&context, request, &response);
  return WithAddress(status, options_.address);
}

}  // namespace reenact::client
