#include "server/server.h"

#include "proto/state_names.h"

#include <chrono>
#include <filesystem>
#include <map>
#include <set>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/log/log.h"
#include "common/rpc/channel.h"
#include "common/rpc/client_limits.h"
#include "common/rpc/request_metrics.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/metrics/server_metrics.h"
#include "server/rpc/ingest_service.h"
#include "server/rpc/jobs_service.h"
#include "server/rpc/reenactments_service.h"
#include "server/rpc/rpc_auth.h"
#include "server/rpc/takes_service.h"
#include "server/rpc/work_service.h"

namespace reenact::server {
namespace {

// Largest --max-message-mb: gRPC sizes are int bytes.
constexpr int kMaxMessageMb = 2047;
// Time for a new connection's TLS and HTTP/2 handshake; a client on a slow
// link does it in well under a second.
constexpr int kHandshakeTimeoutMs = 10'000;

}  // namespace

absl::Status ServerOptions::Validate() const {
  if (data_dir.empty()) return absl::InvalidArgumentError("the data folder is not set");
  if (max_message_mb < 1 || max_message_mb > kMaxMessageMb) {
    return absl::InvalidArgumentError(
        absl::StrCat("max message size must be 1..", kMaxMessageMb, " MiB, got ", max_message_mb));
  }
  if (blocking_threads < 1) return absl::InvalidArgumentError("blocking_threads must be >= 1");
  if (!listen_address.empty()) {
    std::string host;
    int port = 0;
    RETURN_IF_ERROR(SplitHostPort("listen address", listen_address, &host, &port));
  }
  RETURN_IF_ERROR(tls.Validate());
  RETURN_IF_ERROR(client_limits.Validate());
  RETURN_IF_ERROR(rpc::CheckExposure(absl::StrCat("--listen ", listen_address), listen_address,
                                     tls.enabled(), !auth_file.empty(), insecure,
                                     "read and delete every take"));
  if (!metrics_address.empty()) {
    std::string host;
    int port = 0;
    RETURN_IF_ERROR(SplitHostPort("--metrics", metrics_address, &host, &port));
    // Plain HTTP without tokens: only loopback unless the operator says so.
    RETURN_IF_ERROR(rpc::CheckExposure(absl::StrCat("--metrics ", metrics_address), metrics_address,
                                       /*tls=*/false, /*tokens=*/false, insecure,
                                       "read the server's figures"));
  }
  TakeStoreOptions store_options = store;
  store_options.data_dir = data_dir;
  RETURN_IF_ERROR(jobs.Validate());
  RETURN_IF_ERROR(live.Validate());
  return store_options.Validate();
}

namespace {

// The services the health service answers for, besides "" (the server).
std::vector<std::string> HealthServiceNames() {
  return {v1::Ingest::service_full_name(), v1::Takes::service_full_name(),
          v1::Jobs::service_full_name(), v1::Reenactments::service_full_name(),
          v1::Work::service_full_name()};
}

// The methods reenact_rpc_requests_total names; any other is "other".
std::set<std::string, std::less<>> CountedMethods() {
  std::set<std::string, std::less<>> methods;
  for (const auto& [method, access] : ServerMethodAccess()) methods.insert(method);
  methods.insert("/grpc.health.v1.Health/Check");
  methods.insert("/grpc.health.v1.Health/Watch");
  return methods;
}

}  // namespace

std::vector<std::unique_ptr<grpc::Service>> MakeServices(ServerContext& context) {
  std::vector<std::unique_ptr<grpc::Service>> services;
  services.push_back(std::make_unique<IngestService>(context));
  services.push_back(std::make_unique<TakesService>(context));
  services.push_back(std::make_unique<JobsService>(context));
  services.push_back(std::make_unique<ReenactmentsService>(context));
  services.push_back(std::make_unique<WorkService>(context));
  return services;
}

absl::StatusOr<std::unique_ptr<Server>> Server::Start(const ServerOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::unique_ptr<Server> server(new Server());
  server->options_ = options;
  // Credentials and tokens before anything is opened: a bad file stops the
  // server with nothing touched.
  ASSIGN_OR_RETURN(const std::shared_ptr<grpc::ServerCredentials> credentials,
                   rpc::MakeServerCredentials(options.tls));
  std::optional<rpc::TokenTable> tokens;
  std::string local_token;  // Its own workers' token, in memory only.
  if (!options.auth_file.empty()) {
    ASSIGN_OR_RETURN(tokens, rpc::TokenTable::Load(options.auth_file));
    if (options.jobs.local_workers) {
      ASSIGN_OR_RETURN(local_token, rpc::NewToken());
      RETURN_IF_ERROR(tokens->Add("reenact-server local workers", rpc::Role::kWorker, local_token));
    }
  }
  server->auth_ = std::make_unique<rpc::Authorizer>(std::move(tokens), ServerMethodAccess());
  server->local_token_ = local_token;
  if (options.tls.enabled() && server->auth_->enabled()) {
    // Calls without a valid token end before their messages are read
    // (common/rpc/auth.h); the health service needs none.
    credentials->SetAuthMetadataProcessor(
        rpc::MakeTokenMetadataProcessor(server->auth_.get(), {"/grpc.health.v1.Health/"}));
  }
  // Workers run in their job's folder: every path handed to them (the take,
  // the output) must not depend on the server's working directory.
  std::error_code error;
  const std::filesystem::path data_dir = std::filesystem::absolute(options.data_dir, error);
  if (error) {
    return absl::InvalidArgumentError(
        absl::StrCat("data folder ", options.data_dir, ": ", error.message()));
  }
  server->options_.data_dir = data_dir.lexically_normal().string();
  if (!options.jobs.worker_path.empty()) {
    const std::filesystem::path worker = std::filesystem::absolute(options.jobs.worker_path, error);
    if (error) {
      return absl::InvalidArgumentError(
          absl::StrCat("worker ", options.jobs.worker_path, ": ", error.message()));
    }
    server->options_.jobs.worker_path = worker.lexically_normal().string();
  }
  const ServerOptions& absolute = server->options_;
  RegisterServerCounters();
  server->health_ = std::make_unique<rpc::HealthService>(HealthServiceNames());
  TakeStoreOptions store_options = absolute.store;
  store_options.data_dir = absolute.data_dir;
  store_options.disk_full_changed = [s = server.get(),
                                     chained = absolute.store.disk_full_changed](bool full) {
    s->SetDiskFull(full);
    if (chained) chained(full);
  };
  ASSIGN_OR_RETURN(server->store_, TakeStore::Open(store_options, &server->recovered_));
  ASSIGN_OR_RETURN(server->reenactments_,
                   ReenactmentStore::Open(absolute.data_dir + "/reenactments"));
  ASSIGN_OR_RETURN(server->job_store_,
                   JobStore::Open(&server->store_->catalog(), options.jobs.store));
  server->live_ = std::make_unique<LiveHub>(absolute.live);
  ASSIGN_OR_RETURN(
      server->jobs_,
      JobScheduler::Start(absolute.jobs, absolute.data_dir + "/jobs", server->job_store_.get(),
                          server->store_.get(), server->reenactments_.get(), server->live_.get()));
  server->blocking_ = std::make_unique<ThreadPool>(options.blocking_threads);
  server->context_.takes = server->store_.get();
  server->context_.blocking = server->blocking_.get();
  server->context_.ingest_queue_limit_bytes = options.ingest_queue_limit_bytes;
  server->context_.jobs = server->jobs_.get();
  server->context_.reenactments = server->reenactments_.get();
  server->context_.live = server->live_.get();
  server->context_.keep_derived = options.keep_derived;
  if (server->auth_->enabled()) server->context_.auth = server->auth_.get();
  server->client_limits_ = std::make_unique<rpc::ClientLimits>(options.client_limits);
  server->context_.client_limits = server->client_limits_.get();
  server->services_ = MakeServices(server->context_);

  grpc::ServerBuilder builder;
  const int max_bytes = options.max_message_mb << 20;
  builder.SetMaxReceiveMessageSize(max_bytes);
  // Notice dead daemons within ~15 s, so that their takes are freed for a
  // resume; accept the daemons' own keepalive pings.
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 5'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 5'000);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
  // A connection that has not finished its TLS and HTTP/2 handshake in this
  // time is closed (gRPC's default waits 120 s): connections that never
  // start TLS hold a descriptor for seconds, not minutes
  // (server/listener_guard.h).
  builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS, kHandshakeTimeoutMs);
  int port = 0;
  std::string host;
  if (!options.listen_address.empty()) {
    RETURN_IF_ERROR(SplitHostPort("listen address", options.listen_address, &host, &port));
    builder.AddListeningPort(options.listen_address, credentials, &server->port_);
  }
  for (const auto& service : server->services_) builder.RegisterService(service.get());
  // No token needed (common/rpc/health_service.h): probes hold none.
  server->health_->SetClientLimits(server->client_limits_.get());
  builder.RegisterService(server->health_.get());
  auto interceptors = rpc::RequestMetricsInterceptors(CountedMethods());
  interceptors.push_back(server->client_limits_->InterceptorFactory());
  builder.experimental().SetInterceptorCreators(std::move(interceptors));
  server->grpc_server_ = builder.BuildAndStart();
  if (server->grpc_server_ == nullptr || (!options.listen_address.empty() && server->port_ == 0)) {
    return absl::UnavailableError(absl::StrCat("cannot listen on ", options.listen_address,
                                               " (address in use, not local, or not permitted)"));
  }
  if (!options.listen_address.empty()) server->address_ = JoinHostPort(host, server->port_);
  if (absolute.jobs.local_workers && server->jobs_->concurrency() > 0) {
    server->StartLocalWorkers(local_token);
  }
  if (!options.metrics_address.empty()) {
    Server* const s = server.get();
    ASSIGN_OR_RETURN(server->metrics_, metrics::HttpExposer::Start(options.metrics_address, [s] {
                       metrics::Snapshot snapshot;
                       metrics::DefaultRegistry().CollectInto(snapshot);
                       s->CollectMetrics(snapshot);
                       metrics::AddProcessMetrics(snapshot);
                       return snapshot.Expose();
                     }));
    server->metrics_address_ = server->metrics_->address();
  }
  return server;
}

