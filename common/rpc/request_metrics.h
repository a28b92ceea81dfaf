// reenact_rpc_requests_total{method,code} and the latency histogram
// reenact_rpc_duration_seconds{method}: every call a server finishes,
// counted and timed (arrival to status) by a gRPC server interceptor, so
// that no handler has to remember to count (and refusals, which end before
// a handler does anything, are counted too). A call to a method the server
// does not have gets UNIMPLEMENTED with a message saying so, where gRPC's
// own answer has none.
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
