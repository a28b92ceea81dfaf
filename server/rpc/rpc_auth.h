// The access each reenact-server RPC needs (common/rpc/auth.h), and the
// helpers handlers use to refuse a call before doing anything for it.
#pragma once

#include <grpcpp/grpcpp.h>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/rpc/auth.h"
#include "common/rpc/refused_reactor.h"
#include "proto/grpc_status.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// "/reenact.v1.Takes/List" -> the accesses that allow it:
//   read (viewer, coach, admin): every List, Get, Download, Fetch, Follow,
//     Watch;
//   ingest (capture, admin): Ingest;
//   manage (coach, admin): Jobs.Submit, Jobs.Cancel, Takes.Delete,
//     Reenactments.Delete;
//   work (worker, admin): every Work call (Lease, ReadTake, Heartbeat,
//     Upload, Fail).
// The health service (grpc.health.v1.Health) is not here: its handlers ask
// no authorizer, so probes without a token get their answer
// (common/rpc/health_service.h).
const rpc::Authorizer::MethodTable& ServerMethodAccess();

// The caller of `method` (the anonymous admin when the server has no
// tokens), or the refusal.
absl::StatusOr<rpc::Principal> Authorize(const ServerContext& context,
                                         const grpc::CallbackServerContext& rpc,
                                         absl::string_view method);

using rpc::RefusedBidi;
using rpc::RefusedWriter;

// In a unary handler: finishes the call with the refusal and returns its
// reactor, or returns null when the call may go on.
inline grpc::ServerUnaryReactor* RefuseUnlessAllowed(const ServerContext& context,
                                                     grpc::CallbackServerContext* rpc,
                                                     absl::string_view method) {
  const absl::StatusOr<rpc::Principal> who = Authorize(context, *rpc, method);
  if (who.ok()) return nullptr;
  grpc::ServerUnaryReactor* reactor = rpc->DefaultReactor();
  reactor->Finish(ToGrpcStatus(who.status()));
  return reactor;
}

}  // namespace reenact::server