void Server::SetDiskFull(bool full) {
  if (disk_full_.exchange(full) == full) return;
  health_->SetProblem("disk_full", full);
  if (full) {
    log::Error("disk_full", {{"data_dir", options_.data_dir}},
               "the data folder's disk is full; health is NOT_SERVING until writes succeed again");
  } else {
    log::Info("disk_full_cleared", {{"data_dir", options_.data_dir}},
              "the data folder's disk takes writes again");
  }
}

void Server::CollectMetrics(metrics::Snapshot& out) const {
  const std::map<v1::JobState, int64_t> counts = job_store_->CountByState();
  for (const v1::JobState state :
       {v1::JOB_STATE_QUEUED, v1::JOB_STATE_RUNNING, v1::JOB_STATE_SUCCEEDED, v1::JOB_STATE_FAILED,
        v1::JOB_STATE_CANCELLED}) {
    const auto it = counts.find(state);
    out.AddGauge("reenact_jobs", "Jobs in the job store, by state.",
                 {{"state", JobStateName(state)}},
                 it == counts.end() ? 0.0 : static_cast<double>(it->second));
  }
  const auto queued = counts.find(v1::JOB_STATE_QUEUED);
  out.AddGauge("reenact_job_queue_length", "Jobs waiting for a worker slot.", {},
               queued == counts.end() ? 0.0 : static_cast<double>(queued->second));
  out.AddGauge("reenact_data_disk_free_bytes",
               "Bytes free for the server on the data folder's file system (statvfs).", {},
               metrics::FreeDiskBytes(options_.data_dir));
  out.AddGauge("reenact_serving",
               "1 while the health service answers SERVING, 0 while NOT_SERVING.", {},
               health_->StatusFor("") == grpc::health::v1::HealthCheckResponse::SERVING ? 1 : 0);
}

