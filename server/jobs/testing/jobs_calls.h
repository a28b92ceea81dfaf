// Test-only: the Jobs calls the job tests make, as one-liners over a stub.
#pragma once

#include <map>
#include <string>

#include <gtest/gtest.h>

#include "reenact/v1/jobs_service.grpc.pb.h"

namespace reenact::server::testing {

// Submits `method` on `take_id` with `options`; a failure fails the test
// and gives an empty job.
inline v1::Job SubmitJob(v1::Jobs::Stub& jobs, const std::string& take_id,
                         const std::string& method,
                         const std::map<std::string, std::string>& options) {
  grpc::ClientContext context;
  v1::SubmitJobRequest request;
  request.set_take_id(take_id);
  request.set_method(method);
  for (const auto& [key, value] : options) (*request.mutable_options())[key] = value;
  v1::Job job;
  const grpc::Status status = jobs.Submit(&context, request, &job);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return job;
}

// The job now; an empty job when the call fails.
inline v1::Job GetJob(v1::Jobs::Stub& jobs, const std::string& job_id) {
  grpc::ClientContext context;
  v1::GetJobRequest request;
  request.set_job_id(job_id);
  v1::Job job;
  (void)jobs.Get(&context, request, &job);
  return job;
}

}  // namespace reenact::server::testing
