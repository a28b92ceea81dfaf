// reenact-server as a library: opens the take store (recovering takes a
// crash left recording), registers the services and serves them on a TCP
// address and in-process. server_main.cc is a thin wrapper; tests start a
// Server on 127.0.0.1:0 or use InProcessChannel().
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/thread_pool.h"
#include "common/metrics/http_exposer.h"
#include "common/metrics/metrics.h"
#include "common/rpc/auth.h"
#include "common/rpc/channel.h"
#include "common/rpc/health_service.h"
#include "server/http/http_front.h"
#include "server/jobs/job_scheduler.h"
#include "server/jobs/job_store.h"
#include "server/jobs/local_workers.h"
#include "server/live/live_hub.h"
#include "server/rpc/server_context.h"
#include "server/store/reenactment_store.h"
#include "server/store/take_store.h"

namespace reenact::server {

struct ServerOptions {
  // Folder of the catalog and the take files (TakeStoreOptions.data_dir).
  std::string data_dir;
  // "HOST:PORT" to listen on; port 0 picks a free one; empty: in-process
  // only.
  std::string listen_address = "127.0.0.1:0";
  // Largest message the server accepts, MiB; bigger ones fail with
  // RESOURCE_EXHAUSTED.
  int max_message_mb = 64;
  // Everything else about the take store (data_dir is taken from above).
  TakeStoreOptions store;
  // Threads for blocking handler work (opening takes).
  int blocking_threads = 2;
  // An ingest stream stops reading while this many bytes of its take wait
  // for the disk.
  uint64_t ingest_queue_limit_bytes = uint64_t{64} << 20;
  // How long a shutdown lets streams deliver their last answers, seconds.
  double shutdown_grace_s = 1.0;
  // The job queue: worker program, concurrency, grace periods, methods
  // (server/jobs/job_scheduler.h). Jobs live in the catalog, their worker
  // output in DATA/jobs/<job_id>/, reenactments in DATA/reenactments/.
  JobSchedulerOptions jobs;
  // The live hub (server/live/live_hub.h): its factory makes the followers
  // of live jobs; without one, live jobs of recording takes are refused.
  // reenact-server plugs in the registry's (server/live/live_method_follower.h).
  LiveHubOptions live;
  // TLS for the listening port (common/rpc/channel.h); off when empty.
  rpc::ServerTlsFiles tls{};
  // Token file (common/rpc/auth.h): every call then needs a token whose
  // role allows it. Empty: every caller is the anonymous admin.
  std::string auth_file{};
  // Allows a non-loopback listen address without TLS and tokens.
  bool insecure = false;
  // Takes.Delete keeps the take's reenactments and job folders.
  bool keep_derived = false;
  // "HOST:PORT" of the Prometheus metrics endpoint (GET /metrics; port 0
  // picks a free one); empty: none. It has neither TLS nor tokens, so a
  // non-loopback address needs `insecure`, as the listen address does.
  std::string metrics_address{};
  // Calls and streams one client may hold open at once
  // (common/rpc/client_limits.h).
  rpc::ClientLimitOptions client_limits{};

