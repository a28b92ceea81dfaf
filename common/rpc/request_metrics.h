// reenact_rpc_requests_total{method,code}: every call a server finishes,
// counted by a gRPC server interceptor, so that no handler has to remember
// to count (and refusals, which end before a handler does anything, are
// counted too).
//
// Only the methods given are named in the label; any other method (a client
// calling one this server does not have) is counted as "other", so that
// callers cannot grow the set of series without bound.
#pragma once

#include <memory>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/support/server_interceptor.h>

namespace reenact::rpc {

// Interceptor creators for grpc::ServerBuilder::experimental()
// .SetInterceptorCreators(). `methods`: full names ("/reenact.v1.Takes/List").
std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
RequestMetricsInterceptors(std::set<std::string, std::less<>> methods);

}  // namespace reenact::rpc