Server::~Server() { Shutdown(); }

absl::Status Server::ReloadTokens() {
  if (options_.auth_file.empty() || !auth_enabled()) {
    return absl::FailedPreconditionError("the server was started without --auth");
  }
  ASSIGN_OR_RETURN(rpc::TokenTable tokens, rpc::TokenTable::Load(options_.auth_file));
  if (!local_token_.empty()) {
    RETURN_IF_ERROR(tokens.Add("reenact-server local workers", rpc::Role::kWorker, local_token_));
  }
  const size_t count = tokens.size();
  RETURN_IF_ERROR(auth_->ReplaceTokens(std::move(tokens)));
  log::Info("tokens_reloaded", {{"file", options_.auth_file}, {"tokens", count}},
            absl::StrCat("read ", options_.auth_file, " again"));
  return absl::OkStatus();
}

std::shared_ptr<grpc::Channel> Server::InProcessChannel() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options_.max_message_mb << 20);
  args.SetMaxSendMessageSize(-1);
  return grpc_server_->InProcessChannel(args);
}

std::shared_ptr<grpc::Channel> Server::InProcessChannel(const std::string& token,
                                                        const std::string& client) {
  if (token.empty() && client.empty()) return InProcessChannel();
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options_.max_message_mb << 20);
  args.SetMaxSendMessageSize(-1);
  std::vector<std::pair<std::string, std::string>> metadata;
  if (!token.empty()) metadata.emplace_back("authorization", absl::StrCat("Bearer ", token));
  if (!client.empty()) metadata.emplace_back(rpc::kForwardedClientKey, client);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(rpc::MakeMetadataInterceptorFactory(std::move(metadata)));
  return grpc_server_->experimental().InProcessChannelWithInterceptors(args,
                                                                       std::move(interceptors));
}

