#include "server/rpc/rpc_auth.h"

#include <iostream>

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
      {"/reenact.v1.Reenactments/List", rpc::kRead},
      {"/reenact.v1.Reenactments/Get", rpc::kRead},
      {"/reenact.v1.Reenactments/Fetch", rpc::kRead},
      {"/reenact.v1.Reenactments/Follow", rpc::kRead},
      {"/reenact.v1.Reenactments/Delete", rpc::kManage},
  };
  return *table;
}

absl::StatusOr<rpc::Principal> Authorize(const ServerContext& context,
                                         const grpc::CallbackServerContext& rpc,
                                         absl::string_view method) {
  if (context.auth == nullptr) return rpc::Principal{};
  absl::StatusOr<rpc::Principal> who = context.auth->Authorize(rpc, method);
  if (!who.ok()) {
    std::cerr << "reenact-server: refused " << method << " from " << rpc.peer() << ": "
              << absl::StatusCodeToString(who.status().code()) << "\n";
  }
  return who;
}

}  // namespace reenact::server
