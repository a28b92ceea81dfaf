// Client side of the server's Jobs service (proto/reenact/v1/jobs_service.proto):
// what the `reenact jobs` commands, the viewer and scripts use to submit
// reconstruction jobs, follow their progress, cancel and list them. Unary
// calls have the connection's deadline; Watch has none (a job may run for
// hours) and ends with the job. Errors carry the address they were sent to.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/statusor.h"
#include "clients/sdk/takes_client.h"
#include "proto/state_names.h"
#include "reenact/v1/jobs_service.grpc.pb.h"

namespace reenact::client {

// Gets each event of a watched job; returning false stops watching (Watch
// then returns Cancelled).
using JobEventCallback = std::function<bool(const v1::JobEvent& event)>;

class JobsClient {
 public:
  explicit JobsClient(const ConnectionOptions& options);
  JobsClient(std::shared_ptr<grpc::Channel> channel, const ConnectionOptions& options);

  // Queues a job of `method` on the stored take, split across `segments`
  // workers when > 1; `live`: follow the take while it is recorded
  // (SubmitJobRequest.live). InvalidArgument (unknown method, bad options, a
  // method that cannot be segmented or follow a take), NotFound (unknown
  // take), FailedPrecondition (a take still recording, for a job that is
  // not live), as the server answers.
  absl::StatusOr<v1::Job> Submit(const std::string& take_id, const std::string& method,
                                 const std::map<std::string, std::string>& options = {},
                                 int segments = 0, bool live = false) const;
  // Calls `on_event` with the job now and on every change until it ends;
  // returns the last job seen (finished unless the stream broke).
  // Unavailable when the server went away or shut down before the end.
  absl::StatusOr<v1::Job> Watch(const std::string& job_id, const JobEventCallback& on_event) const;
  // Cancels a queued or running job and returns it once it has stopped
  // (CANCELLED; as it is when it had already ended). The call waits for a
  // running worker to stop: up to the server's grace period (5 s).
  absl::StatusOr<v1::Job> Cancel(const std::string& job_id) const;
  // Newest first; UNSPECIFIED / empty do not filter. Fetched a page at a
  // time (`page_size` jobs a call; 0: the server's default).
  absl::StatusOr<std::vector<v1::Job>> List(v1::JobState state = v1::JOB_STATE_UNSPECIFIED,
                                            const std::string& take_id = "",
                                            int page_size = 0) const;
  absl::StatusOr<v1::Job> Get(const std::string& job_id) const;
  // The reconstruction methods the server runs, with their options.
  absl::StatusOr<std::vector<v1::MethodDescription>> ListMethods() const;

 private:
  ConnectionOptions options_;
  std::unique_ptr<v1::Jobs::Stub> stub_;
};

// "queued", "running", "succeeded", "failed", "cancelled" (any case; "all"
// is UNSPECIFIED) -> the state; InvalidArgument for anything else.
absl::StatusOr<v1::JobState> ParseJobState(const std::string& name);
// "queued", ... (proto/state_names.h).
using ::reenact::JobStateName;
// True for SUCCEEDED, FAILED and CANCELLED.
bool JobFinished(v1::JobState state);

}  // namespace reenact::client
