// The Work service (proto/reenact/v1/work_service.proto): workers anywhere on
// the network lease jobs from the server's JobScheduler (its leases are in
// server/jobs/job_leases.cc), stream the take, beat and upload. Beyond the
// proto:
//  - An upload may not be longer than its WorkResult.file_bytes, which may
//    not exceed kMaxUploadBytes; the bytes go to a file as they come
//    (nothing is allocated for the declared size).
//  - A Lease call that waits holds no thread: the scheduler answers it.
#pragma once

#include <cstdint>

#include <grpcpp/grpcpp.h>

#include "reenact/v1/work_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// Largest reenactment a worker may upload, bytes.
inline constexpr int64_t kMaxUploadBytes = int64_t{16} << 30;
// Chunk size of ReadTake.
inline constexpr int64_t kWorkTakeChunkBytes = int64_t{1} << 20;

class WorkService final : public v1::Work::CallbackService {
 public:
  explicit WorkService(ServerContext& context) : context_(context) {}

  grpc::ServerUnaryReactor* Lease(grpc::CallbackServerContext* rpc, const v1::LeaseRequest* request,
                                  v1::LeaseResponse* response) override;
  grpc::ServerWriteReactor<v1::TakeChunk>* ReadTake(grpc::CallbackServerContext* rpc,
                                                    const v1::ReadTakeRequest* request) override;
  grpc::ServerUnaryReactor* Heartbeat(grpc::CallbackServerContext* rpc,
                                      const v1::HeartbeatRequest* request,
                                      v1::HeartbeatResponse* response) override;
  grpc::ServerReadReactor<v1::UploadChunk>* Upload(grpc::CallbackServerContext* rpc,
                                                   v1::UploadResponse* response) override;
  grpc::ServerUnaryReactor* Fail(grpc::CallbackServerContext* rpc, const v1::FailRequest* request,
                                 v1::FailResponse* response) override;

 private:
  ServerContext& context_;
};

}  // namespace reenact::server
