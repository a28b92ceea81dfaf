// The standard gRPC health service (grpc.health.v1.Health,
// proto/grpc/health/v1/health.proto) of reenact-server and reenactd.
//
// The server as a whole ("") and each service it names report one status:
// SERVING, or NOT_SERVING while any problem is set (e.g. "disk_full" when the
// data folder's disk is full, "draining" during a graceful shutdown). Check
// answers NOT_FOUND for a service the server does not have; Watch sends the
// status at once and again at every change (SERVICE_UNKNOWN for an unknown
// service), and ends with UNAVAILABLE at Shutdown, after NOT_SERVING.
//
// The service needs no token: probes (load balancers, systemd, Kubernetes)
// hold none, and it tells nothing but up or down. Its handlers call no
// authorizer, so a server with --auth still answers it. Its calls count
// under the server's per-client caps (SetClientLimits), and Watch streams
// under a cap of their own for all clients together (max_watches): past
// either, RESOURCE_EXHAUSTED.
//
// Thread-safe. Must outlive the gRPC server it is registered with.
#pragma once

#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/rpc/client_limits.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace reenact::rpc {

class HealthWatch;

class HealthService final : public grpc::health::v1::Health::CallbackService {
 public:
  using ServingStatus = grpc::health::v1::HealthCheckResponse::ServingStatus;

  // Watch streams open at once, all clients together, by default.
  static constexpr int kDefaultMaxWatches = 1024;

  // `services`: the fully qualified names of the server's services
  // ("reenact.v1.Ingest"); "" is always known.
  explicit HealthService(std::vector<std::string> services, int max_watches = kDefaultMaxWatches);
  ~HealthService() override;

  // The server's per-client caps, which Check and Watch ask before they
  // answer; null (the default): none. Must outlive the service's calls.
  void SetClientLimits(const ClientLimits* limits);
  // Watch streams open now.
  int watches() const;

  // Sets or clears a named reason not to serve. Watchers hear the change.
  void SetProblem(std::string_view problem, bool present);
  // NOT_SERVING from now on; every Watch gets it and ends (UNAVAILABLE), and
  // later ones end at once. Idempotent.
  void Shutdown();

  // SERVING or NOT_SERVING for a known name, SERVICE_UNKNOWN otherwise.
  ServingStatus StatusFor(std::string_view service) const;
  // The problems set now (for logs and tests).
  std::vector<std::string> problems() const;

  grpc::ServerUnaryReactor* Check(grpc::CallbackServerContext* context,
                                  const grpc::health::v1::HealthCheckRequest* request,
                                  grpc::health::v1::HealthCheckResponse* response) override;
  grpc::ServerWriteReactor<grpc::health::v1::HealthCheckResponse>* Watch(
      grpc::CallbackServerContext* context,
      const grpc::health::v1::HealthCheckRequest* request) override;

 private:
  friend class HealthWatch;
  // Registers a watch; false after Shutdown (the watch then ends at once).
  bool AddWatch(const std::shared_ptr<HealthWatch>& watch);
  void RemoveWatch(const HealthWatch* watch);
  // Tells every watch to send the status again if it changed.
  void NotifyWatches(bool end);

  const std::set<std::string, std::less<>> services_;
  const int max_watches_;
  mutable std::mutex mu_;
  const ClientLimits* limits_ = nullptr;
  std::set<std::string, std::less<>> problems_;
  bool shut_down_ = false;
  std::vector<std::weak_ptr<HealthWatch>> watches_;
};

}  // namespace reenact::rpc
