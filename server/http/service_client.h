// The HTTP front's one client of the server's own services: every call the
// JSON API (web_api.h) and the WebSocket follow make, over the in-process
// channel of one request's token (so that the services' own roles and
// limits apply), each bounded by `timeout_s` except Follow, which lasts as
// long as the take. Errors are the services' statuses. The server's HTTP
// front links no client library (docs/architecture.md, "Layering").
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <grpcpp/channel.h>

#include "absl/status/statusor.h"
#include "common/model/reenactment.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"

namespace reenact::server {

class ServiceClient {
 public:
  ServiceClient(const std::shared_ptr<grpc::Channel>& channel, double timeout_s);

  absl::StatusOr<v1::Take> GetTake(const std::string& take_id) const;
  absl::StatusOr<v1::ListReenactmentsResponse> ListReenactments(
      const v1::ListReenactmentsRequest& request) const;
  absl::StatusOr<v1::ReenactmentSummary> GetReenactment(const std::string& reenactment_id) const;
  // The whole reenactment (Reenactments.Fetch), put together and converted
  // to plain values; DataLoss for a stream out of order or inconsistent.
  absl::StatusOr<Reenactment> FetchReenactment(const std::string& reenactment_id,
                                               bool skip_keyframes) const;
  absl::StatusOr<v1::ListJobsResponse> ListJobs(const v1::ListJobsRequest& request) const;
  absl::StatusOr<v1::Job> GetJob(const std::string& job_id) const;
  // Reenactments.Follow: `on_event` gets each event until it returns false
  // (then Cancelled) or the stream ends; returns its FollowEnd (DataLoss
  // when the stream ended without one).
  absl::StatusOr<v1::FollowEnd> Follow(
      const std::string& job_id,
      const std::function<bool(const v1::FollowEvent& event)>& on_event) const;

 private:
  void SetDeadline(grpc::ClientContext& context) const;

  double timeout_s_;
  std::unique_ptr<v1::Takes::Stub> takes_;
  std::unique_ptr<v1::Reenactments::Stub> reenactments_;
  std::unique_ptr<v1::Jobs::Stub> jobs_;
};

}  // namespace reenact::server
