// Tokens and roles over real TLS on loopback: every role against every RPC
// of reenact-server, anonymous calls, unknown tokens, clients that do not
// trust the server's CA, and takes resumed by another credential.
#include "server/rpc/rpc_auth.h"

#include <chrono>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "common/base/subprocess.h"
#include "common/rpc/channel.h"
#include "common/testing/test_data.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "reenact/v1/work_service.grpc.pb.h"
#include "server/server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

struct Fixture {
  std::string dir;
  std::map<std::string, std::string> tokens;  // name -> token
  std::unique_ptr<Server> server;
};

// A server with TLS (the project's own certificates) and a token per role,
// plus a second capture credential.
Fixture& Shared() {
  static Fixture* const fixture = [] {
    auto* f = new Fixture;
    f->dir = reenact::testing::MakeTempDir("rpc_auth");
    auto certs = Subprocess::Start({"bash", "deploy/make-certs.sh", f->dir + "/certs"});
    EXPECT_TRUE(certs.ok() && (*certs)->Wait(60)->exit_code == 0);
    for (const auto& [name, role] :
         std::vector<std::pair<std::string, rpc::Role>>{{"viewer", rpc::Role::kViewer},
                                                        {"capture", rpc::Role::kCapture},
                                                        {"coach", rpc::Role::kCoach},
                                                        {"worker", rpc::Role::kWorker},
                                                        {"admin", rpc::Role::kAdmin},
                                                        {"capture-2", rpc::Role::kCapture}}) {
      auto token = rpc::AddToken(f->dir + "/tokens.json", role, name);
      EXPECT_TRUE(token.ok()) << token.status();
      f->tokens[name] = token.value_or("");
    }
    ServerOptions options;
    options.data_dir = f->dir + "/data";
    options.listen_address = "127.0.0.1:0";
    options.tls = {f->dir + "/certs/server.pem", f->dir + "/certs/server.key", ""};
    options.auth_file = f->dir + "/tokens.json";
    options.store.catalog_update_period_s = 3600;
    auto server = Server::Start(options);
    EXPECT_TRUE(server.ok()) << server.status();
    if (server.ok()) f->server = std::move(*server);
    return f;
  }();
  return *fixture;
}

std::shared_ptr<grpc::Channel> Channel(const std::string& token, bool trust_ca = true) {
  Fixture& f = Shared();
  rpc::ClientSecurity security;
  if (trust_ca) security = *rpc::LoadClientSecurity(f.dir + "/certs/ca.pem", "");
  security.token = token;
  return rpc::MakeClientChannel(f.server->address(), grpc::ChannelArguments(), security);
}

void Deadline(grpc::ClientContext& context) {
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
}

template <typename Reader, typename Message>
grpc::Status Drain(Reader& reader, Message& message) {
  while (reader->Read(&message)) {
  }
  return reader->Finish();
}

// One call of each RPC with a harmless request; the status it ends with.
using Call = std::function<grpc::Status(const std::shared_ptr<grpc::Channel>&)>;

