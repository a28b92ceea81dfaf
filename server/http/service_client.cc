#include "server/http/service_client.h"

#include <chrono>
#include <optional>
#include <utility>

#include <grpcpp/client_context.h>

#include "absl/strings/str_cat.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_fetch.h"
#include "proto/grpc_status.h"

namespace reenact::server {

ServiceClient::ServiceClient(const std::shared_ptr<grpc::Channel>& channel, double timeout_s)
    : timeout_s_(timeout_s),
      takes_(v1::Takes::NewStub(channel)),
      reenactments_(v1::Reenactments::NewStub(channel)),
      jobs_(v1::Jobs::NewStub(channel)) {}

void ServiceClient::SetDeadline(grpc::ClientContext& context) const {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::milliseconds(static_cast<int64_t>(timeout_s_ * 1000)));
}

absl::StatusOr<v1::Take> ServiceClient::GetTake(const std::string& take_id) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::GetTakeRequest request;
  request.set_take_id(take_id);
  v1::Take take;
  if (const grpc::Status status = takes_->Get(&context, request, &take); !status.ok()) {
    return FromGrpcStatus(status);
  }
  return take;
}

absl::StatusOr<v1::ListReenactmentsResponse> ServiceClient::ListReenactments(
    const v1::ListReenactmentsRequest& request) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::ListReenactmentsResponse listed;
  if (const grpc::Status status = reenactments_->List(&context, request, &listed); !status.ok()) {
    return FromGrpcStatus(status);
  }
  return listed;
}

absl::StatusOr<v1::ReenactmentSummary> ServiceClient::GetReenactment(
    const std::string& reenactment_id) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::GetReenactmentRequest request;
  request.set_reenactment_id(reenactment_id);
  v1::ReenactmentSummary summary;
  if (const grpc::Status status = reenactments_->Get(&context, request, &summary); !status.ok()) {
    return FromGrpcStatus(status);
  }
  return summary;
}

absl::StatusOr<Reenactment> ServiceClient::FetchReenactment(const std::string& reenactment_id,
                                                            bool skip_keyframes) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::FetchReenactmentRequest request;
  request.set_reenactment_id(reenactment_id);
  request.set_skip_keyframes(skip_keyframes);
  auto reader = reenactments_->Fetch(&context, request);
  ReenactmentData data;
  v1::FetchReenactmentChunk chunk;
  int stage = 0;
  absl::Status failure;
  while (reader->Read(&chunk)) {
    failure = AppendFetchChunk(chunk, &data, &stage);
    if (!failure.ok()) {
      context.TryCancel();
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (!failure.ok()) return failure;
  if (!status.ok()) return FromGrpcStatus(status);
  absl::StatusOr<Reenactment> converted = ReenactmentFromProto(data);
  if (!converted.ok()) {
    return absl::DataLossError(
        absl::StrCat("reenactment ", reenactment_id,
                     " arrived incomplete or inconsistent: ", converted.status().message()));
  }
  return converted;
}

absl::StatusOr<v1::ListJobsResponse> ServiceClient::ListJobs(
    const v1::ListJobsRequest& request) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::ListJobsResponse listed;
  if (const grpc::Status status = jobs_->List(&context, request, &listed); !status.ok()) {
    return FromGrpcStatus(status);
  }
  return listed;
}

absl::StatusOr<v1::Job> ServiceClient::GetJob(const std::string& job_id) const {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::GetJobRequest request;
  request.set_job_id(job_id);
  v1::Job job;
  if (const grpc::Status status = jobs_->Get(&context, request, &job); !status.ok()) {
    return FromGrpcStatus(status);
  }
  return job;
}

absl::StatusOr<v1::FollowEnd> ServiceClient::Follow(
    const std::string& job_id,
    const std::function<bool(const v1::FollowEvent& event)>& on_event) const {
  grpc::ClientContext context;
  v1::FollowRequest request;
  request.set_job_id(job_id);
  auto reader = reenactments_->Follow(&context, request);
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
  if (!status.ok()) return FromGrpcStatus(status);
  if (!end.has_value()) {
    return absl::DataLossError(
        absl::StrCat("the follow of job ", job_id, " ended without its end"));
  }
  return *end;
}

}  // namespace reenact::server
