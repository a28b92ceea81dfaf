// The Jobs service (proto/reenact/v1/jobs_service.proto): reconstruction jobs
// run by the server's JobScheduler (server/jobs/job_scheduler.h). One handler
// per RPC, reaching the scheduler through the context. Beyond the proto:
//  - Malformed take or job ids are INVALID_ARGUMENT, unknown ones NOT_FOUND.
//  - Cancel of a RUNNING job answers at once with the job CANCELLED: its
//    lease ends, and its worker hears so at its next heartbeat and stops
//    the job (SIGTERM, SIGKILL after the grace period); a job that ended
//    meanwhile is answered as it ended.
//  - Watch coalesces: a slow reader gets the latest job with every log line
//    since its previous event. At server shutdown a watch of an unfinished
//    job ends with UNAVAILABLE (the job runs again after the restart).
#pragma once

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "common/methods/method_spec.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// The unary handlers that answer at once.
// `submitter`: the caller's token name (Job.submitted_by).
absl::Status SubmitJob(ServerContext& context, const v1::SubmitJobRequest& request,
                       const std::string& submitter, v1::Job* response);
absl::Status ListJobs(ServerContext& context, const v1::ListJobsRequest& request,
                      v1::ListJobsResponse* response);
absl::Status GetJob(ServerContext& context, const v1::GetJobRequest& request, v1::Job* response);
// The scheduler's methods as the wire describes them.
v1::ListMethodsResponse ListMethods(const std::vector<methods::MethodSpec>& specs);

class JobsService final : public v1::Jobs::CallbackService {
 public:
  explicit JobsService(ServerContext& context) : context_(context) {}

  grpc::ServerUnaryReactor* Submit(grpc::CallbackServerContext* rpc,
                                   const v1::SubmitJobRequest* request, v1::Job* response) override;
  grpc::ServerWriteReactor<v1::JobEvent>* Watch(grpc::CallbackServerContext* rpc,
                                                const v1::WatchJobRequest* request) override;
  grpc::ServerUnaryReactor* Cancel(grpc::CallbackServerContext* rpc,
                                   const v1::CancelJobRequest* request, v1::Job* response) override;
  grpc::ServerUnaryReactor* List(grpc::CallbackServerContext* rpc,
                                 const v1::ListJobsRequest* request,
                                 v1::ListJobsResponse* response) override;
  grpc::ServerUnaryReactor* ListMethods(grpc::CallbackServerContext* rpc,
                                        const v1::ListMethodsRequest* request,
                                        v1::ListMethodsResponse* response) override;
  grpc::ServerUnaryReactor* Get(grpc::CallbackServerContext* rpc, const v1::GetJobRequest* request,
                                v1::Job* response) override;

 private:
  ServerContext& context_;
};

}  // namespace reenact::server
