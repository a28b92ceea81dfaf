// The Ingest service (proto/reenact/v1/ingest_service.proto): one take per
// bidirectional stream, acknowledged as frame sets become durable.
//
// Each stream is an IngestStream reactor. Its answers, beyond the protocol:
//  - FrameSet, SensorLost or CloseTake before OpenTake: FAILED_PRECONDITION.
//  - OpenTake of a take another stream is recording: ABORTED (retry once that
//    stream has ended; a dead connection is noticed by keepalive).
//  - OpenTake of a COMPLETE take by its daemon: TakeOpened{resumed, N}; a
//    CloseTake{last_sequence N} then gets TakeClosed again (idempotent after
//    a lost reply), while a FrameSet or any other CloseTake gets
//    ALREADY_EXISTS.
//  - A stream that ends without CloseTake (half-close, cancel, network cut):
//    the take is finished as INTERRUPTED; a half-closing client is told
//    ABORTED.
//  - Server shutdown: UNAVAILABLE after every received frame set is durable.
// On every error the take keeps each frame set durable before the refused
// message, its file is finished and valid, and its daemon may resume it.
//
// With a live hub in the context (server/live/live_hub.h), the stream tells
// it of the take's opening, of each accepted FrameSet of a followed take (a
// copy, with the time the set reached the handler) and of the recording's
// end; the hub queues the sets for its own threads.
#pragma once

#include <grpcpp/grpcpp.h>

#include "reenact/v1/ingest_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

class IngestService final : public v1::Ingest::CallbackService {
 public:
  explicit IngestService(ServerContext& context) : context_(context) {}

  grpc::ServerBidiReactor<v1::IngestRequest, v1::IngestResponse>* Ingest(
      grpc::CallbackServerContext* rpc) override;

 private:
  ServerContext& context_;
};

}  // namespace reenact::server
