// What the RPC handlers reach the server's domain through. The server builds
// one ServerContext and hands it to every service; handlers hold a reference
// and touch nothing else, so tests drive them with stores of their own.
// Later services (jobs, reenactments) add their stores here.
#pragma once

#include <cstdint>

#include "common/base/thread_pool.h"
#include "common/rpc/auth.h"
#include "common/rpc/client_limits.h"
#include "server/store/take_store.h"

namespace reenact::server {
class JobScheduler;
class LiveHub;
class ReenactmentStore;
}  // namespace reenact::server

namespace reenact::server {

struct ServerContext {
  // The take store (Ingest, Takes).
  TakeStore* takes = nullptr;
  // Runs handler work that blocks (opening a take: file creation, fsync),
  // keeping it off gRPC's callback threads.
  ThreadPool* blocking = nullptr;
  // An ingest stream stops reading while its take has more than this many
  // bytes queued for the disk (flow control back to the daemon).
  uint64_t ingest_queue_limit_bytes = uint64_t{64} << 20;
  // The job queue and its worker processes (Jobs).
  JobScheduler* jobs = nullptr;
  // The reenactments finished jobs made (Jobs, Reenactments).
  ReenactmentStore* reenactments = nullptr;
  // Follows recording takes for live jobs (Ingest feeds it, Follow
  // subscribes); null: no live preview.
  LiveHub* live = nullptr;
  // Who may call what (server/rpc/rpc_auth.h); null: everyone, as the
  // anonymous admin.
  const rpc::Authorizer* auth = nullptr;
  // Calls and streams per client (checked with authorisation); null: none.
  const rpc::ClientLimits* client_limits = nullptr;
  // Takes.Delete keeps the take's reenactments and job folders (images of
  // the person) instead of deleting them with it.
  bool keep_derived = false;
};

}  // namespace reenact::server
