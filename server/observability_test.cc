// What an operator sees of a running reenact-server: the standard health
// service over real gRPC, the Prometheus endpoint scraped over a real TCP
// connection, and the structured log (--log-format json) of a child
// process, each checked against what the test did to the server.
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/metrics/testing/scrape.h"
#include "common/rpc/auth.h"
#include "common/rpc/channel.h"
#include "common/testing/test_data.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/server.h"
#include "server/server_flags.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using grpc::health::v1::Health;
using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;
using testing::IngestClient;
using testing::MakeFrameSet;
using testing::MakeOpenTake;
using testing::SensorIds;

// Every stderr line of the child as JSON, by event; fails the test on a
// line that is not a JSON object with ts, level, event and msg.
std::map<std::string, std::vector<nlohmann::json>> ParseEvents(const std::string& text) {
  std::map<std::string, std::vector<nlohmann::json>> events;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    const nlohmann::json event = nlohmann::json::parse(line, nullptr, false);
    EXPECT_TRUE(event.is_object()) << "not a JSON line: " << line;
    if (!event.is_object()) continue;
    for (const char* key : {"ts", "level", "event", "msg"}) {
      EXPECT_TRUE(event.contains(key)) << key << " missing in " << line;
    }
    if (event.contains("event")) events[event["event"].get<std::string>()].push_back(event);
  }
  return events;
}

grpc::Status CheckHealth(Health::Stub& stub, const std::string& service,
                         HealthCheckResponse* response) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  HealthCheckRequest request;
  request.set_service(service);
  return stub.Check(&context, request, response);
}

// A reenact-server child with tokens, a metrics port and JSON logs; the
// test's calls go through real sockets with an admin token.
class ObservedServer : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = reenact::testing::MakeTempDir("server_observability");
    const std::string tokens = dir_ + "/tokens.json";
    auto token = rpc::AddToken(tokens, rpc::Role::kAdmin, "operator");
    ASSERT_TRUE(token.ok()) << token.status();
    token_ = *token;
    SubprocessOptions options;
    options.stderr_path = dir_ + "/stderr.jsonl";
    const std::string port_file = dir_ + "/port";
    auto process = Subprocess::Start(
        {REENACT_SERVER_BINARY, "--data", dir_ + "/data", "--listen", "127.0.0.1:0", "--port-file",
         port_file, "--metrics", "127.0.0.1:0", "--log-format", "json", "--auth", tokens, "--jobs",
         "1", "--worker", REENACT_FAKE_WORKER, "--max-name-bytes", "40"},
        options);
    ASSERT_TRUE(process.ok()) << process.status();
    child_ = std::move(*process);
    for (int i = 0; i < 1000 && !fs::exists(port_file); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    auto address = ReadFileToString(port_file);
    ASSERT_TRUE(address.ok()) << "no port file; stderr: " << Stderr();
    address_ = address->substr(0, address->size() - 1);
    // The metrics address is in the server_listening event.
    const auto events = ParseEvents(Stderr());
    ASSERT_EQ(events.count("server_listening"), 1u) << Stderr();
    const nlohmann::json& listening = events.at("server_listening").front();
    EXPECT_EQ(listening["address"], address_);
    EXPECT_EQ(listening["auth"], true);
    const std::string metrics = listening["metrics_address"].get<std::string>();
    metrics_port_ = std::stoi(metrics.substr(metrics.rfind(':') + 1));
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    channel_ = rpc::MakeClientChannel(address_, args, rpc::ClientSecurity{.token = token_});
    anonymous_ = grpc::CreateChannel(address_, grpc::InsecureChannelCredentials());
  }

  void TearDown() override {
    if (child_ != nullptr && !stopped_) {
      (void)child_->Signal(SIGKILL);
      (void)child_->Wait(20);
    }
  }

  std::string Stderr() const { return ReadFileToString(dir_ + "/stderr.jsonl").value_or(""); }

  std::map<std::string, double> Scrape() {
    auto answer = metrics::testing::HttpRequest(metrics_port_, "/metrics");
    EXPECT_TRUE(answer.ok()) << answer.status();
    if (!answer.ok()) return {};
    EXPECT_EQ(answer->status, 200);
    EXPECT_EQ(answer->headers["content-type"], "text/plain; version=0.0.4; charset=utf-8");
    auto samples = metrics::testing::ParseExposition(answer->body);
    EXPECT_TRUE(samples.ok()) << samples.status() << "\n" << answer->body;
    return samples.ok() ? *samples : std::map<std::string, double>{};
  }

  // SIGTERM, and the exit code.
  int Stop() {
    stopped_ = true;
    EXPECT_TRUE(child_->Signal(SIGTERM).ok());
    auto exit = child_->Wait(30);
    EXPECT_TRUE(exit.ok()) << exit.status();
    return exit.ok() ? exit->exit_code : -1;
  }

  std::string dir_;
  std::string token_;
  std::unique_ptr<Subprocess> child_;
  bool stopped_ = false;
  std::string address_;
  int metrics_port_ = 0;
  std::shared_ptr<grpc::Channel> channel_;
  std::shared_ptr<grpc::Channel> anonymous_;
};

