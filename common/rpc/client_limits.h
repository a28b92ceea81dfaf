// Caps on what one client may hold open on a server at once: calls of any
// kind, and streams (the calls that can last: ingest, download, fetch,
// follow, watch). One client is one peer address and one credential, so
// that a coach's tablet and a capture daemon behind the same NAT are two
// clients, and a client that opens connection after connection is still
// one.
//
// A gRPC server interceptor counts every call from the moment its metadata
// arrives until it ends, so that no handler has to remember to; handlers
// ask Check() (after authorisation) and refuse with RESOURCE_EXHAUSTED.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <grpcpp/server_context.h>
#include <grpcpp/support/server_interceptor.h>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace reenact::rpc {

// The metadata key in which a server's own front (the HTTP front) names the
// web client a call is made for (its IP address), so that each web client
// counts on its own under the caps, not every user of one token as one.
inline constexpr char kForwardedClientKey[] = "x-reenact-forwarded-client";

struct ClientLimitOptions {
  // Calls of one client running at once, streams included.
  int max_calls = 256;
  // Streaming calls of one client running at once.
  int max_streams = 64;

  // InvalidArgument unless both are >= 1 and max_streams <= max_calls.
  absl::Status Validate() const;
};

class ClientLimits {
 public:
  explicit ClientLimits(const ClientLimitOptions& options);
  ClientLimits(const ClientLimits&) = delete;
  ClientLimits& operator=(const ClientLimits&) = delete;

  // For grpc::ServerBuilder::experimental().SetInterceptorCreators(); the
  // factory refers to this object, which must outlive the server.
  std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> InterceptorFactory();

  // OK, or ResourceExhausted naming the limit (and its flag) when the
  // caller of `rpc` runs more calls than allowed or, when `rpc` is a stream,
  // more streams; `rpc` counted.
  absl::Status Check(const grpc::CallbackServerContext& rpc, bool stream) const;

  // Calls and streams of all clients running now.
  int calls() const;
  int streams() const;

  // Who a call comes from: the peer's address without its port, and a hash
  // of its authorization header (never the token itself). A call over the
  // in-process transport (the HTTP front's calls for its web clients, whose
  // peer gRPC reports as no address) counts under the client that
  // `forwarded_client` (metadata kForwardedClientKey) names; from the
  // network that key is ignored, so no caller can pose as another.
  static std::string ClientKey(absl::string_view peer, absl::string_view authorization,
                               absl::string_view forwarded_client = {});

  // Whether `peer` (grpc::ServerContext::peer()) is a network peer: an
  // ipv4:, ipv6: or unix: address.
  static bool IsNetworkPeer(absl::string_view peer);

 private:
  friend class ClientCallCounter;
  struct Count {
    int calls = 0;
    int streams = 0;
  };
  void Enter(const std::string& key, bool stream);
  void Leave(const std::string& key, bool stream);

  const ClientLimitOptions options_;
  mutable std::mutex mu_;
  std::map<std::string, Count> counts_;
  int calls_ = 0;
  int streams_ = 0;
};

}  // namespace reenact::rpc
