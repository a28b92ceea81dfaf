// reenactd's control service with TLS and tokens on loopback: each role
// against each CaptureControl RPC, and anonymous callers.
#include <chrono>
#include <functional>
#include <map>
#include <string>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "capture_daemon/capture_control_service.h"
#include "common/base/subprocess.h"
#include "common/rpc/auth.h"
#include "common/rpc/channel.h"
#include "common/testing/test_data.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {
namespace {

// Answers everything at once; StreamFrames ends the stream immediately.
class IdleController : public CaptureController {
 public:
  std::vector<v1::SensorInfo> ListSensors() override { return {}; }
  absl::StatusOr<std::string> StartTake(const v1::StartTakeRequest&) override {
    return absl::FailedPreconditionError("no sensor streams");
  }
  absl::StatusOr<v1::StopTakeResponse> StopTake() override {
    return absl::FailedPreconditionError("no take is being recorded");
  }
  v1::DaemonStatus Status() override { return {}; }
};

TEST(CaptureControlAuth, EachRoleGetsExactlyItsAccessOverTls) {
  const std::string dir = reenact::testing::MakeTempDir("control_auth");
  auto certs = Subprocess::Start({"bash", "deploy/make-certs.sh", dir + "/certs"});
  ASSERT_TRUE(certs.ok() && (*certs)->Wait(60)->exit_code == 0);
  std::map<std::string, std::string> tokens;
  for (const std::string role : {"viewer", "capture", "coach", "admin"}) {
    auto token = rpc::AddToken(dir + "/tokens.json", *rpc::ParseRole(role), role);
    ASSERT_TRUE(token.ok()) << token.status();
    tokens[role] = *token;
  }
  auto table = rpc::TokenTable::Load(dir + "/tokens.json");
  ASSERT_TRUE(table.ok()) << table.status();
  const rpc::Authorizer auth(*table, CaptureControlMethodAccess());
  IdleController controller;
  auto service = CreateCaptureControlService(&controller, &auth);
  auto credentials =
      rpc::MakeServerCredentials({dir + "/certs/server.pem", dir + "/certs/server.key", ""});
  ASSERT_TRUE(credentials.ok()) << credentials.status();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", *credentials, &port);
  builder.RegisterService(service.get());
  auto server = builder.BuildAndStart();
  ASSERT_NE(server, nullptr);
  const std::string address = "127.0.0.1:" + std::to_string(port);

  using Call = std::function<grpc::Status(v1::CaptureControl::Stub&)>;
  auto deadline = [](grpc::ClientContext& c) {
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  };
  std::map<std::string, Call> calls;
  calls["/reenact.v1.CaptureControl/ListSensors"] = [&](auto& stub) {
    grpc::ClientContext c;
    deadline(c);
    v1::ListSensorsResponse r;
    return stub.ListSensors(&c, {}, &r);
  };
  calls["/reenact.v1.CaptureControl/Status"] = [&](auto& stub) {
    grpc::ClientContext c;
    deadline(c);
    v1::DaemonStatus r;
    return stub.Status(&c, {}, &r);
  };
  calls["/reenact.v1.CaptureControl/StartTake"] = [&](auto& stub) {
    grpc::ClientContext c;
    deadline(c);
    v1::StartTakeResponse r;
    return stub.StartTake(&c, {}, &r);
  };
  calls["/reenact.v1.CaptureControl/StopTake"] = [&](auto& stub) {
    grpc::ClientContext c;
    deadline(c);
    v1::StopTakeResponse r;
    return stub.StopTake(&c, {}, &r);
  };
  calls["/reenact.v1.CaptureControl/StreamFrames"] = [&](auto& stub) {
    grpc::ClientContext c;
    deadline(c);
    auto reader = stub.StreamFrames(&c, {});
    v1::LiveFrameSet m;
    while (reader->Read(&m)) {
    }
    return reader->Finish();
  };
  ASSERT_EQ(calls.size(), CaptureControlMethodAccess().size());
  const rpc::ClientSecurity trusted = *rpc::LoadClientSecurity(dir + "/certs/ca.pem", "");
  for (const std::string role : {"viewer", "capture", "coach", "admin", "anonymous"}) {
    rpc::ClientSecurity security = trusted;
    if (role != "anonymous") security.token = tokens.at(role);
    auto stub = v1::CaptureControl::NewStub(
        rpc::MakeClientChannel(address, grpc::ChannelArguments(), security));
    for (const auto& [method, call] : calls) {
      const grpc::Status status = call(*stub);
      if (role == "anonymous") {
        EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << method;
        continue;
      }
      const bool allowed =
          (rpc::RoleAccess(*rpc::ParseRole(role)) & CaptureControlMethodAccess().at(method)) != 0;
      if (allowed) {
        EXPECT_NE(status.error_code(), grpc::StatusCode::PERMISSION_DENIED) << role << method;
        EXPECT_NE(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << role << method;
      } else {
        EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED) << role << method;
      }
    }
  }
  server->Shutdown();
}

}  // namespace
}  // namespace reenact::capture