std::map<std::string, Call> EveryRpc() {
  std::map<std::string, Call> calls;
  calls["/reenact.v1.Takes/List"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::ListTakesResponse r;
    return v1::Takes::NewStub(ch)->List(&c, {}, &r);
  };
  calls["/reenact.v1.Takes/Get"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::GetTakeRequest q;
    q.set_take_id("no-such-take");
    v1::Take r;
    return v1::Takes::NewStub(ch)->Get(&c, q, &r);
  };
  calls["/reenact.v1.Takes/Delete"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::DeleteTakeRequest q;
    q.set_take_id("no-such-take");
    v1::DeleteTakeResponse r;
    return v1::Takes::NewStub(ch)->Delete(&c, q, &r);
  };
  calls["/reenact.v1.Takes/Download"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::DownloadTakeRequest q;
    q.set_take_id("no-such-take");
    auto reader = v1::Takes::NewStub(ch)->Download(&c, q);
    v1::TakeFileChunk m;
    return Drain(reader, m);
  };
  calls["/reenact.v1.Jobs/Submit"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::SubmitJobRequest q;
    q.set_take_id("no-such-take");
    q.set_method("rigid-cylinders");
    v1::Job r;
    return v1::Jobs::NewStub(ch)->Submit(&c, q, &r);
  };
  calls["/reenact.v1.Jobs/Cancel"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::CancelJobRequest q;
    q.set_job_id("no-such-job");
    v1::Job r;
    return v1::Jobs::NewStub(ch)->Cancel(&c, q, &r);
  };
  calls["/reenact.v1.Jobs/List"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::ListJobsResponse r;
    return v1::Jobs::NewStub(ch)->List(&c, {}, &r);
  };
  calls["/reenact.v1.Jobs/Get"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::GetJobRequest q;
    q.set_job_id("no-such-job");
    v1::Job r;
    return v1::Jobs::NewStub(ch)->Get(&c, q, &r);
  };
  // The Work calls name a lease that does not exist: an allowed caller
  // gets ABORTED (or an empty lease), never a refusal.
  calls["/reenact.v1.Work/Lease"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::LeaseRequest q;
    q.set_protocol(v1::WORK_PROTOCOL_V1);
    v1::LeaseResponse r;
    return v1::Work::NewStub(ch)->Lease(&c, q, &r);
  };
  calls["/reenact.v1.Work/ReadTake"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::ReadTakeRequest q;
    q.set_lease_id("no-such-lease");
    auto reader = v1::Work::NewStub(ch)->ReadTake(&c, q);
    v1::TakeChunk chunk;
    while (reader->Read(&chunk)) {
    }
    return reader->Finish();
  };
  calls["/reenact.v1.Work/Heartbeat"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::HeartbeatRequest q;
    q.set_lease_id("no-such-lease");
    v1::HeartbeatResponse r;
    return v1::Work::NewStub(ch)->Heartbeat(&c, q, &r);
  };
  calls["/reenact.v1.Work/Upload"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::UploadResponse r;
    auto writer = v1::Work::NewStub(ch)->Upload(&c, &r);
    v1::UploadChunk chunk;
    chunk.set_lease_id("no-such-lease");
    chunk.mutable_result()->set_file_bytes(1);
    chunk.set_data("x");
    writer->Write(chunk);
    writer->WritesDone();
    return writer->Finish();
  };
  calls["/reenact.v1.Work/Fail"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::FailRequest q;
    q.set_lease_id("no-such-lease");
    v1::FailResponse r;
    return v1::Work::NewStub(ch)->Fail(&c, q, &r);
  };
  calls["/reenact.v1.Jobs/ListMethods"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::ListMethodsResponse r;
    return v1::Jobs::NewStub(ch)->ListMethods(&c, v1::ListMethodsRequest(), &r);
  };
  calls["/reenact.v1.Jobs/Watch"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::WatchJobRequest q;
    q.set_job_id("no-such-job");
    auto reader = v1::Jobs::NewStub(ch)->Watch(&c, q);
    v1::JobEvent m;
    return Drain(reader, m);
  };
  calls["/reenact.v1.Reenactments/List"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::ListReenactmentsResponse r;
    return v1::Reenactments::NewStub(ch)->List(&c, {}, &r);
  };
  calls["/reenact.v1.Reenactments/Get"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::GetReenactmentRequest q;
    q.set_reenactment_id("no-such-reenactment");
    v1::ReenactmentSummary r;
    return v1::Reenactments::NewStub(ch)->Get(&c, q, &r);
  };
  calls["/reenact.v1.Reenactments/Delete"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::DeleteReenactmentRequest q;
    q.set_reenactment_id("no-such-reenactment");
    v1::DeleteReenactmentResponse r;
    return v1::Reenactments::NewStub(ch)->Delete(&c, q, &r);
  };
  calls["/reenact.v1.Reenactments/Fetch"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::FetchReenactmentRequest q;
    q.set_reenactment_id("no-such-reenactment");
    auto reader = v1::Reenactments::NewStub(ch)->Fetch(&c, q);
    v1::FetchReenactmentChunk m;
    return Drain(reader, m);
  };
  calls["/reenact.v1.Reenactments/Follow"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    v1::FollowRequest q;
    q.set_job_id("no-such-job");
    auto reader = v1::Reenactments::NewStub(ch)->Follow(&c, q);
    v1::FollowEvent m;
    return Drain(reader, m);
  };
  calls["/reenact.v1.Ingest/Ingest"] = [](const auto& ch) {
    grpc::ClientContext c;
    Deadline(c);
    auto stream = v1::Ingest::NewStub(ch)->Ingest(&c);
    stream->WritesDone();
    v1::IngestResponse m;
    return Drain(stream, m);
  };
  return calls;
}

bool Refused(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
         s.error_code() == grpc::StatusCode::PERMISSION_DENIED;
}

TEST(RpcAuth, EveryRpcIsInTheTableAndEveryRoleGetsExactlyItsAccess) {
  Fixture& f = Shared();
  ASSERT_NE(f.server, nullptr);
  const std::map<std::string, Call> calls = EveryRpc();
  // Every method the table names is called here, and the reverse.
  ASSERT_EQ(calls.size(), ServerMethodAccess().size());
  for (const auto& [method, access] : ServerMethodAccess()) {
    ASSERT_TRUE(calls.contains(method)) << method;
  }
  for (const std::string role : {"viewer", "capture", "coach", "worker", "admin"}) {
    const auto channel = Channel(f.tokens.at(role));
    const uint32_t granted = rpc::RoleAccess(*rpc::ParseRole(role));
    for (const auto& [method, call] : calls) {
      const grpc::Status status = call(channel);
      const bool allowed = (granted & ServerMethodAccess().at(method)) != 0;
      if (allowed) {
        EXPECT_FALSE(Refused(status)) << role << " " << method << ": " << status.error_message();
      } else {
        EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED)
            << role << " " << method << ": " << status.error_message();
      }
    }
  }
}

