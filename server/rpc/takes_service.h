// The Takes service (proto/reenact/v1/takes_service.proto): the catalog of
// stored takes. One handler per RPC, reaching the store through the context;
// malformed take ids are INVALID_ARGUMENT, unknown ones NOT_FOUND.
#pragma once

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// Download chunks: 1 MiB unless the request asks for 1 byte .. 16 MiB.
inline constexpr int32_t kDefaultDownloadChunkBytes = 1 << 20;
inline constexpr int32_t kMaxDownloadChunkBytes = 16 << 20;

// The unary handlers.
absl::Status ListTakes(ServerContext& context, const v1::ListTakesRequest& request,
                       v1::ListTakesResponse* response);
absl::Status GetTake(ServerContext& context, const v1::GetTakeRequest& request, v1::Take* response);
absl::Status DeleteTake(ServerContext& context, const v1::DeleteTakeRequest& request,
                        v1::DeleteTakeResponse* response);

class TakesService final : public v1::Takes::CallbackService {
 public:
  explicit TakesService(ServerContext& context) : context_(context) {}

  grpc::ServerUnaryReactor* List(grpc::CallbackServerContext* rpc,
                                 const v1::ListTakesRequest* request,
                                 v1::ListTakesResponse* response) override;
  grpc::ServerUnaryReactor* Get(grpc::CallbackServerContext* rpc, const v1::GetTakeRequest* request,
                                v1::Take* response) override;
  grpc::ServerUnaryReactor* Delete(grpc::CallbackServerContext* rpc,
                                   const v1::DeleteTakeRequest* request,
                                   v1::DeleteTakeResponse* response) override;
  // Streams the file with pread, one chunk per write; fails with ABORTED
  // when the take is resumed (its file reopened) during the download.
  grpc::ServerWriteReactor<v1::TakeFileChunk>* Download(
      grpc::CallbackServerContext* rpc, const v1::DownloadTakeRequest* request) override;

 private:
  ServerContext& context_;
};

}  // namespace reenact::server
