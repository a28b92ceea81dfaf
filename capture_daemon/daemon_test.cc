#include "capture_daemon/daemon.h"

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "capture_daemon/reenactd_cli.h"
#include "capture_daemon/testing/fake_ingest.h"
#include "capture_daemon/testing/synthetic_take.h"
#include "common/base/files.h"
#include "common/metrics/testing/scrape.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {
namespace {

namespace fs = std::filesystem;

DaemonOptions BaseOptions(const std::string& name, const std::string& server) {
  DaemonOptions options;
  options.server_address = server;
  options.sources = {{"playback", testing::SyntheticTakePath()}};
  options.control_address = "127.0.0.1:0";
  options.spool_dir = reenact::testing::MakeTempDir(name) + "/spool";
  options.daemon_id = "test-daemon";
  options.drain_timeout_s = 2.0;
  return options;
}

TEST(Daemon, OnceDeliversTheWholeTakeBitIdentical) {
  testing::FakeIngestServer server;
  ASSERT_TRUE(server.ok());
  server.service().set_kill_after_sets(6);  // One reconnect on the way.
  DaemonOptions options = BaseOptions("daemon_once", server.address());
  options.once = true;
  options.fast = true;
  options.stats_json = fs::path(options.spool_dir).parent_path().string() + "/stats.json";
  std::ostringstream log;
  options.log = &log;
  auto daemon = Daemon::Create(options);
  ASSERT_TRUE(daemon.ok()) << daemon.status();
  const absl::Status result = (*daemon)->Run();
  ASSERT_TRUE(result.ok()) << result << "\n" << log.str();

  const auto source = testing::ReadDepth(testing::SyntheticTakePath());
  const auto takes = server.service().takes();
  ASSERT_EQ(takes.size(), 1u);
  const testing::FakeTake& take = takes.begin()->second;
  EXPECT_TRUE(take.closed);
  EXPECT_EQ(take.open.daemon_id(), "test-daemon");
  EXPECT_EQ(take.open.sensors_size(), 2);
  std::set<std::string> lost_ids;
  for (const v1::SensorLost& lost : take.lost) lost_ids.insert(lost.sensor_id());
  // Both playback sensors end with the recording: that ends the take, and
  // neither counts as lost.
  EXPECT_TRUE(lost_ids.empty()) << *lost_ids.begin();
  const size_t frames = source.at("k0").size();
  ASSERT_EQ(take.sets.size(), frames) << "one set per instant";
  std::map<std::string, size_t> per_sensor;
  for (size_t i = 0; i < take.sets.size(); ++i) {
    const v1::FrameSet& set = take.sets[i];
    EXPECT_EQ(set.sequence(), i + 1);
    EXPECT_EQ(set.frames_size(), 2) << "set " << i + 1;
    for (const v1::Frame& f : set.frames()) {
      const auto& depth = source.at(f.sensor_id()).at(static_cast<size_t>(f.frame_index()));
      EXPECT_EQ(f.depth().data(), depth.data());
      ++per_sensor[f.sensor_id()];
    }
  }
  EXPECT_EQ(per_sensor["k0"], frames);
  EXPECT_EQ(per_sensor["k1"], frames);
  // The take's spool folder is gone once the server closed the take.
  EXPECT_TRUE(ingest::ListUnfinishedTakes(options.spool_dir).empty());

  auto stats_text = ReadFileToString(options.stats_json);
  ASSERT_TRUE(stats_text.ok()) << stats_text.status();
  const nlohmann::json stats = nlohmann::json::parse(*stats_text);
  std::cout << stats.dump(2) << "\n";
  EXPECT_EQ(stats["frame_sets"].get<int64_t>(), static_cast<int64_t>(frames));
  EXPECT_EQ(stats["frames_per_sensor"]["k0"].get<int64_t>(), static_cast<int64_t>(frames));
  EXPECT_EQ(stats["frames_dropped"].get<int64_t>(), 0);
  EXPECT_EQ(stats["reconnects"].get<int64_t>(), 1);
  EXPECT_EQ(stats["latency_ms"]["frame_sets"].get<int64_t>(), static_cast<int64_t>(frames));
  EXPECT_GT(stats["frame_set_bytes_mean"].get<double>(), 1000.0);
  EXPECT_GT(stats["cpu_s"].get<double>(), 0.0);
}

TEST(Daemon, ControlServiceStartsAndStopsTakes) {
  testing::FakeIngestServer server;
  ASSERT_TRUE(server.ok());
  DaemonOptions options = BaseOptions("daemon_control", server.address());
  options.loop = true;  // Real-time pacing, streaming until stopped.
  options.control_port_file = fs::path(options.spool_dir).parent_path().string() + "/control";
  auto daemon = Daemon::Create(options);
  ASSERT_TRUE(daemon.ok()) << daemon.status();
  absl::Status result;
  std::thread runner([&] { result = (*daemon)->Run(); });
  std::string address;
  for (int i = 0; i < 200 && address.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    address = ReadFileToString(options.control_port_file).value_or("");
  }
  ASSERT_FALSE(address.empty());
  address.pop_back();  // Newline.
  auto stub =
      v1::CaptureControl::NewStub(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));