TEST(RpcAuth, AnonymousAndUnknownTokensAreUnauthenticated) {
  Fixture& f = Shared();
  ASSERT_NE(f.server, nullptr);
  for (const std::string& token : {std::string(), std::string("rnt_") + std::string(64, 'f')}) {
    const auto channel = Channel(token);
    for (const auto& [method, call] : EveryRpc()) {
      const grpc::Status status = call(channel);
      EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED)
          << (token.empty() ? "anonymous " : "unknown token ") << method;
      EXPECT_EQ(status.error_message().find(token.empty() ? "\x01" : token), std::string::npos);
    }
  }
}

rpc::ClientSecurity AdminWithoutTls(const Fixture& f) {
  rpc::ClientSecurity security;
  security.token = f.tokens.at("admin");
  return security;
}

TEST(RpcAuth, ClientsThatDoNotTrustTheServersCaNeverConnect) {
  Fixture& f = Shared();
  ASSERT_NE(f.server, nullptr);
  // The admin token, without TLS and with TLS but no CA: no call gets
  // through, and the token is never sent in clear.
  const auto plaintext =
      rpc::MakeClientChannel(f.server->address(), grpc::ChannelArguments(), AdminWithoutTls(f));
  const grpc::Status status = EveryRpc().at("/reenact.v1.Takes/List")(plaintext);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
  const std::string other = f.dir + "/other-ca";
  auto certs = Subprocess::Start({"bash", "deploy/make-certs.sh", other});
  ASSERT_TRUE(certs.ok() && (*certs)->Wait(60)->exit_code == 0);
  auto wrong_ca = rpc::LoadClientSecurity(other + "/ca.pem", "");
  ASSERT_TRUE(wrong_ca.ok());
  wrong_ca->token = f.tokens.at("admin");
  const auto untrusted =
      rpc::MakeClientChannel(f.server->address(), grpc::ChannelArguments(), *wrong_ca);
  const grpc::Status refused = EveryRpc().at("/reenact.v1.Takes/List")(untrusted);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.error_message();
}

// Opens `take_id` as daemon "d1" with `token`; the status of the stream and
// whether the take was opened.
grpc::Status OpenTakeAs(const std::string& token, const std::string& take_id, bool* opened) {
  const auto channel = Channel(token);
  grpc::ClientContext c;
  Deadline(c);
  auto stream = v1::Ingest::NewStub(channel)->Ingest(&c);
  v1::IngestRequest open;
  *open.mutable_open() = testing::MakeOpenTake(take_id, "d1", 1);
  stream->Write(open);
  v1::IngestResponse response;
  *opened = stream->Read(&response) && response.has_opened();
  stream->WritesDone();
  while (stream->Read(&response)) {
  }
  return stream->Finish();
}

TEST(RpcAuth, OnlyTheCredentialThatCreatedATakeOrAnAdminMayResumeIt) {
  Fixture& f = Shared();
  ASSERT_NE(f.server, nullptr);
  bool opened = false;
  OpenTakeAs(f.tokens.at("capture"), "bound-take", &opened);
  ASSERT_TRUE(opened);
  // The stream ended without CloseTake: the take is interrupted, resumable.
  const grpc::Status other = OpenTakeAs(f.tokens.at("capture-2"), "bound-take", &opened);
  EXPECT_FALSE(opened);
  EXPECT_EQ(other.error_code(), grpc::StatusCode::PERMISSION_DENIED) << other.error_message();
  OpenTakeAs(f.tokens.at("capture"), "bound-take", &opened);
  EXPECT_TRUE(opened);
  OpenTakeAs(f.tokens.at("admin"), "bound-take", &opened);
  EXPECT_TRUE(opened);
  // Nothing stored was touched by the refusal.
  auto take = f.server->takes().GetTake("bound-take");
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_EQ(take->daemon_id(), "d1");
}

TEST(RpcAuth, NonLoopbackWithoutTlsAndTokensIsRefusedUnlessInsecure) {
  ServerOptions options;
  options.data_dir = reenact::testing::MakeTempDir("rpc_auth_open");
  options.listen_address = "0.0.0.0:0";
  const auto refused = Server::Start(options);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("--insecure"), std::string::npos);
  options.insecure = true;
  const auto allowed = Server::Start(options);
  EXPECT_TRUE(allowed.ok()) << allowed.status();
}

}  // namespace
}  // namespace reenact::server
