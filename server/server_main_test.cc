// The reenact-server binary: flags and exit codes, the port file, graceful
// shutdown on SIGTERM, and recovery after SIGKILL in the middle of a take.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/base/time.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "server/listener_guard.h"
#include "server/server_flags.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::ExpectStoredFrameSets;
using testing::IngestClient;
using testing::MakeOpenTake;
using testing::SensorIds;

// A reenact-server child process with its stderr in a file.
struct Child {
  std::unique_ptr<Subprocess> process;
  std::string stderr_path;
  std::string address;

  std::string Stderr() const { return ReadFileToString(stderr_path).value_or(""); }
};

ExitInfo RunToEnd(const std::vector<std::string>& args, std::string* err) {
  const std::string dir = reenact::testing::MakeTempDir("server_main_run");
  SubprocessOptions options;
  options.stderr_path = dir + "/stderr.txt";
  std::vector<std::string> argv = {REENACT_SERVER_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  auto child = Subprocess::Start(argv, options);
  EXPECT_TRUE(child.ok()) << child.status();
  if (!child.ok()) return {};
  auto info = (*child)->Wait(30);
  EXPECT_TRUE(info.ok()) << info.status();
  *err = ReadFileToString(options.stderr_path).value_or("");
  return info.ok() ? *info : ExitInfo{};
}

// Starts the server on `data_dir` and waits for its port file.
Child StartServer(const std::string& data_dir, const std::string& scratch) {
  Child child;
  const std::string port_file = scratch + "/port";
  fs::remove(port_file);
  child.stderr_path = scratch + "/stderr.txt";
  SubprocessOptions options;
  options.stderr_path = child.stderr_path;
  auto process = Subprocess::Start({REENACT_SERVER_BINARY, "--data", data_dir, "--listen",
                                    "127.0.0.1:0", "--port-file", port_file},
                                   options);
  EXPECT_TRUE(process.ok()) << process.status();
  if (!process.ok()) return child;
  child.process = std::move(*process);
  for (int i = 0; i < 1000 && !fs::exists(port_file); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const auto content = ReadFileToString(port_file);
  EXPECT_TRUE(content.ok()) << "no port file; stderr: " << child.Stderr();
  if (!content.ok()) return child;
  EXPECT_TRUE(std::regex_match(*content, std::regex("127\\.0\\.0\\.1:[0-9]+\n"))) << *content;
  child.address = content->substr(0, content->size() - 1);
  EXPECT_NE(child.Stderr().find("listening on " + child.address), std::string::npos)
      << child.Stderr();
  return child;
}

struct Stubs {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::Ingest::Stub> ingest;
  std::unique_ptr<v1::Takes::Stub> takes;
  explicit Stubs(const std::string& address)
      : channel(grpc::CreateChannel(address, grpc::InsecureChannelCredentials())),
        ingest(v1::Ingest::NewStub(channel)),
        takes(v1::Takes::NewStub(channel)) {}
  v1::Take Get(const std::string& id) {
    grpc::ClientContext context;
    v1::GetTakeRequest request;
    request.set_take_id(id);
    v1::Take take;
    EXPECT_TRUE(takes->Get(&context, request, &take).ok());
    return take;
  }
};

TEST(ServerMain, UsageErrorsExitWithTwo) {
  std::string err;
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {},
           {"--data", "/tmp/x"},
           {"--data", "/tmp/x", "--listen", "no-port"},
           {"--data", "/tmp/x", "--listen", "127.0.0.1:0", "--max-message-mb", "0"},
           {"--data", "/tmp/x", "--listen", "127.0.0.1:0", "--depth-check", "maybe"},
           {"--data", "/tmp/x", "--listen", "127.0.0.1:0", "--max-name-bytes", "0"},
           {"--data", "/tmp/x", "--listen", "127.0.0.1:0", "--max-notes-bytes", "-1"},
           {"--data", "/tmp/x", "--listen", "127.0.0.1:0", "--bogus"}}) {
    const ExitInfo info = RunToEnd(args, &err);
    EXPECT_TRUE(info.exited);
    EXPECT_EQ(info.exit_code, 2) << err;
    EXPECT_NE(err.find("usage: reenact-server"), std::string::npos) << err;
  }
}

