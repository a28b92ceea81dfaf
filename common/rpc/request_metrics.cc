#include "common/rpc/request_metrics.h"

#include <memory>
#include <utility>

#include "absl/status/status.h"
#include "common/metrics/metrics.h"

namespace reenact::rpc {
namespace {

using grpc::experimental::InterceptionHookPoints;

constexpr char kName[] = "reenact_rpc_requests_total";
constexpr char kHelp[] = "RPCs finished by the server, by method and status code.";

class RequestCounter final : public grpc::experimental::Interceptor {
 public:
  explicit RequestCounter(std::string method) : method_(std::move(method)) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    // The status a handler finishes with passes here once per call, whatever
    // the kind of call (unary or streaming).
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status status = methods->GetSendStatus();
      metrics::DefaultRegistry()
          .GetCounter(kName, kHelp,
                      {{"method", method_},
                       {"code", absl::StatusCodeToString(
                                    static_cast<absl::StatusCode>(status.error_code()))}})
          .Increment();
    }
    methods->Proceed();
  }

 private:
  const std::string method_;
};

class RequestCounterFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit RequestCounterFactory(std::set<std::string, std::less<>> methods)
      : methods_(std::move(methods)) {}

  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override {
    const char* method = info->method();
    const bool known = method != nullptr && methods_.contains(std::string_view(method));
    return new RequestCounter(known ? method : "other");
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