  v1::ListSensorsResponse sensors;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->ListSensors(&context, {}, &sensors).ok());
  }
  EXPECT_EQ(sensors.sensors_size(), 2);
  {
    grpc::ClientContext context;
    v1::StopTakeResponse stopped;
    EXPECT_EQ(stub->StopTake(&context, {}, &stopped).error_code(),
              grpc::StatusCode::FAILED_PRECONDITION);
  }
  v1::StartTakeRequest start;
  start.set_name("kata-01");
  v1::StartTakeResponse started;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->StartTake(&context, start, &started).ok());
  }
  EXPECT_NE(started.take_id().find("kata-01"), std::string::npos) << started.take_id();
  {
    grpc::ClientContext context;
    v1::StartTakeResponse again;
    EXPECT_EQ(stub->StartTake(&context, start, &again).error_code(),
              grpc::StatusCode::FAILED_PRECONDITION);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  v1::DaemonStatus status;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->Status(&context, {}, &status).ok());
  }
  EXPECT_EQ(status.take_id(), started.take_id());
  EXPECT_EQ(status.daemon_id(), "test-daemon");
  EXPECT_GT(status.frame_sets(), 10);
  EXPECT_EQ(status.sync_size(), 2);
  EXPECT_TRUE(status.server_connected());
  v1::StopTakeResponse stopped;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->StopTake(&context, {}, &stopped).ok());
  }
  EXPECT_EQ(stopped.take_id(), started.take_id());
  EXPECT_GT(stopped.frame_set_count(), 10u);
  (*daemon)->RequestStop();
  runner.join();
  EXPECT_TRUE(result.ok()) << result;
  const auto takes = server.service().takes();
  ASSERT_EQ(takes.count(started.take_id()), 1u);
  const testing::FakeTake& take = takes.at(started.take_id());
  EXPECT_TRUE(take.closed);
  EXPECT_EQ(take.sets.size(), stopped.frame_set_count());
}

