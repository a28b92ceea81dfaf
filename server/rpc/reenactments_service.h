// The Reenactments service (proto/reenact/v1/reenactments_service.proto): the
// reenactments that finished jobs stored, listed, described, streamed and
// deleted, and the live preview of a job that follows its take (Follow). One
// handler per RPC, reaching the store through the context; unknown ids are
// NOT_FOUND.
//
// Fetch streams the file's messages in the order the proto states: the
// info, every part mesh, the part frames in batches of at most
// kFetchFrameBatchBytes serialized bytes, then the keyframes one per message
// (unless skipped). A reader thread per stream reads the file ahead of the
// client by at most kFetchQueueBytes, so a slow client holds neither a gRPC
// thread nor the whole reenactment in memory.
#pragma once

#include <cstdint>

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// Frames per Fetch message: a batch closes once its frames reach this many
// serialized bytes (well below gRPC's default 4 MiB message limit).
inline constexpr int64_t kFetchFrameBatchBytes = int64_t{1} << 20;
// How far a Fetch reader thread may run ahead of the client, bytes (at
// least one message is always queued).
inline constexpr int64_t kFetchQueueBytes = int64_t{8} << 20;

// The unary handlers.
absl::Status ListReenactments(ServerContext& context, const v1::ListReenactmentsRequest& request,
                              v1::ListReenactmentsResponse* response);
absl::Status GetReenactment(ServerContext& context, const v1::GetReenactmentRequest& request,
                            v1::ReenactmentSummary* response);
absl::Status DeleteReenactment(ServerContext& context, const v1::DeleteReenactmentRequest& request,
                               v1::DeleteReenactmentResponse* response);

class ReenactmentsService final : public v1::Reenactments::CallbackService {
 public:
  explicit ReenactmentsService(ServerContext& context) : context_(context) {}

  grpc::ServerUnaryReactor* List(grpc::CallbackServerContext* rpc,
                                 const v1::ListReenactmentsRequest* request,
                                 v1::ListReenactmentsResponse* response) override;
  grpc::ServerUnaryReactor* Get(grpc::CallbackServerContext* rpc,
                                const v1::GetReenactmentRequest* request,
                                v1::ReenactmentSummary* response) override;
  grpc::ServerWriteReactor<v1::FetchReenactmentChunk>* Fetch(
      grpc::CallbackServerContext* rpc, const v1::FetchReenactmentRequest* request) override;
  grpc::ServerUnaryReactor* Delete(grpc::CallbackServerContext* rpc,
                                   const v1::DeleteReenactmentRequest* request,
                                   v1::DeleteReenactmentResponse* response) override;
  // A live job's preview (server/rpc/follow_stream.h).
  grpc::ServerWriteReactor<v1::FollowEvent>* Follow(grpc::CallbackServerContext* rpc,
                                                    const v1::FollowRequest* request) override;

 private:
  ServerContext& context_;
};

}  // namespace reenact::server
