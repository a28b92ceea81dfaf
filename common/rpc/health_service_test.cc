// The health service over a real gRPC server on loopback, through the
// stub generated from proto/grpc/health/v1/health.proto.
#include "common/rpc/health_service.h"

#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

namespace reenact::rpc {
namespace {

using grpc::health::v1::Health;
using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

struct Served {
  std::unique_ptr<HealthService> health;
  std::unique_ptr<grpc::Server> server;
  std::unique_ptr<Health::Stub> stub;

  std::unique_ptr<ClientLimits> limits;

  explicit Served(int max_watches = HealthService::kDefaultMaxWatches,
                  const ClientLimitOptions* caps = nullptr) {
    health =
        std::make_unique<HealthService>(std::vector<std::string>{"reenact.v1.Takes"}, max_watches);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    if (caps != nullptr) {
      limits = std::make_unique<ClientLimits>(*caps);
      health->SetClientLimits(limits.get());
      std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> counted;
      counted.push_back(limits->InterceptorFactory());
      builder.experimental().SetInterceptorCreators(std::move(counted));
    }
    builder.RegisterService(health.get());
    server = builder.BuildAndStart();
    EXPECT_GT(port, 0);
    stub = Health::NewStub(grpc::CreateChannel("127.0.0.1:" + std::to_string(port),
                                               grpc::InsecureChannelCredentials()));
  }
  ~Served() {
    health->Shutdown();
    server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  }

  grpc::Status Check(const std::string& service, HealthCheckResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    HealthCheckRequest request;
    request.set_service(service);
    return stub->Check(&context, request, response);
  }
};

TEST(HealthService, CheckAnswersForTheServerAndItsServices) {
  Served served;
  HealthCheckResponse response;
  ASSERT_TRUE(served.Check("", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
  ASSERT_TRUE(served.Check("reenact.v1.Takes", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
  EXPECT_EQ(served.Check("reenact.v1.Nothing", &response).error_code(),
            grpc::StatusCode::NOT_FOUND);

  served.health->SetProblem("disk_full", true);
  ASSERT_TRUE(served.Check("", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  ASSERT_TRUE(served.Check("reenact.v1.Takes", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  served.health->SetProblem("draining", true);
  served.health->SetProblem("disk_full", false);
  ASSERT_TRUE(served.Check("", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);  // Still draining.
  served.health->SetProblem("draining", false);
  ASSERT_TRUE(served.Check("", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
}

TEST(HealthService, WatchSendsEveryChangeAndEndsAtShutdown) {
  Served served;
  grpc::ClientContext context;
  HealthCheckRequest request;
  auto reader = served.stub->Watch(&context, request);
  HealthCheckResponse response;
  ASSERT_TRUE(reader->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
  served.health->SetProblem("disk_full", true);
  ASSERT_TRUE(reader->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  served.health->SetProblem("disk_full", true);  // No change: nothing sent.
  served.health->SetProblem("disk_full", false);
  ASSERT_TRUE(reader->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
  served.health->Shutdown();
  ASSERT_TRUE(reader->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  EXPECT_FALSE(reader->Read(&response));
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::UNAVAILABLE);

  // After the shutdown a watch gets NOT_SERVING and ends.
  grpc::ClientContext late_context;
  auto late = served.stub->Watch(&late_context, request);
  ASSERT_TRUE(late->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  EXPECT_FALSE(late->Read(&response));
  EXPECT_EQ(late->Finish().error_code(), grpc::StatusCode::UNAVAILABLE);
}

TEST(HealthService, WatchOfAnUnknownServiceSaysSoAndCancelEndsIt) {
  Served served;
  grpc::ClientContext context;
  HealthCheckRequest request;
  request.set_service("reenact.v1.Nothing");
  auto reader = served.stub->Watch(&context, request);
  HealthCheckResponse response;
  ASSERT_TRUE(reader->Read(&response));
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVICE_UNKNOWN);
  context.TryCancel();
  EXPECT_FALSE(reader->Read(&response));
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  // The service forgets the watch: later changes reach nobody and break nothing.
  served.health->SetProblem("disk_full", true);
  HealthCheckResponse checked;
  ASSERT_TRUE(served.Check("", &checked).ok());
  EXPECT_EQ(checked.status(), HealthCheckResponse::NOT_SERVING);
}

TEST(HealthService, ManyWatchersAllHearTheChange) {
  Served served;
  constexpr int kWatchers = 8;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<HealthCheckResponse>>> readers;
  HealthCheckRequest request;
  for (int i = 0; i < kWatchers; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    readers.push_back(served.stub->Watch(contexts.back().get(), request));
    HealthCheckResponse first;
    ASSERT_TRUE(readers.back()->Read(&first));
    EXPECT_EQ(first.status(), HealthCheckResponse::SERVING);
  }
  served.health->SetProblem("draining", true);
  for (auto& reader : readers) {
    HealthCheckResponse next;
    ASSERT_TRUE(reader->Read(&next));
    EXPECT_EQ(next.status(), HealthCheckResponse::NOT_SERVING);
  }
  for (auto& context : contexts) context->TryCancel();
  for (auto& reader : readers) (void)reader->Finish();
}

TEST(HealthService, WatchesPastTheCapsAreRefusedAndTheOthersGoOn) {
  // One client may hold 3 streams and 5 calls; the server 4 watches in all.
  ClientLimitOptions caps;
  caps.max_calls = 5;
  caps.max_streams = 3;
  Served served(/*max_watches=*/4, &caps);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<HealthCheckResponse>>> readers;
  const HealthCheckRequest request;
  const auto watch = [&]() -> grpc::Status {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    contexts.back()->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    readers.push_back(served.stub->Watch(contexts.back().get(), request));
    HealthCheckResponse first;
    if (readers.back()->Read(&first)) return grpc::Status::OK;
    return readers.back()->Finish();
  };
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(watch().ok()) << i;
  const grpc::Status fourth = watch();
  EXPECT_EQ(fourth.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(fourth.error_message().find("stream"), std::string::npos) << fourth.error_message();
  // Check still answers: unary calls have room left under max_calls.
  HealthCheckResponse response;
  EXPECT_TRUE(served.Check("", &response).ok());
  EXPECT_EQ(served.health->watches(), 3);
  for (int i = 0; i < 3; ++i) contexts[i]->TryCancel();
  for (int i = 0; i < 3; ++i) (void)readers[i]->Finish();
  // Once they end, the cap frees.
  for (int i = 0; i < 50 && served.health->watches() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(served.health->watches(), 0);
}

TEST(HealthService, WatchesPastTheServerCapAreRefused) {
  Served served(/*max_watches=*/2);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<HealthCheckResponse>>> readers;
  const HealthCheckRequest request;
  std::vector<grpc::StatusCode> codes;
  for (int i = 0; i < 3; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    readers.push_back(served.stub->Watch(contexts.back().get(), request));
    HealthCheckResponse first;
    codes.push_back(readers.back()->Read(&first) ? grpc::StatusCode::OK
                                                 : readers.back()->Finish().error_code());
  }
  EXPECT_EQ(codes, (std::vector<grpc::StatusCode>{grpc::StatusCode::OK, grpc::StatusCode::OK,
                                                  grpc::StatusCode::RESOURCE_EXHAUSTED}));
  for (int i = 0; i < 2; ++i) contexts[i]->TryCancel();
  for (int i = 0; i < 2; ++i) (void)readers[i]->Finish();
}

}  // namespace
}  // namespace reenact::rpc