TEST_F(ObservedServer, HealthMetricsAndJsonLogsTellWhatHappened) {
  // Health: no token needed, even on a server that asks every other call
  // for one.
  auto health = Health::NewStub(anonymous_);
  HealthCheckResponse response;
  for (const char* service : {"", "reenact.v1.Ingest", "reenact.v1.Takes", "reenact.v1.Jobs",
                              "reenact.v1.Reenactments"}) {
    ASSERT_TRUE(CheckHealth(*health, service, &response).ok()) << service;
    EXPECT_EQ(response.status(), HealthCheckResponse::SERVING) << service;
  }
  EXPECT_EQ(CheckHealth(*health, "reenact.v1.Nothing", &response).error_code(),
            grpc::StatusCode::NOT_FOUND);

  // Refusals: a call without a token, and a name over --max-name-bytes.
  {
    auto takes = v1::Takes::NewStub(anonymous_);
    grpc::ClientContext context;
    v1::ListTakesResponse listed;
    EXPECT_EQ(takes->List(&context, {}, &listed).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }
  auto ingest = v1::Ingest::NewStub(channel_);
  {
    IngestClient client(*ingest);
    v1::OpenTake open = MakeOpenTake("long-name", "daemon-a", 1);
    open.mutable_info()->set_name(std::string(41, 'n'));
    client.Open(open);
    EXPECT_EQ(client.Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }

  // A take of kSets frame sets from two sensors.
  constexpr uint64_t kSets = 12;
  double sent_bytes = 0;
  {
    IngestClient client(*ingest);
    client.Open(MakeOpenTake("observed", "daemon-a", 2));
    for (uint64_t s = 1; s <= kSets; ++s) {
      const v1::FrameSet set = MakeFrameSet(s, SensorIds(2));
      sent_bytes += static_cast<double>(set.ByteSizeLong());
      ASSERT_TRUE(client.SendSet(set));
    }
    ASSERT_TRUE(client.WaitAck(kSets));
    // While it records, the gauge shows it.
    EXPECT_EQ(Scrape().at("reenact_takes_open"), 1);
    client.Close(kSets);
    ASSERT_TRUE(client.Finish().ok());
  }

  // A job on it, through the fake worker, to its end.
  auto jobs = v1::Jobs::NewStub(channel_);
  v1::Job job;
  {
    grpc::ClientContext context;
    v1::SubmitJobRequest request;
    request.set_take_id("observed");
    request.set_method("rigid-carved");
    ASSERT_TRUE(jobs->Submit(&context, request, &job).ok());
  }
  for (int i = 0;
       i < 300 && job.state() != v1::JOB_STATE_SUCCEEDED && job.state() != v1::JOB_STATE_FAILED;
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    grpc::ClientContext context;
    v1::GetJobRequest request;
    request.set_job_id(job.job_id());
    ASSERT_TRUE(jobs->Get(&context, request, &job).ok());
  }
  ASSERT_EQ(job.state(), v1::JOB_STATE_SUCCEEDED) << job.error();

  // A method no service has: UNIMPLEMENTED that says so.
  {
    grpc::GenericStub stub(channel_);
    grpc::ClientContext context;
    grpc::CompletionQueue queue;
    auto call =
        stub.PrepareUnaryCall(&context, "/reenact.v1.Nothing/Here", grpc::ByteBuffer(), &queue);
    call->StartCall();
    grpc::ByteBuffer response;
    grpc::Status status;
    call->Finish(&response, &status, &queue);
    void* tag = nullptr;
    bool ok = false;
    ASSERT_TRUE(queue.Next(&tag, &ok));
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNIMPLEMENTED);
    EXPECT_NE(status.error_message().find("no such method on this server"), std::string::npos)
        << status.error_message();
    queue.Shutdown();
    while (queue.Next(&tag, &ok)) {
    }
  }

  const std::map<std::string, double> samples = Scrape();
  // Latency histograms: one Submit timed, one job run and waited for.
  EXPECT_EQ(samples.at("reenact_rpc_duration_seconds_count{method=\"/reenact.v1.Jobs/Submit\"}"),
            1);
  EXPECT_EQ(samples.at("reenact_rpc_duration_seconds_bucket{method=\"/reenact.v1.Jobs/Submit\","
                       "le=\"+Inf\"}"),
            1);
  EXPECT_GT(samples.at("reenact_rpc_duration_seconds_sum{method=\"/reenact.v1.Jobs/Submit\"}"),
            0.0);
  EXPECT_EQ(samples.at("reenact_rpc_requests_total{method=\"other\",code=\"UNIMPLEMENTED\"}"), 1);
  EXPECT_EQ(samples.at("reenact_job_duration_seconds_count{method=\"rigid-carved\","
                       "outcome=\"succeeded\"}"),
            1);
  EXPECT_EQ(samples.at("reenact_job_wait_seconds_count{method=\"rigid-carved\"}"), 1);
  EXPECT_GT(samples.at("process_cpu_seconds_total"), 0.0);
  EXPECT_GT(samples.at("process_open_fds"), 3);
  EXPECT_EQ(samples.count("reenact_build_info{version=\"" REENACT_VERSION "\"}"), 1u);
  EXPECT_EQ(samples.at("reenact_ingest_frame_sets_total"), kSets);
  EXPECT_EQ(samples.at("reenact_ingest_bytes_total"), sent_bytes);
  EXPECT_EQ(samples.at("reenact_takes_open"), 0);
  EXPECT_EQ(samples.at("reenact_limit_refusals_total{limit=\"name_bytes\"}"), 1);
  EXPECT_EQ(samples.at("reenact_limit_refusals_total{limit=\"frame_set\"}"), 0);
  EXPECT_EQ(samples.at("reenact_auth_refusals_total{reason=\"no_token\"}"), 1);
  EXPECT_EQ(samples.at("reenact_auth_refusals_total{reason=\"unknown_token\"}"), 0);
  EXPECT_EQ(samples.at("reenact_jobs{state=\"succeeded\"}"), 1);
  EXPECT_EQ(samples.at("reenact_jobs{state=\"queued\"}"), 0);
  EXPECT_EQ(samples.at("reenact_job_queue_length"), 0);
  EXPECT_EQ(samples.at("reenact_serving"), 1);
  EXPECT_EQ(
      samples.at("reenact_rpc_requests_total{method=\"/reenact.v1.Ingest/Ingest\",code=\"OK\"}"),
      1);
  EXPECT_EQ(samples.at("reenact_rpc_requests_total{method=\"/reenact.v1.Ingest/Ingest\","
                       "code=\"INVALID_ARGUMENT\"}"),
            1);
  EXPECT_EQ(samples.at("reenact_rpc_requests_total{method=\"/reenact.v1.Takes/List\","
                       "code=\"UNAUTHENTICATED\"}"),
            1);
  EXPECT_EQ(samples.at("reenact_rpc_requests_total{method=\"/grpc.health.v1.Health/Check\","
                       "code=\"OK\"}"),
            5);
  EXPECT_EQ(samples.at("reenact_rpc_requests_total{method=\"/grpc.health.v1.Health/Check\","
                       "code=\"NOT_FOUND\"}"),
            1);
  EXPECT_EQ(
      samples.at("reenact_rpc_requests_total{method=\"/reenact.v1.Jobs/Submit\",code=\"OK\"}"), 1);
  EXPECT_GT(samples.at("reenact_data_disk_free_bytes"), 0);
  EXPECT_GT(samples.at("process_resident_memory_bytes"), 1 << 20);

  EXPECT_EQ(Stop(), 0) << Stderr();
  const std::string log = Stderr();
  auto events = ParseEvents(log);
  ASSERT_EQ(events["take_opened"].size(), 1u) << log;
  const nlohmann::json& opened = events["take_opened"][0];
  EXPECT_EQ(opened["level"], "info");
  EXPECT_EQ(opened["take_id"], "observed");
  EXPECT_EQ(opened["daemon_id"], "daemon-a");
  EXPECT_EQ(opened["owner"], "operator");
  EXPECT_EQ(opened["sensors"], 2);
  EXPECT_EQ(opened["resumed"], false);
  ASSERT_EQ(events["take_closed"].size(), 1u) << log;
  const nlohmann::json& closed = events["take_closed"][0];
  EXPECT_EQ(closed["take_id"], "observed");
  EXPECT_EQ(closed["state"], "complete");
  EXPECT_EQ(closed["frame_sets"], kSets);
  EXPECT_GT(closed["bytes"].get<int64_t>(), 0);
  ASSERT_EQ(events["limit_hit"].size(), 1u) << log;
  EXPECT_EQ(events["limit_hit"][0]["limit"], "name_bytes");
  EXPECT_EQ(events["limit_hit"][0]["take_id"], "long-name");
  EXPECT_EQ(events["limit_hit"][0]["level"], "warn");
  ASSERT_EQ(events["auth_refused"].size(), 1u) << log;
  const nlohmann::json& refused = events["auth_refused"][0];
  EXPECT_EQ(refused["rpc"], "/reenact.v1.Takes/List");
  EXPECT_EQ(refused["reason"], "no_token");
  EXPECT_EQ(refused["status"], "UNAUTHENTICATED");
  EXPECT_NE(refused["peer"].get<std::string>().find("127.0.0.1"), std::string::npos);
  for (const char* event : {"job_queued", "job_started", "job_finished"}) {
    ASSERT_EQ(events[event].size(), 1u) << event << "\n" << log;
    EXPECT_EQ(events[event][0]["job_id"], job.job_id()) << event;
    EXPECT_EQ(events[event][0]["take_id"], "observed") << event;
    EXPECT_EQ(events[event][0]["method"], "rigid-carved") << event;
  }
  EXPECT_EQ(events["job_finished"][0]["reenactment_id"], job.reenactment_id());
  EXPECT_EQ(events["server_stopping"].size(), 1u) << log;
  EXPECT_EQ(events["server_stopped"].size(), 1u) << log;
  EXPECT_EQ(log.find(token_), std::string::npos);  // Never the token.
}

// In-process server on a real port: the disk-full setter and the drain at
// shutdown turn health to NOT_SERVING, and a Watch hears both.
TEST(ServerHealth, NotServingWhileTheDiskIsFullAndWhileDraining) {
  const std::string dir = reenact::testing::MakeTempDir("server_health");
  ServerOptions options;
  options.data_dir = dir + "/data";
  options.listen_address = "127.0.0.1:0";
  options.metrics_address = "127.0.0.1:0";
  auto server = Server::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto channel = grpc::CreateChannel((*server)->address(), grpc::InsecureChannelCredentials());
  auto health = Health::NewStub(channel);
  const std::string& metrics = (*server)->metrics_address();
  const int metrics_port = std::stoi(metrics.substr(metrics.rfind(':') + 1));
  auto serving = [&](const metrics::testing::HttpAnswer& answer) {
    auto samples = metrics::testing::ParseExposition(answer.body);
    EXPECT_TRUE(samples.ok()) << samples.status();
    return samples.ok() ? samples->at("reenact_serving") : -1.0;
  };

  grpc::ClientContext watch_context;
  auto watch = health->Watch(&watch_context, HealthCheckRequest());
  HealthCheckResponse watched;
  ASSERT_TRUE(watch->Read(&watched));
  EXPECT_EQ(watched.status(), HealthCheckResponse::SERVING);

  (*server)->SetDiskFull(true);
  HealthCheckResponse response;
  ASSERT_TRUE(CheckHealth(*health, "", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  ASSERT_TRUE(CheckHealth(*health, "reenact.v1.Ingest", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
  ASSERT_TRUE(watch->Read(&watched));
  EXPECT_EQ(watched.status(), HealthCheckResponse::NOT_SERVING);
  auto scraped = metrics::testing::HttpRequest(metrics_port, "/metrics");
  ASSERT_TRUE(scraped.ok()) << scraped.status();
  EXPECT_EQ(serving(*scraped), 0);

  (*server)->SetDiskFull(false);
  ASSERT_TRUE(CheckHealth(*health, "", &response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::SERVING);
  ASSERT_TRUE(watch->Read(&watched));
  EXPECT_EQ(watched.status(), HealthCheckResponse::SERVING);

  // Shutdown: the watch hears NOT_SERVING, then ends.
  std::thread stopper([&] { (*server)->Shutdown(); });
  ASSERT_TRUE(watch->Read(&watched));
  EXPECT_EQ(watched.status(), HealthCheckResponse::NOT_SERVING);
  EXPECT_FALSE(watch->Read(&watched));
  EXPECT_EQ(watch->Finish().error_code(), grpc::StatusCode::UNAVAILABLE);
  stopper.join();
  EXPECT_EQ((*server)->health().StatusFor(""), HealthCheckResponse::NOT_SERVING);
  EXPECT_FALSE(metrics::testing::HttpRequest(metrics_port, "/metrics").ok());  // Closed.
}

TEST(ServerFlags, MetricsAndLogFlagsParse) {
  auto parsed =
      ParseServerCommandLine({"--data", "/d", "--listen", "127.0.0.1:0", "--metrics",
                              "127.0.0.1:9464", "--log-format", "json", "--log-level", "debug"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.metrics_address, "127.0.0.1:9464");
  EXPECT_EQ(parsed->log.format, log::Format::kJson);
  EXPECT_EQ(parsed->log.level, log::Level::kDebug);
  auto defaults = ParseServerCommandLine({"--data", "/d", "--listen", "127.0.0.1:0"});
  ASSERT_TRUE(defaults.ok()) << defaults.status();
  EXPECT_TRUE(defaults->options.metrics_address.empty());  // Off unless asked for.
  EXPECT_EQ(defaults->log.format, log::Format::kText);
  EXPECT_EQ(defaults->log.level, log::Level::kInfo);
  for (const std::vector<std::string>& bad : std::vector<std::vector<std::string>>{
           {"--log-format", "xml"}, {"--log-level", "verbose"}, {"--metrics", "0.0.0.0:9464"}}) {
    std::vector<std::string> args = {"--data", "/d", "--listen", "127.0.0.1:0"};
    args.insert(args.end(), bad.begin(), bad.end());
    EXPECT_FALSE(ParseServerCommandLine(args).ok()) << bad[0];
  }
}

TEST(ServerHealth, MetricsOffTheLoopbackNeedInsecure) {
  ServerOptions options;
  options.data_dir = "/tmp/unused";
  options.listen_address = "127.0.0.1:0";
  options.metrics_address = "0.0.0.0:9100";
  EXPECT_TRUE(absl::IsFailedPrecondition(options.Validate())) << options.Validate();
  options.insecure = true;
  EXPECT_TRUE(options.Validate().ok()) << options.Validate();
  options.metrics_address = "no-port";
  EXPECT_TRUE(absl::IsInvalidArgument(options.Validate())) << options.Validate();
}

}  // namespace
}  // namespace reenact::server
