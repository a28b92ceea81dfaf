#include "common/rpc/request_metrics.h"

#include <chrono>
#include <memory>
#include <utility>

#include "absl/status/status.h"
#include "common/metrics/metrics.h"

namespace reenact::rpc {
namespace {

using grpc::experimental::InterceptionHookPoints;

constexpr char kName[] = "reenact_rpc_requests_total";
constexpr char kHelp[] = "RPCs finished by the server, by method and status code.";
constexpr char kSecondsName[] = "reenact_rpc_duration_seconds";
constexpr char kSecondsHelp[] =
    "Time from a call's arrival to its status, by method (streams: their whole life).";

class RequestCounter final : public grpc::experimental::Interceptor {
 public:
  explicit RequestCounter(std::string method)
      : method_(std::move(method)), start_(std::chrono::steady_clock::now()) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    // The status a handler finishes with passes here once per call, whatever
    // the kind of call (unary or streaming).
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      grpc::Status status = methods->GetSendStatus();
      if (method_ == kOther && status.error_code() == grpc::StatusCode::UNIMPLEMENTED &&
          status.error_message().empty()) {
        // gRPC's own answer to a method no service has says nothing more.
        status = grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                              "no such method on this server; its services and methods are in "
                              "proto/reenact/v1 (grpc.health.v1.Health/Check for health)");
        methods->ModifySendStatus(status);
      }
      const std::string code =
          absl::StatusCodeToString(static_cast<absl::StatusCode>(status.error_code()));
      metrics::Registry& registry = metrics::DefaultRegistry();
      registry.GetCounter(kName, kHelp, {{"method", method_}, {"code", code}}).Increment();
      registry
          .GetHistogram(kSecondsName, kSecondsHelp, {{"method", method_}},
                        metrics::RequestSecondsBounds())
          .Observe(
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    }
    methods->Proceed();
  }

  static constexpr char kOther[] = "other";

 private:
  const std::string method_;
  const std::chrono::steady_clock::time_point start_;
};

class RequestCounterFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit RequestCounterFactory(std::set<std::string, std::less<>> methods)
      : methods_(std::move(methods)) {}

  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override {
    const char* method = info->method();
    const bool known = method != nullptr && methods_.contains(std::string_view(method));
    return new RequestCounter(known ? method : RequestCounter::kOther);
  }

 private:
  const std::set<std::string, std::less<>> methods_;
};

}  // namespace

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>>
RequestMetricsInterceptors(std::set<std::string, std::less<>> methods) {
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> creators;
  creators.push_back(std::make_unique<RequestCounterFactory>(std::move(methods)));
  return creators;
}

}  // namespace reenact::rpc