// The operator's view of a running daemon: health on the control port
// (no token needed), figures on --metrics over a real TCP connection, and
// one parseable JSON line per event.
TEST(Daemon, HealthMetricsAndJsonEvents) {
  testing::FakeIngestServer server;
  ASSERT_TRUE(server.ok());
  DaemonOptions options = BaseOptions("daemon_observability", server.address());
  options.loop = true;
  options.control_port_file = fs::path(options.spool_dir).parent_path().string() + "/control";
  options.metrics_address = "127.0.0.1:0";
  options.log_options = {log::Format::kJson, log::Level::kInfo};
  std::ostringstream log;
  options.log = &log;
  auto daemon = Daemon::Create(options);
  ASSERT_TRUE(daemon.ok()) << daemon.status();
  const std::string metrics_address = (*daemon)->metrics_address();
  ASSERT_FALSE(metrics_address.empty());
  const int metrics_port = std::stoi(metrics_address.substr(metrics_address.rfind(':') + 1));
  // The request counters are the process's: earlier tests' calls are in.
  const std::string start_take_ok =
      "reenact_rpc_requests_total{method=\"/reenact.v1.CaptureControl/StartTake\",code=\"OK\"}";
  auto before = metrics::testing::HttpRequest(metrics_port, "/metrics");
  ASSERT_TRUE(before.ok()) << before.status();
  auto samples_before = metrics::testing::ParseExposition(before->body);
  ASSERT_TRUE(samples_before.ok()) << samples_before.status() << "\n" << before->body;
  const double start_takes_before =
      samples_before->contains(start_take_ok) ? samples_before->at(start_take_ok) : 0;
  EXPECT_EQ(samples_before->at("reenactd_recording"), 0);
  absl::Status result;
  std::thread runner([&] { result = (*daemon)->Run(); });
  std::string address;
  for (int i = 0; i < 200 && address.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    address = ReadFileToString(options.control_port_file).value_or("");
  }
  ASSERT_FALSE(address.empty());
  address.pop_back();  // Newline.
  auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  auto health = grpc::health::v1::Health::NewStub(channel);
  for (const std::string name : {"", "reenact.v1.CaptureControl"}) {
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckRequest request;
    request.set_service(name);
    grpc::health::v1::HealthCheckResponse response;
    ASSERT_TRUE(health->Check(&context, request, &response).ok()) << name;
    EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING) << name;
  }
  auto control = v1::CaptureControl::NewStub(channel);
  v1::StartTakeRequest start;
  start.set_name("observed");
  v1::StartTakeResponse started;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(control->StartTake(&context, start, &started).ok());
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));

  auto answer = metrics::testing::HttpRequest(metrics_port, "/metrics");
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_EQ(answer->status, 200);
  auto samples = metrics::testing::ParseExposition(answer->body);
  ASSERT_TRUE(samples.ok()) << samples.status() << "\n" << answer->body;
  for (const char* sensor : {"k0", "k1"}) {
    const std::string labels = absl::StrCat("{sensor=\"", sensor, "\"}");
    EXPECT_GT(samples->at("reenactd_frames_captured_total" + labels), 5) << answer->body;
    EXPECT_EQ(samples->at("reenactd_sensor_up" + labels), 1);
    EXPECT_TRUE(samples->contains("reenactd_frames_dropped_total" + labels)) << answer->body;
  }
  EXPECT_EQ(samples->at("reenactd_recording"), 1);
  EXPECT_EQ(samples->at("reenactd_uplink_connected"), 1);
  EXPECT_GE(samples->at("reenactd_uplink_queue_bytes"), 0);
  EXPECT_EQ(samples->at(start_take_ok), start_takes_before + 1);
  EXPECT_GE(samples->at("reenact_rpc_requests_total{method=\"/grpc.health.v1.Health/Check\","
                        "code=\"OK\"}"),
            2);
  EXPECT_GT(samples->at("process_resident_memory_bytes"), 0);

  v1::StopTakeResponse stopped;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(control->StopTake(&context, {}, &stopped).ok());
  }
  // The stopped take becomes durable on the fake server; then shut down.
  for (int i = 0; i < 200; ++i) {
    const auto takes = server.service().takes();
    if (takes.count(started.take_id()) && takes.at(started.take_id()).closed) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // A tick notices it.
  (*daemon)->RequestStop();
  runner.join();
  EXPECT_TRUE(result.ok()) << result;
  {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(2));
    grpc::health::v1::HealthCheckResponse response;
    const grpc::Status after = health->Check(&context, {}, &response);
    // Stopped: NOT_SERVING, or the port is already closed.
    EXPECT_TRUE(!after.ok() ||
                response.status() == grpc::health::v1::HealthCheckResponse::NOT_SERVING);
  }

  std::map<std::string, std::vector<nlohmann::json>> events;
  std::istringstream lines(log.str());
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json event = nlohmann::json::parse(line, nullptr, false);
    ASSERT_TRUE(event.is_object()) << line;
    for (const char* key : {"ts", "level", "event", "msg"}) {
      EXPECT_TRUE(event.contains(key)) << key << " in " << line;
    }
    events[event["event"].get<std::string>()].push_back(event);
  }
  ASSERT_EQ(events["sensor_opened"].size(), 2u) << log.str();
  EXPECT_EQ(events["sensor_opened"][0]["backend"], "playback");
  ASSERT_EQ(events["metrics_listening"].size(), 1u) << log.str();
  EXPECT_EQ(events["metrics_listening"][0]["address"], metrics_address);
  ASSERT_EQ(events["control_listening"].size(), 1u) << log.str();
  ASSERT_EQ(events["take_started"].size(), 1u) << log.str();
  EXPECT_EQ(events["take_started"][0]["take_id"], started.take_id());
  EXPECT_EQ(events["take_started"][0]["sensors"], 2);
  ASSERT_EQ(events["take_stopped"].size(), 1u) << log.str();
  EXPECT_EQ(events["take_stopped"][0]["frame_sets"].get<uint64_t>(), stopped.frame_set_count());
  ASSERT_EQ(events["take_durable"].size(), 1u) << log.str();
  EXPECT_EQ(events["take_durable"][0]["take_id"], started.take_id());
}

