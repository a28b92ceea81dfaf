#include "clients/sdk/jobs_client.h"

#include <chrono>

#include <grpcpp/client_context.h>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "clients/sdk/call_util.h"
#include "common/base/status_macros.h"
#include "proto/grpc_status.h"

namespace reenact::client {
namespace {

// Extra time a Cancel gets beyond the unary deadline: the server answers
// once the worker has stopped (its grace period is 5 s).
constexpr double kCancelGraceS = 6.0;

using internal::ForEachPage;
using internal::SetDeadline;
using internal::WithAddress;

}  // namespace

JobsClient::JobsClient(const ConnectionOptions& options)
    : JobsClient(MakeChannel(options), options) {}

JobsClient::JobsClient(std::shared_ptr<grpc::Channel> channel, const ConnectionOptions& options)
    : options_(options), stub_(v1::Jobs::NewStub(std::move(channel))) {}

absl::StatusOr<v1::Job> JobsClient::Submit(const std::string& take_id, const std::string& method,
                                           const std::map<std::string, std::string>& options,
                                           int segments, bool live) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::SubmitJobRequest request;
  request.set_take_id(take_id);
  request.set_method(method);
  request.set_segments(segments);
  request.set_live(live);
  for (const auto& [key, value] : options) (*request.mutable_options())[key] = value;
  v1::Job job;
  const grpc::Status status = stub_->Submit(&context, request, &job);
  if (!status.ok()) return WithAddress(status, options_.address);
  return job;
}

absl::StatusOr<v1::Job> JobsClient::Watch(const std::string& job_id,
                                          const JobEventCallback& on_event) const {
  grpc::ClientContext context;
  v1::WatchJobRequest request;
  request.set_job_id(job_id);
  auto reader = stub_->Watch(&context, request);
  v1::JobEvent event;
  v1::Job last;
  bool stopped = false;
  while (reader->Read(&event)) {
    last = event.job();
    if (on_event && !on_event(event)) {
      stopped = true;
      context.TryCancel();
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (stopped) return absl::CancelledError(absl::StrCat("stopped watching job ", job_id));
  if (!status.ok()) return WithAddress(status, options_.address);
  if (!JobFinished(last.state())) {
    return absl::UnavailableError(
        absl::StrCat(options_.address, ": the watch of job ", job_id, " ended before the job did"));
  }
  return last;
}

absl::StatusOr<v1::Job> JobsClient::Cancel(const std::string& job_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s + kCancelGraceS);
  v1::CancelJobRequest request;
  request.set_job_id(job_id);
  v1::Job job;
  const grpc::Status status = stub_->Cancel(&context, request, &job);
  if (!status.ok()) return WithAddress(status, options_.address);
  return job;
}

absl::StatusOr<std::vector<v1::Job>> JobsClient::List(v1::JobState state,
                                                      const std::string& take_id,
                                                      int page_size) const {
  v1::ListJobsRequest request;
  request.set_state(state);
  request.set_take_id(take_id);
  request.set_page_size(page_size);
  std::vector<v1::Job> jobs;
  RETURN_IF_ERROR(
      ForEachPage(request, [&](const v1::ListJobsRequest& page) -> absl::StatusOr<std::string> {
        grpc::ClientContext context;
        SetDeadline(context, options_.timeout_s);
        v1::ListJobsResponse response;
        const grpc::Status status = stub_->List(&context, page, &response);
        if (!status.ok()) return WithAddress(status, options_.address);
        jobs.insert(jobs.end(), response.jobs().begin(), response.jobs().end());
        return response.next_page_token();
      }));
  return jobs;
}

absl::StatusOr<v1::Job> JobsClient::Get(const std::string& job_id) const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::GetJobRequest request;
  request.set_job_id(job_id);
  v1::Job job;
  const grpc::Status status = stub_->Get(&context, request, &job);
  if (!status.ok()) return WithAddress(status, options_.address);
  return job;
}

absl::StatusOr<std::vector<v1::MethodDescription>> JobsClient::ListMethods() const {
  grpc::ClientContext context;
  SetDeadline(context, options_.timeout_s);
  v1::ListMethodsResponse response;
  const grpc::Status status = stub_->ListMethods(&context, v1::ListMethodsRequest(), &response);
  if (!status.ok()) return WithAddress(status, options_.address);
  return std::vector<v1::MethodDescription>(response.methods().begin(), response.methods().end());
}

absl::StatusOr<v1::JobState> ParseJobState(const std::string& name) {
  const std::string lower = absl::AsciiStrToLower(name);
  if (lower == "all" || lower.empty()) return v1::JOB_STATE_UNSPECIFIED;
  if (const std::optional<v1::JobState> state = JobStateFromName(lower)) return *state;
  return absl::InvalidArgumentError(absl::StrCat(
      "unknown job state \"", name, "\" (queued, running, succeeded, failed, cancelled, all)"));
}

bool JobFinished(v1::JobState state) {
  return state == v1::JOB_STATE_SUCCEEDED || state == v1::JOB_STATE_FAILED ||
         state == v1::JOB_STATE_CANCELLED;
}

}  // namespace reenact::client
