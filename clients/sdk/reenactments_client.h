// Client side of the server's Reenactments service: what the `reenact` tool
// and the viewer use to list, inspect, fetch and delete the reenactments that
// jobs made. Unary calls have a deadline (ConnectionOptions.timeout_s); Fetch
// has none, it streams for as long as the reenactment takes. Errors carry the
// address they were sent to.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/sdk/takes_client.h"
#include "common/base/progress.h"
#include "common/io/reenactment_file.h"
#include "common/model/reenactment.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"

namespace reenact::client {

// Gets each event of a followed job; returning false stops following
// (Follow then returns Cancelled).
using FollowEventCallback = std::function<bool(const v1::FollowEvent& event)>;

class ReenactmentsClient {
 public:
  explicit ReenactmentsClient(const ConnectionOptions& options);
  ReenactmentsClient(std::shared_ptr<grpc::Channel> channel, const ConnectionOptions& options);

  // Newest first; only those of `take_id` when it is not empty. Fetched a
  // page at a time (`page_size` a call; 0: the server's default).
  absl::StatusOr<std::vector<v1::ReenactmentSummary>> List(const std::string& take_id = "",
                                                           int page_size = 0) const;
  // NotFound for an unknown id.
  absl::StatusOr<v1::ReenactmentSummary> Get(const std::string& reenactment_id) const;
  // The whole reenactment, reassembled from the stream, checked and
  // converted (ReenactmentFromProto); `skip_keyframes` leaves the texture keyframes on
  // the server (most of the bytes). `progress` sees the parts, frames and
  // keyframes arrive (items: messages' parts + frames + keyframes); returning
  // false cancels (Cancelled). DataLoss when the stream is out of order or
  // what arrived is not a valid reenactment.
  absl::StatusOr<Reenactment> Fetch(const std::string& reenactment_id, bool skip_keyframes = false,
                                    const ProgressCallback& progress = {}) const;
  // The BodyMesh of a body-model reenactment: the start of Fetch's stream
  // (info, the body mesh and its appearance video), cancelled once those
  // have arrived, so the frames stay on the server. NotFound for an unknown id;
  // FailedPrecondition when the reenactment has no body mesh (rigid parts);
  // DataLoss when the stream is out of order.
  absl::StatusOr<v1::BodyMesh> FetchBodyMesh(const std::string& reenactment_id) const;
  // NotFound for an unknown id.
  absl::Status Delete(const std::string& reenactment_id) const;
  // The live preview of a job that follows its take (a live job, Job.live):
  // calls `on_event` with each event as it arrives (the body
  // mesh first, one frame per fitted FrameSet, the FollowEnd last) and
  // returns the FollowEnd. No deadline: it lasts as long as the take. A job
  // that follows nothing gets only a FollowEnd (NOT_FOLLOWING). NotFound
  // for an unknown job; Unavailable when the server went away or shut down;
  // Cancelled when `on_event` returned false; DataLoss when the stream
  // ended without a FollowEnd.
  absl::StatusOr<v1::FollowEnd> Follow(const std::string& job_id,
                                       const FollowEventCallback& on_event) const;

 private:
  ConnectionOptions options_;
  std::unique_ptr<v1::Reenactments::Stub> stub_;
};

}  // namespace reenact::client