  // InvalidArgument naming the first bad field; FailedPrecondition for a
  // non-loopback address without TLS and tokens (unless insecure).
  absl::Status Validate() const;
};

class Server {
 public:
  // Opens the store and starts serving. Unavailable when the address cannot
  // be bound; the store's errors when the data folder is unusable.
  static absl::StatusOr<std::unique_ptr<Server>> Start(const ServerOptions& options);
  // Shutdown().
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // "HOST:PORT" actually bound (the port resolved when 0 was asked); empty
  // without a listen address.
  const std::string& address() const { return address_; }
  int port() const { return port_; }
  // The metrics endpoint's bound "HOST:PORT"; empty without one.
  const std::string& metrics_address() const { return metrics_address_; }
  // A channel to this server that bypasses the network.
  std::shared_ptr<grpc::Channel> InProcessChannel();
  // The same, sending `token` with every call ("authorization: Bearer"), so
  // that the calls are authorised as that token's (the HTTP front's calls
  // on behalf of its clients). Empty `token`: none is sent. A non-empty
  // `client` (a web client's address) is sent as rpc::kForwardedClientKey,
  // so that the calls count under that client's caps
  // (--max-calls-per-client, --max-streams-per-client).
  std::shared_ptr<grpc::Channel> InProcessChannel(const std::string& token,
                                                  const std::string& client = {});
  // Whether calls need a token (--auth).
  bool auth_enabled() const { return auth_ != nullptr && auth_->enabled(); }
  // Reads the --auth token file again (SIGHUP): tokens added since work and
  // removed ones are refused from the next call on; the server's own
  // workers keep theirs. FailedPrecondition without --auth; the file's
  // errors leave the tokens as they were.
  absl::Status ReloadTokens();
  // Takes that Start() recovered after a crash.
  const std::vector<RecoveredTake>& recovered() const { return recovered_; }
  TakeStore& takes() { return *store_; }
  JobScheduler& jobs() { return *jobs_; }
  LiveHub& live() { return *live_; }
  ReenactmentStore& reenactments() { return *reenactments_; }
  // The grpc.health.v1.Health service (common/rpc/health_service.h).
  rpc::HealthService& health() { return *health_; }

  // Whether the data folder's disk is full: the health service answers
  // NOT_SERVING while it is (the store calls it through
  // TakeStoreOptions.disk_full_changed; operators' tools may too). Logged
  // when it changes. Thread-safe.
  void SetDiskFull(bool full);

  // The figures only this server knows, read now: jobs by state, the queue,
  // the data folder's free bytes, whether it serves.
  void CollectMetrics(metrics::Snapshot& out) const;

  // Graceful stop: health says NOT_SERVING (and its watches end), ends live
  // follows (their jobs stay RUNNING and run offline after a restart),
  // refuses new takes, makes every received frame set durable and finishes
  // recording takes as INTERRUPTED, ends their streams with UNAVAILABLE,
  // then stops serving. Idempotent.
  void Shutdown();
  // Blocks until Shutdown() (from another thread) has stopped the server.
  void Wait();

 private:
  // Starts --workers local:N over the in-process channel with `token`.
  void StartLocalWorkers(const std::string& token);
  Server() = default;

  ServerOptions options_;
  std::vector<RecoveredTake> recovered_;
  // Before the store, which may report a full disk while it opens.
  std::unique_ptr<rpc::HealthService> health_;
  std::atomic<bool> disk_full_{false};
  std::unique_ptr<TakeStore> store_;
  // Declared after the take store (whose catalog holds the jobs) and before
  // the gRPC server, so that they outlive every handler.
  std::unique_ptr<ReenactmentStore> reenactments_;
  std::unique_ptr<JobStore> job_store_;
  // Before the scheduler, which calls it (and is called back by it).
  std::unique_ptr<LiveHub> live_;
  std::unique_ptr<JobScheduler> jobs_;
  std::unique_ptr<ThreadPool> blocking_;
  std::unique_ptr<rpc::Authorizer> auth_;
  std::string local_token_;  // Its own workers' token (memory only); "" none.
  // Before the gRPC server, whose interceptor refers to it.
  std::unique_ptr<rpc::ClientLimits> client_limits_;
  ServerContext context_;
  std::vector<std::unique_ptr<grpc::Service>> services_;
  std::unique_ptr<grpc::Server> grpc_server_;
  std::string address_;
  int port_ = 0;
  bool shut_down_ = false;
  // Last: destroyed first, so that no scrape reads a store being destroyed.
  std::unique_ptr<metrics::HttpExposer> metrics_;
  // Its own workers (--workers local:N); last, so that they go first.
  std::unique_ptr<LocalWorkers> local_workers_;
  std::string metrics_address_;
};

// The services of the server, registered in this one place.
std::vector<std::unique_ptr<grpc::Service>> MakeServices(ServerContext& context);

// What the HTTP front (server/http/http_front.h) serves of `server`: its
// tokens, its in-process channel and its reenactment store's files.
// `server` must outlive the front.
http::HttpBackend HttpBackendOf(Server* server);

}  // namespace reenact::server