// --help reads as a page: grouped, every line under 100 characters.
TEST(ServerMain, HelpIsAPageOfShortLines) {
  const std::string usage = reenact::server::kServerUsage;
  size_t lines = 0, longest = 0, start = 0;
  while (start <= usage.size()) {
    size_t end = usage.find('\n', start);
    if (end == std::string::npos) end = usage.size();
    longest = std::max(longest, end - start);
    ++lines;
    start = end + 1;
  }
  std::printf("reenact-server --help: %zu lines, the longest %zu characters\n", lines, longest);
  EXPECT_LT(longest, 100u);
  EXPECT_GT(lines, 40u);
  for (const char* heading : {"Jobs and workers:", "Security:", "Limits on what clients send:"}) {
    EXPECT_NE(usage.find(heading), std::string::npos) << heading;
  }
}

TEST(ServerMain, UnusableDataFolderExitsWithOne) {
  const std::string dir = reenact::testing::MakeTempDir("server_main_bad_data");
  ASSERT_TRUE(WriteFileAtomically(dir + "/file", "not a folder").ok());
  std::string err;
  const ExitInfo info = RunToEnd({"--data", dir + "/file", "--listen", "127.0.0.1:0"}, &err);
  EXPECT_TRUE(info.exited);
  EXPECT_EQ(info.exit_code, 1) << err;
  EXPECT_NE(err.find(dir + "/file"), std::string::npos) << err;
}