void Server::StartLocalWorkers(const std::string& token) {
  const JobSchedulerOptions& jobs = options_.jobs;
  LocalWorkersOptions local;
  local.count = jobs_->concurrency();
  local.job_program = jobs_->worker_path();
  local.scratch_dir = options_.data_dir + "/scratch";
  local.asset_roots = jobs.asset_roots;
  local.memory_limit_mb = jobs_->job_memory_mb();
  local.cancel_grace_s = jobs.cancel_grace_s;
  local.stop_grace_s = jobs.shutdown_grace_s;
  local.poll_period_s = jobs.poll_period_s;
  local.channel = InProcessChannel(token);
  JobScheduler* const scheduler = jobs_.get();
  local.local_take = [scheduler](const std::string& lease_id) -> std::optional<std::string> {
    absl::StatusOr<std::string> path = scheduler->LeasedTakePath(lease_id);
    if (!path.ok()) return std::nullopt;
    return *std::move(path);
  };
  local_workers_ = std::make_unique<LocalWorkers>(std::move(local));
}

void Server::Shutdown() {
  if (shut_down_ || grpc_server_ == nullptr) return;
  shut_down_ = true;
  // Probes hear NOT_SERVING first: balancers stop sending work while the
  // server drains.
  health_->Shutdown();
  // Live follows first: their subscribers hear the end; their jobs stay
  // RUNNING.
  live_->Shutdown();
  // Its own workers next: each stops its job, which stays RUNNING and runs
  // again after a restart.
  jobs_->StopLeasing();
  if (local_workers_ != nullptr) local_workers_->Stop();
  // Then the scheduler: network workers' jobs stay RUNNING until their
  // leases lapse after a restart; watch streams end with UNAVAILABLE.
  jobs_->Shutdown();
  store_->Shutdown(absl::UnavailableError(
      "the server is shutting down; every acknowledged frame set is stored, resume the take "
      "later"));
  const auto grace = std::chrono::duration_cast<std::chrono::nanoseconds>(
      std::chrono::duration<double>(options_.shutdown_grace_s));
  grpc_server_->Shutdown(std::chrono::system_clock::now() + grace);
  blocking_->Wait();
  if (metrics_ != nullptr) metrics_->Stop();
}

void Server::Wait() {
  if (grpc_server_ != nullptr) grpc_server_->Wait();
}

http::HttpBackend HttpBackendOf(Server* server) {
  http::HttpBackend backend;
  backend.auth = server->auth_enabled();
  backend.channel = [server](const std::string& token, const std::string& client) {
    return server->InProcessChannel(token, client);
  };
  backend.derived_path = [server](const std::string& id, const std::string& extension) {
    return server->reenactments().DerivedPathFor(id, extension);
  };
  backend.still_stored = [server](const std::string& id) {
    return server->reenactments().Get(id).ok();
  };
  return backend;
}

}  // namespace reenact::server
