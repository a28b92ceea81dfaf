#include "common/rpc/channel.h"

#include <sys/stat.h>

#include <stdlib.h>

#include <chrono>
#include <string>

#include <grpcpp/generic/async_generic_service.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"

namespace reenact::rpc {
namespace {

// Certificates from the project's own script, once per test binary.
const std::string& CertDir() {
  static const std::string dir = [] {
    const std::string out = reenact::testing::MakeTempDir("rpc_certs");
    auto child = Subprocess::Start({"bash", "deploy/make-certs.sh", out});
    EXPECT_TRUE(child.ok()) << child.status();
    if (child.ok()) {
      EXPECT_EQ((*child)->Wait(60)->exit_code, 0);
    }
    return out;
  }();
  return dir;
}

struct Listening {
  // A server needs a service; this one answers UNIMPLEMENTED to everything.
  std::unique_ptr<grpc::CallbackGenericService> service =
      std::make_unique<grpc::CallbackGenericService>();
  std::unique_ptr<grpc::Server> server;
  std::string address;
};

Listening Listen(const ServerTlsFiles& files) {
  auto credentials = MakeServerCredentials(files);
  EXPECT_TRUE(credentials.ok()) << credentials.status();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", *credentials, &port);
  Listening out;
  builder.RegisterCallbackGenericService(out.service.get());
  out.server = builder.BuildAndStart();
  out.address = "127.0.0.1:" + std::to_string(port);
  return out;
}

// True when the channel completes its (TLS) handshake within `timeout_s`.
bool Connects(const std::string& address, const ClientSecurity& security, int timeout_s = 3) {
  auto channel = MakeClientChannel(address, grpc::ChannelArguments(), security);
  return channel->WaitForConnected(std::chrono::system_clock::now() +
                                   std::chrono::seconds(timeout_s));
}

TEST(Tls, ClientsConnectOnlyWithTheServersCa) {
  const std::string& d = CertDir();
  Listening tls = Listen({d + "/server.pem", d + "/server.key", ""});
  ASSERT_NE(tls.server, nullptr);
  auto trusted = LoadClientSecurity(d + "/ca.pem", "");
  ASSERT_TRUE(trusted.ok()) << trusted.status();
  EXPECT_TRUE(Connects(tls.address, *trusted));
  // Same address by name: the certificate names localhost too.
  EXPECT_TRUE(Connects("localhost:" + tls.address.substr(tls.address.rfind(':') + 1), *trusted));
  // No TLS at all, and TLS trusting another CA.
  EXPECT_FALSE(Connects(tls.address, ClientSecurity{}));
  const std::string other = reenact::testing::MakeTempDir("rpc_other_ca");
  ASSERT_EQ((*Subprocess::Start({"bash", "deploy/make-certs.sh", other}))->Wait(60)->exit_code, 0);
  EXPECT_FALSE(Connects(tls.address, *LoadClientSecurity(other + "/ca.pem", "")));
  tls.server->Shutdown();
}

TEST(Tls, ServerWithClientCaRequiresAClientCertificate) {
  const std::string& d = CertDir();
  Listening mtls = Listen({d + "/server.pem", d + "/server.key", d + "/ca.pem"});
  ASSERT_NE(mtls.server, nullptr);
  EXPECT_FALSE(Connects(mtls.address, *LoadClientSecurity(d + "/ca.pem", "")));
  auto with_cert = LoadClientSecurity(d + "/ca.pem", "", d + "/client.pem", d + "/client.key");
  ASSERT_TRUE(with_cert.ok()) << with_cert.status();
  EXPECT_TRUE(Connects(mtls.address, *with_cert));
  mtls.server->Shutdown();
}

TEST(Tls, BadFilesAreClearErrors) {
  const std::string& d = CertDir();
  EXPECT_EQ(MakeServerCredentials({d + "/server.pem", "", ""}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(MakeServerCredentials({"", "", d + "/ca.pem"}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const auto missing = MakeServerCredentials({d + "/nope.pem", d + "/server.key", ""});
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(missing.status().message().find("nope.pem"), std::string::npos);
  ASSERT_TRUE(WriteFileAtomically(d + "/junk.pem", "not a certificate\n").ok());
  EXPECT_EQ(LoadClientSecurity(d + "/junk.pem", "").status().code(),
            absl::StatusCode::kInvalidArgument);
  // The key's text is never echoed.
  const auto bad_key = MakeServerCredentials({d + "/server.pem", d + "/junk.pem", ""});
  EXPECT_EQ(bad_key.status().message().find("not a certificate"), std::string::npos);
}

TEST(ClientSecurity, TokenFromFileOrEnvironment) {
  const std::string dir = reenact::testing::MakeTempDir("rpc_token");
  ASSERT_TRUE(WriteFileAtomically(dir + "/token", "rnt_abc\n").ok());
  ASSERT_EQ(::chmod((dir + "/token").c_str(), 0600), 0);
  ::unsetenv("REENACT_TOKEN");
  ::unsetenv("REENACT_TLS_CA");
  EXPECT_EQ(LoadClientSecurity("", dir + "/token")->token, "rnt_abc");
  EXPECT_EQ(LoadClientSecurity("", "")->token, "");
  ::setenv("REENACT_TOKEN", " rnt_env ", 1);
  EXPECT_EQ(LoadClientSecurity("", "")->token, "rnt_env");
  EXPECT_EQ(LoadClientSecurity("", dir + "/token")->token, "rnt_abc");  // The flag wins.
  ::unsetenv("REENACT_TOKEN");
  // A token file other users may read is refused, and says how to mend it.
  ASSERT_TRUE(WriteFileAtomically(dir + "/shared", "rnt_abc\n").ok());
  ASSERT_EQ(::chmod((dir + "/shared").c_str(), 0644), 0);
  const auto shared = LoadClientSecurity("", dir + "/shared");
  EXPECT_EQ(shared.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(shared.status().message().find("chmod 600"), std::string::npos) << shared.status();
  ASSERT_TRUE(WriteFileAtomically(dir + "/two", "a b\n").ok());
  ASSERT_EQ(::chmod((dir + "/two").c_str(), 0600), 0);
  EXPECT_EQ(LoadClientSecurity("", dir + "/two").status().code(),
            absl::StatusCode::kInvalidArgument);
  ASSERT_TRUE(WriteFileAtomically(dir + "/empty", "\n").ok());
  ASSERT_EQ(::chmod((dir + "/empty").c_str(), 0600), 0);
  EXPECT_EQ(LoadClientSecurity("", dir + "/empty").status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LoadClientSecurity("", dir + "/missing").status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ClientSecurity, TheTokenGoesInPlainTextOnlyToThisMachine) {
  ClientSecurity plain;
  plain.token = "rnt_abc";
  EXPECT_TRUE(TokenMayTravel("127.0.0.1:50051", plain));
  EXPECT_TRUE(TokenMayTravel("[::1]:50051", plain));
  EXPECT_FALSE(TokenMayTravel("192.168.1.2:50051", plain));
  EXPECT_FALSE(TokenMayTravel("studio:50051", plain));
  ClientSecurity tls = plain;
  tls.ca_pem = "-----BEGIN CERTIFICATE-----";
  EXPECT_TRUE(TokenMayTravel("studio:50051", tls));
  EXPECT_TRUE(TokenMayTravel("studio:50051", ClientSecurity{}));
}

TEST(IsLoopbackAddress, KnowsWhatOnlyThisMachineReaches) {
  for (const char* a :
       {"127.0.0.1:50051", "127.1.2.3:1", "localhost:80", "[::1]:50051", "unix:/tmp/s"}) {
    EXPECT_TRUE(IsLoopbackAddress(a)) << a;
  }
  for (const char* a : {"0.0.0.0:50051", "[::]:50051", "192.168.1.2:50051", "studio:50051",
                        "[::2]:1", "128.0.0.1:1"}) {
    EXPECT_FALSE(IsLoopbackAddress(a)) << a;
  }
}

}  // namespace
}  // namespace reenact::rpc
