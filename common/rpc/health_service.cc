#include "common/rpc/health_service.h"

#include <algorithm>
#include <optional>
#include <utility>

#include "proto/write_pump.h"

namespace reenact::rpc {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

namespace {

// A Watch refused before it started.
class RefusedWatch final : public grpc::ServerWriteReactor<HealthCheckResponse> {
 public:
  explicit RefusedWatch(const grpc::Status& status) { Finish(status); }
  void OnDone() override { delete this; }
};

grpc::Status ToGrpc(const absl::Status& status) {
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

}  // namespace

// One Watch call. It re-reads the service's status whenever told to
// (Refresh), so a late notice can never send an older status after a newer
// one. Owned by itself from the start until OnDone; the service holds weak
// references and locks one before calling it, so a notice racing with the
// end of the call touches a live object.
class HealthWatch final : public PumpedWriteReactor<HealthCheckResponse> {
 public:
  // The reactor to hand to gRPC (writes started before that are held by
  // gRPC until it has the reactor).
  static HealthWatch* Start(HealthService* service, std::string name) {
    auto watch = std::shared_ptr<HealthWatch>(new HealthWatch(service, std::move(name)));
    watch->self_ = watch;
    const bool open = service->AddWatch(watch);
    watch->Refresh();
    if (!open) watch->End();
    return watch.get();
  }

  // Queues the current status when it differs from the last one queued.
  void Refresh() {
    {
      std::lock_guard<std::mutex> lock(mutex());
      if (ended_locked()) return;
      const HealthService::ServingStatus status = service_->StatusFor(name_);
      if (last_queued_.has_value() && *last_queued_ == status) return;
      last_queued_ = status;
      pending_ = status;
    }
    Pump();
  }

  // Nothing more is sent after what is queued; then UNAVAILABLE.
  void End() {
    {
      std::lock_guard<std::mutex> lock(mutex());
      MarkEndedLocked();
    }
    Pump();
  }

  void OnDone() override {
    std::shared_ptr<HealthWatch> keep = std::move(self_);
    service_->RemoveWatch(this);
    // `keep` (maybe the last reference) goes out of scope last.
  }

 private:
  HealthWatch(HealthService* service, std::string name)
      : PumpedWriteReactor("the health watch"), service_(service), name_(std::move(name)) {}

  bool TakeNextLocked(HealthCheckResponse* next) override {
    if (!pending_.has_value()) return false;
    next->set_status(*pending_);
    pending_.reset();
    return true;
  }
  grpc::Status EndStatusLocked() override {
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is shutting down");
  }

  HealthService* const service_;
  const std::string name_;
  std::shared_ptr<HealthWatch> self_;
  std::optional<HealthService::ServingStatus> last_queued_;
  std::optional<HealthService::ServingStatus> pending_;
};

HealthService::HealthService(std::vector<std::string> services, int max_watches)
    : services_(std::make_move_iterator(services.begin()), std::make_move_iterator(services.end())),
      max_watches_(std::max(1, max_watches)) {}

HealthService::~HealthService() = default;

void HealthService::SetProblem(std::string_view problem, bool present) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    const bool changed =
        present ? problems_.emplace(problem).second : problems_.erase(std::string(problem)) > 0;
    if (!changed) return;
  }
  NotifyWatches(/*end=*/false);
}

void HealthService::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (shut_down_) return;
    shut_down_ = true;
  }
  NotifyWatches(/*end=*/true);
}

HealthService::ServingStatus HealthService::StatusFor(std::string_view service) const {
  if (!service.empty() && !services_.contains(service)) {
    return HealthCheckResponse::SERVICE_UNKNOWN;
  }
  std::lock_guard<std::mutex> lock(mu_);
  return shut_down_ || !problems_.empty() ? HealthCheckResponse::NOT_SERVING
                                          : HealthCheckResponse::SERVING;
}

std::vector<std::string> HealthService::problems() const {
  std::lock_guard<std::mutex> lock(mu_);
  return {problems_.begin(), problems_.end()};
}

grpc::ServerUnaryReactor* HealthService::Check(grpc::CallbackServerContext* context,
                                               const HealthCheckRequest* request,
                                               HealthCheckResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  const ClientLimits* limits = nullptr;
  {
    std::lock_guard<std::mutex> lock(mu_);
    limits = limits_;
  }
  if (limits != nullptr) {
    if (const absl::Status allowed = limits->Check(*context, /*stream=*/false); !allowed.ok()) {
      reactor->Finish(ToGrpc(allowed));
      return reactor;
    }
  }
  const ServingStatus status = StatusFor(request->service());
  if (status == HealthCheckResponse::SERVICE_UNKNOWN) {
    reactor->Finish(grpc::Status(grpc::StatusCode::NOT_FOUND,
                                 "unknown service \"" + request->service() + "\""));
    return reactor;
  }
  response->set_status(status);
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerWriteReactor<HealthCheckResponse>* HealthService::Watch(
    grpc::CallbackServerContext* context, const HealthCheckRequest* request) {
  const ClientLimits* limits = nullptr;
  {
    std::lock_guard<std::mutex> lock(mu_);
    limits = limits_;
    // Forget the watches that ended, so the list is as long as the live ones.
    watches_.erase(std::remove_if(watches_.begin(), watches_.end(),
                                  [](const std::weak_ptr<HealthWatch>& w) { return w.expired(); }),
                   watches_.end());
    if (static_cast<int>(watches_.size()) >= max_watches_) {
      return new RefusedWatch(grpc::Status(
          grpc::StatusCode::RESOURCE_EXHAUSTED,
          "too many health watches are open on this server; use Check, or watch later"));
    }
  }
  if (limits != nullptr) {
    if (const absl::Status allowed = limits->Check(*context, /*stream=*/true); !allowed.ok()) {
      return new RefusedWatch(ToGrpc(allowed));
    }
  }
  return HealthWatch::Start(this, request->service());
}

void HealthService::SetClientLimits(const ClientLimits* limits) {
  std::lock_guard<std::mutex> lock(mu_);
  limits_ = limits;
}

int HealthService::watches() const {
  std::lock_guard<std::mutex> lock(mu_);
  return static_cast<int>(
      std::count_if(watches_.begin(), watches_.end(),
                    [](const std::weak_ptr<HealthWatch>& w) { return !w.expired(); }));
}

bool HealthService::AddWatch(const std::shared_ptr<HealthWatch>& watch) {
  std::lock_guard<std::mutex> lock(mu_);
  watches_.push_back(watch);
  return !shut_down_;
}

void HealthService::RemoveWatch(const HealthWatch* watch) {
  std::lock_guard<std::mutex> lock(mu_);
  watches_.erase(std::remove_if(watches_.begin(), watches_.end(),
                                [watch](const std::weak_ptr<HealthWatch>& w) {
                                  const std::shared_ptr<HealthWatch> live = w.lock();
                                  return live == nullptr || live.get() == watch;
                                }),
                 watches_.end());
}

void HealthService::NotifyWatches(bool end) {
  // Called without mu_: a write or finish may run the reactor's callbacks
  // on this thread, and OnDone takes mu_.
  std::vector<std::shared_ptr<HealthWatch>> live;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const std::weak_ptr<HealthWatch>& w : watches_) {
      if (std::shared_ptr<HealthWatch> watch = w.lock()) live.push_back(std::move(watch));
    }
  }
  for (const std::shared_ptr<HealthWatch>& watch : live) {
    watch->Refresh();
    if (end) watch->End();
  }
}

}  // namespace reenact::rpc
