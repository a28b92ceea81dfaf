#include "server/rpc/rpc_auth.h"

#include <set>

#include "common/base/status_macros.h"
#include "server/metrics/server_metrics.h"

namespace reenact::server {

const rpc::Authorizer::MethodTable& ServerMethodAccess() {
  static const auto* const table = new rpc::Authorizer::MethodTable{
      {"/reenact.v1.Ingest/Ingest", rpc::kIngest},
      {"/reenact.v1.Takes/List", rpc::kRead},
      {"/reenact.v1.Takes/Get", rpc::kRead},
      {"/reenact.v1.Takes/Download", rpc::kRead},
      {"/reenact.v1.Takes/Delete", rpc::kManage},
      {"/reenact.v1.Jobs/Submit", rpc::kManage},
      {"/reenact.v1.Jobs/Cancel", rpc::kManage},
      {"/reenact.v1.Jobs/Watch", rpc::kRead},
      {"/reenact.v1.Jobs/List", rpc::kRead},
      {"/reenact.v1.Jobs/Get", rpc::kRead},
      {"/reenact.v1.Jobs/ListMethods", rpc::kRead},
      {"/reenact.v1.Reenactments/List", rpc::kRead},
      {"/reenact.v1.Reenactments/Get", rpc::kRead},
      {"/reenact.v1.Reenactments/Fetch", rpc::kRead},
      {"/reenact.v1.Reenactments/Follow", rpc::kRead},
      {"/reenact.v1.Reenactments/Delete", rpc::kManage},
      {"/reenact.v1.Work/Lease", rpc::kWork},
      {"/reenact.v1.Work/ReadTake", rpc::kWork},
      {"/reenact.v1.Work/Heartbeat", rpc::kWork},
      {"/reenact.v1.Work/Upload", rpc::kWork},
      {"/reenact.v1.Work/Fail", rpc::kWork},
  };
  return *table;
}

absl::StatusOr<rpc::Principal> Authorize(const ServerContext& context,
                                         const grpc::CallbackServerContext& rpc,
                                         absl::string_view method) {
  rpc::Principal who;
  if (context.auth != nullptr) {
    // The authorizer counts and logs each refusal (event auth_refused).
    ASSIGN_OR_RETURN(who, context.auth->Authorize(rpc, method));
  }
  if (context.client_limits != nullptr) {
    // The calls that can last; a unary call counts only against max_calls.
    static const auto* const kStreams = new std::set<absl::string_view>{
        "/reenact.v1.Ingest/Ingest",       "/reenact.v1.Takes/Download",
        "/reenact.v1.Jobs/Watch",          "/reenact.v1.Reenactments/Fetch",
        "/reenact.v1.Reenactments/Follow", "/reenact.v1.Work/ReadTake",
        "/reenact.v1.Work/Upload"};
    if (absl::Status allowed = context.client_limits->Check(rpc, kStreams->contains(method));
        !allowed.ok()) {
      LimitHit("client_calls", {{"rpc", method}, {"peer", rpc.peer()}}, allowed.message());
      return allowed;
    }
  }
  return who;
}

}  // namespace reenact::server
