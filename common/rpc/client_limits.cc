#include "common/rpc/client_limits.h"

#include <functional>
#include <optional>
#include <string_view>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace reenact::rpc {
namespace {

using grpc::experimental::InterceptionHookPoints;
using grpc::experimental::ServerRpcInfo;

constexpr char kAuthorization[] = "authorization";

std::optional<std::string> Metadata(
    const std::multimap<grpc::string_ref, grpc::string_ref>& metadata, const char* key) {
  const auto it = metadata.find(key);
  if (it == metadata.end()) return std::nullopt;
  return std::string(it->second.data(), it->second.size());
}

bool IsStream(ServerRpcInfo::Type type) { return type != ServerRpcInfo::Type::UNARY; }

}  // namespace

// Counts one call of one client from its metadata to its end.
class ClientCallCounter final : public grpc::experimental::Interceptor {
 public:
  ClientCallCounter(ClientLimits* limits, ServerRpcInfo* info)
      : limits_(limits), info_(info), stream_(IsStream(info->type())) {}
  ~ClientCallCounter() override {
    if (entered_) limits_->Leave(key_, stream_);
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (!entered_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      const auto* metadata = methods->GetRecvInitialMetadata();
      const std::optional<std::string> authorization =
          metadata != nullptr ? Metadata(*metadata, kAuthorization) : std::nullopt;
      const std::optional<std::string> forwarded =
          metadata != nullptr ? Metadata(*metadata, kForwardedClientKey) : std::nullopt;
      key_ = ClientLimits::ClientKey(info_->server_context()->peer(), authorization.value_or(""),
                                     forwarded.value_or(""));
      limits_->Enter(key_, stream_);
      entered_ = true;
    }
    methods->Proceed();
  }

 private:
  ClientLimits* const limits_;
  ServerRpcInfo* const info_;
  const bool stream_;
  bool entered_ = false;
  std::string key_;
};

namespace {

class ClientCallCounterFactory final
    : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit ClientCallCounterFactory(ClientLimits* limits) : limits_(limits) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(ServerRpcInfo* info) override {
    return new ClientCallCounter(limits_, info);
  }

 private:
  ClientLimits* const limits_;
};

}  // namespace

absl::Status ClientLimitOptions::Validate() const {
  if (max_calls < 1 || max_streams < 1 || max_streams > max_calls) {
    return absl::InvalidArgumentError(absl::StrCat("client limits: max_calls (", max_calls,
                                                   ") and max_streams (", max_streams,
                                                   ") must be >= 1, streams at most calls"));
  }
  return absl::OkStatus();
}

ClientLimits::ClientLimits(const ClientLimitOptions& options) : options_(options) {}

std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>
ClientLimits::InterceptorFactory() {
  return std::make_unique<ClientCallCounterFactory>(this);
}

bool ClientLimits::IsNetworkPeer(absl::string_view peer) {
  return absl::StartsWith(peer, "ipv4:") || absl::StartsWith(peer, "ipv6:") ||
         absl::StartsWith(peer, "unix:");
}

std::string ClientLimits::ClientKey(absl::string_view peer, absl::string_view authorization,
                                    absl::string_view forwarded_client) {
  // "ipv4:127.0.0.1:54321", "ipv6:[::1]:54321": the port changes with every
  // connection, the host does not.
  absl::string_view host = peer;
  // The server's own front calls in process for a web client: it counts as
  // that client (at most an address's length of it is taken).
  std::string forwarded;
  if (!forwarded_client.empty() && !IsNetworkPeer(peer)) {
    forwarded = absl::StrCat("forwarded:", forwarded_client.substr(0, 64));
    host = forwarded;
  }
  if (absl::StartsWith(peer, "ipv4:") || absl::StartsWith(peer, "ipv6:")) {
    if (const size_t colon = peer.rfind(':'); colon > 5) host = peer.substr(0, colon);
  }
  if (authorization.empty()) return std::string(host);
  return absl::StrFormat(
      "%s|%016x", host,
      std::hash<std::string_view>{}(std::string_view(authorization.data(), authorization.size())));
}

void ClientLimits::Enter(const std::string& key, bool stream) {
  std::lock_guard<std::mutex> lock(mu_);
  Count& count = counts_[key];
  ++count.calls;
  ++calls_;
  if (stream) {
    ++count.streams;
    ++streams_;
  }
}

void ClientLimits::Leave(const std::string& key, bool stream) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = counts_.find(key);
  if (it == counts_.end()) return;
  --it->second.calls;
  --calls_;
  if (stream) {
    --it->second.streams;
    --streams_;
  }
  if (it->second.calls <= 0) counts_.erase(it);
}

absl::Status ClientLimits::Check(const grpc::CallbackServerContext& rpc, bool stream) const {
  const auto& metadata = rpc.client_metadata();
  const std::optional<std::string> authorization = Metadata(metadata, kAuthorization);
  const std::optional<std::string> forwarded = Metadata(metadata, kForwardedClientKey);
  const std::string key = ClientKey(rpc.peer(), authorization.value_or(""), forwarded.value_or(""));
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = counts_.find(key);
  if (it == counts_.end()) return absl::OkStatus();
  if (it->second.calls > options_.max_calls) {
    return absl::ResourceExhaustedError(absl::StrCat("this client runs ", it->second.calls,
                                                     " calls at once; at most ", options_.max_calls,
                                                     " (reenact-server --max-calls-per-client)"));
  }
  if (stream && it->second.streams > options_.max_streams) {
    return absl::ResourceExhaustedError(
        absl::StrCat("this client holds ", it->second.streams, " streams open; at most ",
                     options_.max_streams, " (reenact-server --max-streams-per-client)"));
  }
  return absl::OkStatus();
}

int ClientLimits::calls() const {
  std::lock_guard<std::mutex> lock(mu_);
  return calls_;
}

int ClientLimits::streams() const {
  std::lock_guard<std::mutex> lock(mu_);
  return streams_;
}

}  // namespace reenact::rpc