TEST(ServerMain, FlagsParseIntoOptions) {
  auto parsed = ParseServerCommandLine({"--data",
                                        "/d",
                                        "--listen",
                                        "0.0.0.0:50051",
                                        "--max-message-mb",
                                        "8",
                                        "--port-file",
                                        "/p",
                                        "--depth-check",
                                        "header",
                                        "--max-name-bytes",
                                        "64",
                                        "--max-notes-bytes",
                                        "1000",
                                        "--tls-cert",
                                        "/c.pem",
                                        "--tls-key",
                                        "/k.pem",
                                        "--auth",
                                        "/t.json"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.data_dir, "/d");
  EXPECT_EQ(parsed->options.listen_address, "0.0.0.0:50051");
  EXPECT_EQ(parsed->options.max_message_mb, 8);
  EXPECT_EQ(parsed->port_file, "/p");
  EXPECT_EQ(parsed->options.store.limits.depth_check, DepthCheck::kHeader);
  EXPECT_EQ(parsed->options.store.limits.max_name_bytes, 64);
  EXPECT_EQ(parsed->options.store.limits.max_notes_bytes, 1000);
  EXPECT_EQ(parsed->options.tls.cert_file, "/c.pem");
  EXPECT_EQ(parsed->options.tls.key_file, "/k.pem");
  EXPECT_EQ(parsed->options.auth_file, "/t.json");
  EXPECT_FALSE(parsed->options.insecure);
  // An open port on the network needs TLS and tokens, or --insecure.
  EXPECT_EQ(ParseServerCommandLine({"--data", "/d", "--listen", "0.0.0.0:50051"}).status().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_TRUE(
      ParseServerCommandLine({"--data", "/d", "--listen", "0.0.0.0:50051", "--insecure"}).ok());
  EXPECT_EQ(ParseServerCommandLine({"--data", "/d", "--listen", "127.0.0.1:1", "--tls-cert", "/c"})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ParseServerCommandLine({"--data", "/d", "--listen", "h:70000"}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ServerMain, RestartKeepsTheBoundPortsAndEveryOtherArgument) {
  const std::vector<std::string> argv = {"reenact-server", "--data",    "/d",
                                         "--listen",       "0.0.0.0:0", "--http=127.0.0.1:0",
                                         "--port-file",    "/p",        "--listen-x"};
  const std::vector<std::string> expected = {
      "reenact-server",         "--data",      "/d", "--listen",  "0.0.0.0:41000",
      "--http=127.0.0.1:41001", "--port-file", "/p", "--listen-x"};
  EXPECT_EQ(PinnedArguments(argv, {{"--listen", "0.0.0.0:41000"},
                                   {"--http", "127.0.0.1:41001"},
                                   {"--metrics", "127.0.0.1:41002"}}),
            expected);
  EXPECT_TRUE(IsListenerFailure("Failed accept4: Too many open files"));
  EXPECT_FALSE(IsListenerFailure("Handshake failed with fatal error SSL_ERROR_SSL"));
  EXPECT_GT(OpenDescriptorCount(), 2);
  EXPECT_GT(RaiseDescriptorLimit(), 0);
}

TEST(ServerMain, SigtermStopsGracefullyAndKeepsTheTake) {
  const std::string scratch = reenact::testing::MakeTempDir("server_main_term");
  const std::string data = scratch + "/data";
  Child child = StartServer(data, scratch);
  ASSERT_FALSE(child.address.empty());
  Stubs stubs(child.address);
  IngestClient client(*stubs.ingest);
  client.Open(MakeOpenTake("t", "daemon-a", 2));
  client.SendSets(1, 7, 2);
  ASSERT_TRUE(client.WaitAck(7));
  ASSERT_TRUE(child.process->Signal(SIGTERM).ok());
  auto info = child.process->Wait(20);
  ASSERT_TRUE(info.ok());
  EXPECT_TRUE(info->exited);
  EXPECT_EQ(info->exit_code, 0) << child.Stderr();
  EXPECT_EQ(client.Finish().error_code(), grpc::StatusCode::UNAVAILABLE);
  Child again = StartServer(data, scratch);
  ASSERT_FALSE(again.address.empty());
  EXPECT_EQ(again.Stderr().find("recovered"), std::string::npos) << again.Stderr();
  Stubs stubs2(again.address);
  const v1::Take take = stubs2.Get("t");
  EXPECT_EQ(take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(take.durable_sequence(), 7u);
  ASSERT_TRUE(again.process->Signal(SIGINT).ok());
  auto again_info = again.process->Wait(20);
  ASSERT_TRUE(again_info.ok());
  EXPECT_EQ(again_info->exit_code, 0);
  ExpectStoredFrameSets(data + "/takes/t.mcap", SensorIds(2), 7);
}

TEST(ServerMain, SigkillMidTakeIsRecoveredAndResumed) {
  const std::string scratch = reenact::testing::MakeTempDir("server_main_kill");
  const std::string data = scratch + "/data";
  Child child = StartServer(data, scratch);
  ASSERT_FALSE(child.address.empty());
  uint64_t acked = 0;
  {
    Stubs stubs(child.address);
    IngestClient client(*stubs.ingest);
    client.Open(MakeOpenTake("t", "daemon-a", 2));
    client.SendSets(1, 10, 2);
    ASSERT_TRUE(client.WaitAck(10));
    client.SendSets(11, 16, 2);  // Some of these may be in flight at the kill.
    ASSERT_TRUE(child.process->Signal(SIGKILL).ok());
    ASSERT_TRUE(child.process->Wait(20).ok());
    client.Finish();
    acked = client.acks().back();
  }
  Child again = StartServer(data, scratch);
  ASSERT_FALSE(again.address.empty());
  EXPECT_NE(again.Stderr().find("recovered take t:"), std::string::npos) << again.Stderr();
  Stubs stubs(again.address);
  v1::Take take = stubs.Get("t");
  EXPECT_EQ(take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_GE(take.durable_sequence(), acked);  // Every ack held.
  EXPECT_LE(take.durable_sequence(), 16u);
  IngestClient client(*stubs.ingest);
  client.Open(MakeOpenTake("t", "daemon-a", 2));
  const auto opened = client.ReadOpened();
  ASSERT_TRUE(opened.has_value());
  EXPECT_TRUE(opened->resumed());
  EXPECT_EQ(opened->durable_sequence(), take.durable_sequence());
  client.SendSets(opened->durable_sequence() + 1, 20, 2);
  client.Close(20);
  ASSERT_TRUE(client.Finish().ok());
  ASSERT_TRUE(again.process->Signal(SIGTERM).ok());
  ASSERT_TRUE(again.process->Wait(20).ok());
  ExpectStoredFrameSets(data + "/takes/t.mcap", SensorIds(2), 20);
}

// Two sensors at 30 fps, 1080p JPEG colour and 512x424 RVL depth: time from
// sending a frame set to its ack (capture to durable, less the capture).
// Printed, not asserted.
TEST(ServerMain, IngestLatencyAtThirtyFramesPerSecond) {
  const std::string scratch = reenact::testing::MakeTempDir("server_main_latency");
  Child child = StartServer(scratch + "/data", scratch);
  ASSERT_FALSE(child.address.empty());
  // A smooth scene with fine texture: ~0.3 MB at quality 90, like a room.
  RgbImage color(1920, 1080);
  for (int y = 0; y < color.height; ++y) {
    for (int x = 0; x < color.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        uint32_t h = (static_cast<uint32_t>(x) * 2654435761u) ^
                     (static_cast<uint32_t>(y) * 40503u) ^ (static_cast<uint32_t>(c) * 97u);
        h = (h ^ (h >> 13)) * 1274126177u;
        h ^= h >> 16;
        color.at(x, y, c) = static_cast<uint8_t>(60 + x / 16 + y / 12 + 30 * c + h % 8);
      }
    }
  }
  const std::string jpeg = *EncodeJpeg(color, 90);
  DepthImageMm depth(512, 424);
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      depth.at(x, y) = static_cast<uint16_t>(2000 + (x * 7 + y * 3) % 400 + (x * y) % 5);  // mm
    }
  }
  const std::string rvl = *EncodeDepth(depth, DepthCodecOptions{.zstd = false});
  v1::OpenTake open = MakeOpenTake("latency", "daemon-a", 2);
  for (v1::SensorCalibration& s : *open.mutable_sensors()) {
    s.mutable_depth_intrinsics()->set_width_px(512);
    s.mutable_depth_intrinsics()->set_height_px(424);
    s.mutable_color_intrinsics()->set_width_px(1920);
    s.mutable_color_intrinsics()->set_height_px(1080);
  }
  Stubs stubs(child.address);
  grpc::ClientContext context;
  auto stream = stubs.ingest->Ingest(&context);
  v1::IngestRequest request;
  *request.mutable_open() = open;
  ASSERT_TRUE(stream->Write(request));
  constexpr uint64_t kSets = 90;
  std::vector<int64_t> sent_ns(kSets + 1, 0), acked_ns(kSets + 1, 0);
  std::thread reader([&] {
    v1::IngestResponse response;
    uint64_t done = 0;
    while (stream->Read(&response)) {
      if (!response.has_ack()) continue;
      const int64_t now = SteadyNowNs();
      for (uint64_t s = done + 1; s <= response.ack().durable_sequence(); ++s) acked_ns[s] = now;
      done = response.ack().durable_sequence();
    }
  });
  const int64_t start_ns = SteadyNowNs();
  size_t set_bytes = 0;
  for (uint64_t s = 1; s <= kSets; ++s) {
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(
        std::chrono::nanoseconds(start_ns + static_cast<int64_t>(s - 1) * testing::kPeriodNs)));
    v1::FrameSet set = testing::MakeFrameSet(s, SensorIds(2));
    for (v1::Frame& f : *set.mutable_frames()) {
      f.clear_mask();
      f.mutable_color()->set_width_px(1920);
      f.mutable_color()->set_height_px(1080);
      f.mutable_color()->set_data(jpeg);
      f.mutable_depth()->set_width_px(512);
      f.mutable_depth()->set_height_px(424);
      f.mutable_depth()->set_encoding("rvl");
      f.mutable_depth()->set_data(rvl);
    }
    request.Clear();
    *request.mutable_frame_set() = std::move(set);
    set_bytes = request.ByteSizeLong();
    sent_ns[s] = SteadyNowNs();
    ASSERT_TRUE(stream->Write(request));
  }
  request.Clear();
  request.mutable_close()->set_last_sequence(kSets);
  ASSERT_TRUE(stream->Write(request));
  stream->WritesDone();
  reader.join();
  ASSERT_TRUE(stream->Finish().ok());
  std::vector<double> ms;
  for (uint64_t s = 1; s <= kSets; ++s) {
    ASSERT_GT(acked_ns[s], 0) << "set " << s << " never acked";
    ms.push_back((acked_ns[s] - sent_ns[s]) * 1e-6);
  }
  std::sort(ms.begin(), ms.end());
  std::printf(
      "send->durable ack over %llu sets of %.2f MB at 30 fps: p50 %.1f ms, p90 %.1f ms, "
      "p99 %.1f ms, max %.1f ms\n",
      static_cast<unsigned long long>(kSets), set_bytes / 1e6, ms[ms.size() / 2],
      ms[ms.size() * 9 / 10], ms[ms.size() * 99 / 100], ms.back());
  ASSERT_TRUE(child.process->Signal(SIGTERM).ok());
  ASSERT_TRUE(child.process->Wait(20).ok());
}

}  // namespace
}  // namespace reenact::server