TEST(Daemon, DrainTimeoutLeavesSpoolThenRestartDeliversIt) {
  int port = 0;
  {
    testing::FakeIngestServer probe;
    port = probe.port();
  }
  const std::string address = "127.0.0.1:" + std::to_string(port);
  DaemonOptions options = BaseOptions("daemon_drain", address);
  options.once = true;
  options.fast = true;
  options.drain_timeout_s = 0.5;
  std::ostringstream log;
  options.log = &log;
  auto daemon = Daemon::Create(options);
  ASSERT_TRUE(daemon.ok());
  absl::Status result;
  std::thread runner([&] { result = (*daemon)->Run(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  (*daemon)->RequestStop();
  runner.join();
  EXPECT_TRUE(absl::IsDeadlineExceeded(result)) << result;
  EXPECT_NE(result.message().find("stay in the spool"), std::string::npos) << result;
  const auto unfinished = ingest::ListUnfinishedTakes(options.spool_dir);
  ASSERT_EQ(unfinished.size(), 1u);
  daemon->reset();

  // The server is back; a new daemon on the same spool sends the take.
  testing::FakeIngestServer server(port);
  ASSERT_TRUE(server.ok());
  options.once = false;
  options.log = nullptr;
  auto second = Daemon::Create(options);
  ASSERT_TRUE(second.ok());
  std::thread second_runner([&] { result = (*second)->Run(); });
  for (int i = 0; i < 200; ++i) {
    const auto takes = server.service().takes();
    if (!takes.empty() && takes.begin()->second.closed &&
        ingest::ListUnfinishedTakes(options.spool_dir).empty()) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  (*second)->RequestStop();
  second_runner.join();
  const auto takes = server.service().takes();
  ASSERT_EQ(takes.size(), 1u);
  EXPECT_TRUE(takes.begin()->second.closed);
  EXPECT_EQ(takes.begin()->second.sets.size(),
            testing::ReadDepth(testing::SyntheticTakePath()).at("k0").size());
  EXPECT_TRUE(ingest::ListUnfinishedTakes(options.spool_dir).empty());
}

TEST(ReenactdFlags, ConfigFileAndFlagsMerge) {
  const std::string dir = reenact::testing::MakeTempDir("reenactd_flags");
  const std::string config = dir + "/reenactd.conf";
  std::ofstream(config)
      << R"({"server": "studio:50051", "source": ["playback:a.mcap", "freenect:all"],
                                "spool-max-mb": 64, "fast": true, "sync-tolerance-ms": 5})";
  auto options = ParseReenactdFlags({"--config", config, "--spool-max-mb", "128", "--spool", dir});
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->server_address, "studio:50051");
  EXPECT_EQ(options->sources.size(), 2u);
  EXPECT_EQ(options->spool_max_mb, 128) << "flags win";
  EXPECT_TRUE(options->fast);
  EXPECT_EQ(options->sync.tolerance_ns, 5'000'000);
  auto replaced = ParseReenactdFlags({"--config", config, "--source", "openni2", "--spool", dir});
  ASSERT_TRUE(replaced.ok());
  ASSERT_EQ(replaced->sources.size(), 1u);
  EXPECT_EQ(replaced->sources[0].backend, "openni2");

  EXPECT_TRUE(
      absl::IsInvalidArgument(ParseReenactdFlags({"--source", "playback:x", "--bogus"}).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(
      ParseReenactdFlags({"--source", "playback:x", "--segmentation", "maybe"}).status()));
  std::ofstream(config) << R"({"colour": 1})";
  EXPECT_TRUE(absl::IsInvalidArgument(ParseReenactdFlags({"--config", config}).status()));
  // --metrics: a HOST:PORT, on loopback unless --insecure; log flags checked.
  EXPECT_TRUE(absl::IsInvalidArgument(
      ParseReenactdFlags({"--source", "playback:x", "--spool", dir, "--metrics", "no-port"})
          .status()));
  EXPECT_TRUE(absl::IsFailedPrecondition(
      ParseReenactdFlags({"--source", "playback:x", "--spool", dir, "--metrics", "0.0.0.0:9100"})
          .status()));
  auto exposed =
      ParseReenactdFlags({"--source", "playback:x", "--spool", dir, "--metrics", "0.0.0.0:9100",
                          "--insecure", "--log-format", "json", "--log-level", "warn"});
  ASSERT_TRUE(exposed.ok()) << exposed.status();
  EXPECT_EQ(exposed->metrics_address, "0.0.0.0:9100");
  EXPECT_EQ(exposed->log_options.format, log::Format::kJson);
  EXPECT_EQ(exposed->log_options.level, log::Level::kWarn);
  EXPECT_TRUE(absl::IsInvalidArgument(
      ParseReenactdFlags({"--source", "playback:x", "--spool", dir, "--log-format", "xml"})
          .status()));
  std::ostringstream out;
  std::ostringstream err;
  EXPECT_EQ(RunReenactd({"--server", "x:1"}, out, err), kExitUsage);
  EXPECT_EQ(RunReenactd({"--source", "playback:/no/such.mcap", "--spool", dir, "--control", ""},
                        out, err),
            kExitFailure);
  EXPECT_NE(err.str().find("/no/such.mcap"), std::string::npos) << err.str();
}

}  // namespace
}  // namespace reenact::capture
