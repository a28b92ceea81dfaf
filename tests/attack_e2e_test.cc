// The real reenact-server under attacks that need no token, from a client on
// loopback: the server keeps serving, or recovers on its own within
// seconds, with every stored take intact.
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact::testing {
namespace {

namespace fs = std::filesystem;

// Opens up to `count` TCP connections to 127.0.0.1:`port` that send
// nothing; returns their descriptors.
std::vector<int> OpenIdleConnections(int port, int count) {
  std::vector<int> fds;
  for (int i = 0; i < count; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) break;
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) != 0) {
      ::close(fd);
      break;
    }
    fds.push_back(fd);
  }
  return fds;
}

// The peak resident memory of process `pid` (VmHWM), in MiB; -1 unknown.
double PeakResidentMib(int pid) {
  const std::string status = ReadText("/proc/" + std::to_string(pid) + "/status");
  const size_t at = status.find("VmHWM:");
  if (at == std::string::npos) return -1;
  return std::strtod(status.c_str() + at + 6, nullptr) / 1024.0;
}

class AttackE2e : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir("attack_e2e");
    // This test holds a thousand sockets itself.
    rlimit limit{};
    if (::getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur < limit.rlim_max) {
      limit.rlim_cur = limit.rlim_max;
      (void)::setrlimit(RLIMIT_NOFILE, &limit);
    }
  }
  void TearDown() override {
    if (server_ && server_->Running()) {
      (void)server_->Signal(SIGTERM);
      (void)server_->Wait(30);
    }
  }

  // reenact-server under `ulimit -n descriptors` with `flags`; returns its
  // address.
  std::string StartServer(int descriptors, const std::vector<std::string>& flags = {}) {
    SubprocessOptions options;
    options.stdout_path = options.stderr_path = dir_ + "/server.log";
    std::vector<std::string> argv = {"/bin/sh",
                                     "-c",
                                     "ulimit -n \"$0\" && exec \"$@\"",
                                     std::to_string(descriptors),
                                     Bin("reenact-server"),
                                     "--data",
                                     dir_ + "/data",
                                     "--listen",
                                     "127.0.0.1:0",
                                     "--port-file",
                                     dir_ + "/server.port",
                                     "--workers",
                                     "none"};
    argv.insert(argv.end(), flags.begin(), flags.end());
    auto started = Subprocess::Start(argv, options);
    EXPECT_TRUE(started.ok()) << started.status();
    if (!started.ok()) return "";
    server_ = std::move(*started);
    for (int i = 0; i < 300; ++i) {
      const std::string text = ReadText(dir_ + "/server.port");
      if (const auto nl = text.find('\n'); nl != std::string::npos) return text.substr(0, nl);
      if (!server_->Running()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ADD_FAILURE() << "the server did not start: " << ReadText(dir_ + "/server.log");
    return "";
  }

  // `reenact takes show ID --json` as JSON; null when the call fails.
  nlohmann::json ShowTake(const std::string& address, const std::string& id, double timeout_s) {
    const CommandResult shown =
        RunCommand(dir_, "show",
                   {Bin("reenact"), "takes", "show", id, "--server", address, "--json"}, timeout_s);
    if (shown.exit_code != 0) return nullptr;
    return nlohmann::json::parse(shown.out, nullptr, /*allow_exceptions=*/false);
  }

  std::string dir_;
  std::unique_ptr<Subprocess> server_;
};

TEST_F(AttackE2e, IdleConnectionsThatExhaustDescriptorsDoNotStopTheGrpcPort) {
  const std::string mkv = TestDataDir() + "/rgbd/azure-kinect-mkv/recording.mkv";
  if (!fs::exists(mkv)) GTEST_SKIP() << "no Azure Kinect recording under ../shared/data";
  const std::string take = dir_ + "/desk.mcap";
  const CommandResult imported =
      RunCommand(dir_, "import", {Bin("reenact"), "import", mkv, "--out", take, "--quiet"});
  ASSERT_EQ(imported.exit_code, 0) << imported.err;
  // A low limit, so that a thousand connections exhaust it.
  const std::string address = StartServer(256);
  ASSERT_FALSE(address.empty());
  const CommandResult up = RunCommand(dir_, "upload",
                                      {Bin("reenact"), "takes", "upload", take, "--server", address,
                                       "--spool", dir_ + "/spool", "--json"});
  ASSERT_EQ(up.exit_code, 0) << up.err;
  const std::string take_id =
      nlohmann::json::parse(up.out, nullptr, false).value("take_id", std::string());
  ASSERT_FALSE(take_id.empty()) << up.out;
  const nlohmann::json before = ShowTake(address, take_id, 60);
  ASSERT_TRUE(before.is_object());
  int port = 0;
  ASSERT_TRUE(absl::SimpleAtoi(address.substr(address.rfind(':') + 1), &port));

  // A thousand connections that never start a handshake, held a second.
  std::vector<int> idle = OpenIdleConnections(port, 1000);
  std::printf("%zu idle connections opened\n", idle.size());
  EXPECT_GE(idle.size(), 300u);
  std::this_thread::sleep_for(std::chrono::seconds(1));
  for (const int fd : idle) ::close(fd);
  const auto closed = std::chrono::steady_clock::now();
  nlohmann::json after;
  while (std::chrono::steady_clock::now() - closed < std::chrono::seconds(30)) {
    after = ShowTake(address, take_id, 10);
    if (after.is_object()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - closed).count();
  std::printf("the gRPC port answered again %.1f s after the connections closed\n", seconds);
  ASSERT_TRUE(after.is_object()) << "the gRPC port never answered again: "
                                 << ReadText(dir_ + "/server.log");
  EXPECT_LT(seconds, 15.0);
  EXPECT_TRUE(server_->Running());
  // Nothing stored is lost.
  EXPECT_EQ(after["frame_set_count"], before["frame_set_count"]);
  EXPECT_EQ(after["size_bytes"], before["size_bytes"]);
  EXPECT_EQ(after["state"], before["state"]);
  // It said what happened.
  const std::string log = ReadText(dir_ + "/server.log");
  EXPECT_NE(log.find("grpc_listener_stopped"), std::string::npos) << log;
  EXPECT_NE(log.find("server_restarting"), std::string::npos) << log;
}

TEST_F(AttackE2e, CallsWithoutATokenAreRefusedBeforeTheirMessagesAreRead) {
  ASSERT_EQ(RunCommand(dir_, "certs", {"bash", "deploy/make-certs.sh", dir_ + "/tls"}).exit_code,
            0);
  const CommandResult added =
      RunCommand(dir_, "add",
                 {Bin("reenact"), "auth", "add", "--file", dir_ + "/tokens.json", "--role",
                  "viewer", "--name", "v"});
  ASSERT_EQ(added.exit_code, 0) << added.err;
  const std::string address =
      StartServer(4096, {"--tls-cert", dir_ + "/tls/server.pem", "--tls-key",
                         dir_ + "/tls/server.key", "--auth", dir_ + "/tokens.json"});
  ASSERT_FALSE(address.empty());
  const int pid = server_->pid();
  const double before_mib = PeakResidentMib(pid);
  grpc::SslCredentialsOptions tls;
  tls.pem_root_certs = ReadText(dir_ + "/tls/ca.pem");
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(-1);
  const auto channel = grpc::CreateCustomChannel(address, grpc::SslCredentials(tls), args);
  grpc::GenericStub stub(channel);
  // A call of `method` with `bytes` as its request and no token.
  const auto call = [&stub](const std::string& method, const std::string& bytes) {
    grpc::Slice slice(bytes);
    grpc::ByteBuffer request(&slice, 1);
    grpc::ByteBuffer response;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    std::mutex mutex;
    std::condition_variable done;
    bool finished = false;
    grpc::Status status;
    stub.UnaryCall(&context, method, grpc::StubOptions(), &request, &response, [&](grpc::Status s) {
      std::lock_guard<std::mutex> lock(mutex);
      status = std::move(s);
      finished = true;
      done.notify_all();
    });
    std::unique_lock<std::mutex> lock(mutex);
    done.wait(lock, [&] { return finished; });
    return status;
  };
  // Eight calls at once, each with a 60 MiB request and no token.
  const std::string bytes(60u << 20, 'x');
  std::vector<std::thread> callers;
  std::vector<grpc::StatusCode> codes(8, grpc::StatusCode::OK);
  for (int i = 0; i < 8; ++i) {
    callers.emplace_back(
        [&, i] { codes[i] = call("/reenact.v1.Jobs/Submit", bytes).error_code(); });
  }
  for (std::thread& caller : callers) caller.join();
  const double after_mib = PeakResidentMib(pid);
  std::printf("8 calls of 60 MiB without a token: server peak memory %.0f -> %.0f MiB\n",
              before_mib, after_mib);
  for (const grpc::StatusCode code : codes) EXPECT_EQ(code, grpc::StatusCode::UNAUTHENTICATED);
  // Reading them would have taken 480 MiB.
  EXPECT_LT(after_mib - before_mib, 100.0);
  // Health needs no token and still answers (an empty request is a valid
  // HealthCheckRequest).
  const grpc::Status health = call("/grpc.health.v1.Health/Check", "");
  EXPECT_TRUE(health.ok()) << health.error_message();
}

}  // namespace
}  // namespace reenact::testing
