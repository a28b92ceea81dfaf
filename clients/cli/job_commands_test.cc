// `reenact jobs ...` against a fake Jobs service on 127.0.0.1:0: flags,
// options, progress bar, JSON output and exit codes.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/commands.h"
#include "clients/cli/remote_flags.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"

namespace reenact::cli {
namespace {

// Jobs of take "good" succeed, of "bad" fail, "missing" is unknown.
class FakeJobs final : public v1::Jobs::Service {
 public:
  grpc::Status Submit(grpc::ServerContext*, const v1::SubmitJobRequest* request,
                      v1::Job* job) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (request->take_id() == "missing") {
      return grpc::Status(grpc::StatusCode::NOT_FOUND, "no take \"missing\"");
    }
    if (request->method() != "rigid-carved" && request->method() != "rigid-cylinders" &&
        request->method() != "body") {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "unknown method");
    }
    last_submit = *request;
    job->set_job_id("j-" + request->take_id());
    job->set_take_id(request->take_id());
    job->set_method(request->method());
    *job->mutable_options() = request->options();
    job->set_state(v1::JOB_STATE_QUEUED);
    return grpc::Status::OK;
  }
  grpc::Status Watch(grpc::ServerContext*, const v1::WatchJobRequest* request,
                     grpc::ServerWriter<v1::JobEvent>* writer) override {
    const std::string take = request->job_id().substr(2);
    v1::JobEvent event;
    v1::Job* job = event.mutable_job();
    job->set_job_id(request->job_id());
    job->set_take_id(take);
    job->set_state(v1::JOB_STATE_QUEUED);
    writer->Write(event);
    job->set_state(v1::JOB_STATE_RUNNING);
    job->set_started_unix_ns(1'000'000'000);
    for (int i = 1; i <= 4; ++i) {
      v1::JobProgress* p = job->mutable_progress();
      p->set_stage(i <= 2 ? "load" : "register");
      p->set_fraction(0.25 * i);
      p->set_frames_done(30 * i);
      p->set_frames_total(120);
      p->set_eta_s(4.0 - i);
      event.clear_log_lines();
      event.add_log_lines("step " + std::to_string(i));
      writer->Write(event);
    }
    event.clear_log_lines();
    job->set_finished_unix_ns(3'500'000'000);
    if (take == "good") {
      job->set_state(v1::JOB_STATE_SUCCEEDED);
      job->set_reenactment_id("r-20260101-000000-abcd");
    } else {
      job->set_state(v1::JOB_STATE_FAILED);
      // The last log line is the worker's, whatever it printed.
      job->set_error("worker killed by signal 11 (SIGSEGV); last log: boom\x1b[2J\x1b]0;pwned\x07");
    }
    writer->Write(event);
    return grpc::Status::OK;
  }
  grpc::Status Cancel(grpc::ServerContext*, const v1::CancelJobRequest* request,
                      v1::Job* job) override {
    job->set_job_id(request->job_id());
    job->set_state(v1::JOB_STATE_CANCELLED);
    job->set_error("cancelled by a client");
    return grpc::Status::OK;
  }
  grpc::Status List(grpc::ServerContext*, const v1::ListJobsRequest* request,
                    v1::ListJobsResponse* response) override {
    std::lock_guard<std::mutex> lock(mu_);
    last_list = *request;
    v1::Job* job = response->add_jobs();
    job->set_job_id("j-good");
    job->set_take_id("good");
    job->set_method("rigid-carved");
    job->set_state(v1::JOB_STATE_SUCCEEDED);
    job->mutable_progress()->set_fraction(1.0);
    job->set_reenactment_id("r-1");
    return grpc::Status::OK;
  }
  grpc::Status Get(grpc::ServerContext*, const v1::GetJobRequest* request, v1::Job* job) override {
    if (request->job_id() == "j-fit" || request->job_id() == "j-gone") {
      job->set_job_id(request->job_id());
      job->set_method("body");
      job->set_state(v1::JOB_STATE_SUCCEEDED);
      job->set_reenactment_id(request->job_id() == "j-fit" ? "r-fit" : "r-gone");
      return grpc::Status::OK;
    }
    if (request->job_id() != "j-good") return grpc::Status(grpc::StatusCode::NOT_FOUND, "no job");
    job->set_job_id("j-good");
    job->set_state(v1::JOB_STATE_RUNNING);
    job->mutable_progress()->set_stage("register");
    job->mutable_progress()->set_fraction(0.5);
    job->mutable_progress()->set_eta_s(65);
    return grpc::Status::OK;
  }

  std::mutex mu_;
  v1::SubmitJobRequest last_submit;
  v1::ListJobsRequest last_list;
};

// One body-model reenactment, "r-fit", with its fit diagnosis: two
// sensors, two doubtful spans (one reason with terminal escapes).
class FakeReenactments final : public v1::Reenactments::Service {
 public:
  grpc::Status Get(grpc::ServerContext*, const v1::GetReenactmentRequest* request,
                   v1::ReenactmentSummary* summary) override {
    if (request->reenactment_id() != "r-fit") {
      return grpc::Status(grpc::StatusCode::NOT_FOUND, "no reenactment");
    }
    v1::ReenactmentInfo* info = summary->mutable_info();
    info->set_reenactment_id("r-fit");
    info->set_method("body");
    info->add_sensors()->set_sensor_id("front");
    info->add_sensors()->set_sensor_id("back");
    auto& figures = *info->mutable_figures();
    figures["sensor.front.explained_fraction"] = 0.973;
    figures["sensor.front.rms_mm"] = 4.24;
    figures["sensor.front.surface_seen_fraction"] = 0.912;
    figures["sensor.back.explained_fraction"] = 0.801;
    figures["sensor.back.rms_mm"] = 7.5;
    figures["sensor.back.surface_seen_fraction"] = 0.55;
    figures["doubtful_frames"] = 5;
    v1::DoubtfulSpan* span = info->add_doubtful_spans();
    span->set_first_frame(18);
    span->set_last_frame(21);
    span->set_start_s(1.2);
    span->set_end_s(1.4);
    span->set_reason("the fit explains 41 % of sensor back's points");
    span = info->add_doubtful_spans();
    span->set_first_frame(40);
    span->set_last_frame(40);
    span->set_start_s(2.667);
    span->set_end_s(2.667);
    span->set_reason("no fit\x1b[2J");
    return grpc::Status::OK;
  }
};

class JobCommands : public ::testing::Test {
 protected:
  void SetUp() override {
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(&service_);
    builder.RegisterService(&reenactments_);
    server_ = builder.BuildAndStart();
    ASSERT_NE(server_, nullptr);
    address_ = "127.0.0.1:" + std::to_string(port);
  }
  void TearDown() override { server_->Shutdown(); }

  int Run(const std::vector<std::string>& argv) {
    out_.str("");
    err_.str("");
    std::vector<std::string> args = argv;
    args.insert(args.begin() + 2, {"--server", address_});
    return Dispatch(args, out_, err_);
  }

  FakeJobs service_;
  FakeReenactments reenactments_;
  std::unique_ptr<grpc::Server> server_;
  std::string address_;
  std::ostringstream out_, err_;
};

// `reenact auth --help` lists the group's commands; a group alone or with an
// unknown command is a usage error that lists them too.
TEST(Dispatch, AGroupWithoutItsCommandListsTheGroup) {
  std::ostringstream out, err;
  EXPECT_EQ(Dispatch({"auth", "--help"}, out, err), kExitOk);
  EXPECT_NE(out.str().find("auth add"), std::string::npos) << out.str();
  EXPECT_EQ(out.str().find("jobs submit"), std::string::npos) << "only the group's commands";
  std::ostringstream out2, err2;
  EXPECT_EQ(Dispatch({"takes"}, out2, err2), kExitUsage);
  EXPECT_NE(err2.str().find("takes upload"), std::string::npos) << err2.str();
  std::ostringstream out3, err3;
  EXPECT_EQ(Dispatch({"takes", "frobnicate"}, out3, err3), kExitUsage);
  EXPECT_NE(err3.str().find("unknown command 'takes frobnicate'"), std::string::npos) << err3.str();
  std::ostringstream out4, err4;
  EXPECT_EQ(Dispatch({"nothing"}, out4, err4), kExitUsage);
  EXPECT_NE(err4.str().find("unknown command 'nothing'"), std::string::npos);
}

// `reenact help`: commands under headings, each with the first clause of its
// summary (folded under 100 characters), and the next step at the end.
TEST(Dispatch, HelpGroupsTheCommandsUnderHeadings) {
  std::ostringstream out, err;
  ASSERT_EQ(Dispatch({"help"}, out, err), kExitOk);
  const std::string help = out.str();
  for (const char* heading :
       {"Record with a reenactd beside the sensors:", "Takes on this machine:",
        "A reenact-server: takes, jobs and reenactments:", "Skeleton tracking:"}) {
    EXPECT_NE(help.find(heading), std::string::npos) << heading;
  }
  for (const Command& c : AllCommands()) {
    std::string name;
    for (const auto& p : c.path) name += (name.empty() ? "" : " ") + p;
    EXPECT_NE(help.find("\n  " + name + " "), std::string::npos) << name;
  }
  size_t longest = 0;
  std::istringstream lines(help);
  for (std::string line; std::getline(lines, line);) longest = std::max(longest, line.size());
  EXPECT_LE(longest, 100u) << help;
  EXPECT_NE(help.find("--help: what it does, its arguments and flags"), std::string::npos);
  std::printf("reenact help: %zu lines, the longest %zu characters\n",
              static_cast<size_t>(std::count(help.begin(), help.end(), '\n')), longest);
  std::ostringstream group, group_err;
  ASSERT_EQ(Dispatch({"help", "jobs"}, group, group_err), kExitOk);
  EXPECT_NE(group.str().find("jobs submit"), std::string::npos);
  EXPECT_EQ(group.str().find("takes upload"), std::string::npos) << "only the group's commands";
}

TEST(Dispatch, VersionPrintsTheProjectVersion) {
  for (const char* flag : {"--version", "version"}) {
    std::ostringstream out, err;
    EXPECT_EQ(Dispatch({flag}, out, err), kExitOk);
    EXPECT_EQ(out.str(), std::string("reenact ") + REENACT_VERSION + "\n");
  }
}

// A mistyped command or flag names the nearest one.
TEST(Dispatch, AMistypedCommandOrFlagSuggestsTheNearest) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"jobs", "sumbit"}, "did you mean 'reenact jobs submit'?"},
      {{"reenactment", "list"}, "did you mean 'reenact reenactments list'?"},
      {{"exprot", "--out", "x"}, "did you mean 'reenact export'?"},
      {{"jobs", "list", "--sever", "127.0.0.1:1"}, "unknown flag --sever (did you mean --server?)"},
  };
  for (const auto& [args, says] : cases) {
    std::ostringstream out, err;
    EXPECT_EQ(Dispatch(args, out, err), kExitUsage) << args[0];
    EXPECT_NE(err.str().find(says), std::string::npos) << err.str();
  }
  std::ostringstream out, err;
  EXPECT_EQ(Dispatch({"frobnicate"}, out, err), kExitUsage);
  EXPECT_EQ(err.str().find("did you mean"), std::string::npos) << "no near command";
}

// A server that is not there, an address without a port, and REENACT_SERVER.
TEST(RemoteErrors, AnUnreachableServerSaysWhatToTryNext) {
  {
    std::ostringstream out, err;
    EXPECT_EQ(Dispatch({"jobs", "list", "--server", "127.0.0.1:1", "--timeout", "5"}, out, err),
              kExitFailure);
    EXPECT_NE(err.str().find("UNAVAILABLE"), std::string::npos) << err.str();
    EXPECT_NE(err.str().find("hint: nothing answers there: is reenact-server running"),
              std::string::npos)
        << err.str();
  }
  for (const std::string address : {"localhost", "localhost:", ":50051", "localhost:0",
                                    "localhost:99999", "::1:50051", "[]:50051", "[::1:50051"}) {
    std::ostringstream out, err;
    EXPECT_EQ(Dispatch({"jobs", "list", "--server", address}, out, err), kExitUsage) << address;
    EXPECT_NE(err.str().find("give HOST:PORT, e.g. 127.0.0.1:50051"), std::string::npos)
        << err.str();
  }
  ASSERT_EQ(::setenv("REENACT_SERVER", "127.0.0.1:1", 1), 0);
  std::ostringstream out, err;
  EXPECT_EQ(Dispatch({"jobs", "list", "--timeout", "5"}, out, err), kExitFailure);
  EXPECT_NE(err.str().find("127.0.0.1:1"), std::string::npos) << err.str();
  ::setenv("REENACT_SERVER", "no-port", 1);
  std::ostringstream out2, err2;
  EXPECT_EQ(Dispatch({"jobs", "list"}, out2, err2), kExitUsage);
  EXPECT_NE(err2.str().find("--server \"no-port\" is not HOST:PORT: no port"), std::string::npos)
      << err2.str();
  ::unsetenv("REENACT_SERVER");
}

// A port that speaks something other than gRPC (the server's --http port,
// say): every connection gets an HTTP error and is closed.
class NotGrpcListener {
 public:
  NotGrpcListener() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof(address);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&address), size) != 0 ||
        ::listen(fd_, 8) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
      return;
    }
    port_ = ntohs(address.sin_port);
    thread_ = std::thread([this] {
      for (;;) {
        const int client = ::accept(fd_, nullptr, nullptr);
        if (client < 0) return;
        constexpr char kReply[] = "HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n";
        (void)!::write(client, kReply, sizeof(kReply) - 1);
        ::close(client);
      }
    });
  }
  ~NotGrpcListener() {
    ::shutdown(fd_, SHUT_RDWR);
    ::close(fd_);
    if (thread_.joinable()) thread_.join();
  }
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
  std::thread thread_;
};

TEST(RemoteErrors, APortThatIsNotGrpcSaysWhichPortToUse) {
  NotGrpcListener http;
  ASSERT_NE(http.port(), 0);
  std::ostringstream out, err;
  EXPECT_EQ(Dispatch({"jobs", "list", "--server", "127.0.0.1:" + std::to_string(http.port()),
                      "--timeout", "5"},
                     out, err),
            kExitFailure);
  EXPECT_NE(err.str().find("UNAVAILABLE"), std::string::npos) << err.str();
  EXPECT_NE(err.str().find("hint: something answered there but not in gRPC"), std::string::npos)
      << err.str();
}

TEST(RemoteErrors, EachKindOfFailureHasItsOwnHint) {
  // Messages as gRPC writes them; the hint follows the code first.
  const std::vector<std::pair<absl::Status, std::string>> cases = {
      {absl::UnavailableError("DNS resolution failed for nowhere.invalid:50051: C-ares status "
                              "is not ARES_SUCCESS qtype=A name=nowhere.invalid: Domain name "
                              "not found"),
       "the host name does not resolve"},
      {absl::UnavailableError("failed to connect to all addresses; last error: UNKNOWN: "
                              "ipv4:127.0.0.1:1: Failed to connect to remote host: Connection "
                              "refused"),
       "nothing answers there"},
      {absl::DeadlineExceededError("Deadline Exceeded"), "no answer within --timeout"},
      {absl::UnauthenticatedError("a token is required"), "this server wants a token"},
      {absl::PermissionDeniedError("role viewer may not submit jobs"),
       "your token's role may not do this"},
  };
  for (const auto& [status, hint] : cases) {
    std::ostringstream err;
    EXPECT_EQ(ReportRemoteError(status, err), kExitFailure);
    EXPECT_NE(err.str().find("hint: " + hint), std::string::npos) << err.str();
    EXPECT_EQ(err.str().rfind("reenact: " + absl::StatusCodeToString(status.code()) + ": ", 0), 0u)
        << err.str();
  }
  // A precise answer from the server needs no hint.
  std::ostringstream err;
  ReportRemoteError(absl::NotFoundError("no job 7"), err);
  EXPECT_EQ(err.str(), "reenact: NOT_FOUND: no job 7\n");
}

TEST_F(JobCommands, SubmitWaitJsonPrintsTheJobAndTheReenactment) {
  ASSERT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "rigid-carved", "--option",
                 "voxel_mm=8", "--option=mu_mm=20", "--option", "note=a=b", "--wait", "--json"}),
            kExitOk)
      << err_.str();
  EXPECT_EQ(service_.last_submit.options().at("voxel_mm"), "8");
  EXPECT_EQ(service_.last_submit.options().at("mu_mm"), "20");
  EXPECT_EQ(service_.last_submit.options().at("note"), "a=b");
  const auto result = nlohmann::json::parse(out_.str(), nullptr, false);
  ASSERT_FALSE(result.is_discarded()) << out_.str();
  EXPECT_EQ(result["reenactment"], "r-20260101-000000-abcd");
  EXPECT_EQ(result["job"]["state"], "succeeded");
  EXPECT_EQ(result["job"]["job_id"], "j-good");
  // The progress bar on stderr: stage, percentage, frames, ETA.
  const std::string err = err_.str();
  EXPECT_NE(err.find("register"), std::string::npos) << err;
  EXPECT_NE(err.find("100.0%"), std::string::npos) << err;
  EXPECT_NE(err.find("90/120 frames"), std::string::npos) << err;
  EXPECT_NE(err.find("ETA 1s"), std::string::npos) << err;
}

TEST_F(JobCommands, SubmitWaitReportsAFailedJob) {
  EXPECT_EQ(Run({"jobs", "submit", "--take", "bad", "--method", "rigid-cylinders", "--wait"}),
            kExitFailure);
  EXPECT_NE(err_.str().find("reenact: job j-bad failed: worker killed by signal 11 (SIGSEGV)"),
            std::string::npos)
      << err_.str();
  // Terminal escapes in what a worker wrote are printed as text, not obeyed.
  EXPECT_EQ(err_.str().find('\x1b'), std::string::npos) << err_.str();
  EXPECT_NE(err_.str().find("boom\\x1b[2J\\x1b]0;pwned\\x07"), std::string::npos) << err_.str();
  EXPECT_EQ(
      Run({"jobs", "submit", "--take", "bad", "--method", "rigid-cylinders", "--wait", "--json"}),
      kExitFailure);
  const auto result = nlohmann::json::parse(out_.str(), nullptr, false);
  ASSERT_FALSE(result.is_discarded()) << out_.str();
  EXPECT_TRUE(result["reenactment"].is_null());
  EXPECT_EQ(result["job"]["state"], "failed");
}

TEST_F(JobCommands, SubmitWithoutWaitPrintsTheJobId) {
  ASSERT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "rigid-carved"}), kExitOk);
  EXPECT_EQ(out_.str(), "j-good\n");
}

TEST_F(JobCommands, SubmitErrors) {
  EXPECT_EQ(Run({"jobs", "submit", "--take", "missing", "--method", "rigid-carved"}), kExitFailure);
  EXPECT_NE(err_.str().find("no take \"missing\""), std::string::npos) << err_.str();
  EXPECT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "nope"}), kExitFailure);
  EXPECT_EQ(
      Run({"jobs", "submit", "--take", "good", "--method", "rigid-carved", "--option", "novalue"}),
      kExitUsage);
  EXPECT_EQ(Run({"jobs", "submit", "--method", "rigid-carved"}), kExitUsage);
}

TEST_F(JobCommands, SubmitModelIsTheBodyMethodsModelOption) {
  ASSERT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--model",
                 "makehuman:teacher", "--option", "atlas_px=512"}),
            kExitOk)
      << err_.str();
  EXPECT_EQ(service_.last_submit.method(), "body");
  EXPECT_EQ(service_.last_submit.options().at("model"), "makehuman:teacher");
  EXPECT_EQ(service_.last_submit.options().at("atlas_px"), "512");
  // The same model twice is fine.
  ASSERT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--model=procedural",
                 "--option", "model=procedural"}),
            kExitOk)
      << err_.str();
  EXPECT_EQ(service_.last_submit.options().at("model"), "procedural");
  EXPECT_EQ(service_.last_submit.options().size(), 1u);
  EXPECT_FALSE(service_.last_submit.live());
}

TEST_F(JobCommands, SubmitLiveIsTheRequestsFieldNotAnOption) {
  ASSERT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--live"}), kExitOk)
      << err_.str();
  EXPECT_TRUE(service_.last_submit.live());
  EXPECT_FALSE(service_.last_submit.options().contains("live"));
  EXPECT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--option", "live=true"}),
            kExitUsage);
  EXPECT_NE(err_.str().find("live is not an option"), std::string::npos) << err_.str();
}

TEST_F(JobCommands, SubmitModelErrors) {
  service_.last_submit.Clear();
  // --model and --option model= that disagree.
  EXPECT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--model", "procedural",
                 "--option", "model=makehuman:teacher"}),
            kExitUsage);
  EXPECT_NE(err_.str().find("--model procedural disagrees with --option model=makehuman:teacher"),
            std::string::npos)
      << err_.str();
  EXPECT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--model", ""}),
            kExitUsage);
  EXPECT_EQ(Run({"jobs", "submit", "--take", "good", "--method", "body", "--model"}), kExitUsage);
  // Nothing reached the server.
  EXPECT_TRUE(service_.last_submit.method().empty());
}

TEST_F(JobCommands, ListFiltersAndPrints) {
  ASSERT_EQ(Run({"jobs", "list", "--state", "succeeded", "--take", "good", "--json"}), kExitOk);
  EXPECT_EQ(service_.last_list.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(service_.last_list.take_id(), "good");
  const auto list = nlohmann::json::parse(out_.str(), nullptr, false);
  ASSERT_TRUE(list.is_array()) << out_.str();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["reenactment_id"], "r-1");
  ASSERT_EQ(Run({"jobs", "list"}), kExitOk);
  EXPECT_NE(out_.str().find("j-good"), std::string::npos);
  EXPECT_NE(out_.str().find("100.0%"), std::string::npos);
  EXPECT_EQ(Run({"jobs", "list", "--state", "sleeping"}), kExitUsage);
}

TEST_F(JobCommands, WatchShowAndCancel) {
  ASSERT_EQ(Run({"jobs", "watch", "--job", "j-good", "--json"}), kExitOk) << err_.str();
  std::istringstream lines(out_.str());
  std::string line;
  int events = 0, log_lines = 0;
  while (std::getline(lines, line)) {
    const auto event = nlohmann::json::parse(line, nullptr, false);
    ASSERT_FALSE(event.is_discarded()) << line;
    ++events;
    log_lines += static_cast<int>(event["log_lines"].size());
  }
  EXPECT_EQ(events, 6);
  EXPECT_EQ(log_lines, 4);
  EXPECT_EQ(Run({"jobs", "watch", "--job", "j-bad"}), kExitFailure);
  ASSERT_EQ(Run({"jobs", "show", "--job", "j-good"}), kExitOk);
  EXPECT_NE(out_.str().find("register 50.0%"), std::string::npos) << out_.str();
  EXPECT_NE(out_.str().find("ETA 1m05s"), std::string::npos) << out_.str();
  EXPECT_EQ(Run({"jobs", "show", "--job", "j-nope"}), kExitFailure);
  ASSERT_EQ(Run({"jobs", "cancel", "--job", "j-good"}), kExitOk);
  EXPECT_EQ(out_.str(), "job j-good cancelled\n");
  EXPECT_EQ(Run({"jobs", "cancel"}), kExitUsage);
}

// `jobs show` of a body job prints how well its fits explain each sensor and
// the moments the sensors contradict them, from the reenactment's figures;
// a reenactment that cannot be read leaves the job's lines alone.
TEST_F(JobCommands, ShowPrintsTheFitDiagnosisOfTheReenactment) {
  ASSERT_EQ(Run({"jobs", "show", "--job", "j-fit"}), kExitOk) << err_.str();
  const std::string text = out_.str();
  EXPECT_NE(
      text.find("fit          sensor front: 97.3 % of its points explained (RMS 4.2 mm), 91 % "
                "of the surface facing it seen"),
      std::string::npos)
      << text;
  EXPECT_NE(text.find("sensor back: 80.1 %"), std::string::npos) << text;
  EXPECT_NE(text.find("doubtful     5 frames in 2 spans"), std::string::npos) << text;
  EXPECT_NE(text.find("   1.20 ..    1.40 s  frames 18-21: the fit explains 41 % of sensor "
                      "back's points"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find('\x1b'), std::string::npos) << "a reason is printed terminal-safe";

  ASSERT_EQ(Run({"jobs", "show", "--job", "j-fit", "--json"}), kExitOk) << err_.str();
  const auto json = nlohmann::json::parse(out_.str());
  ASSERT_TRUE(json.contains("fit")) << json.dump();
  EXPECT_EQ(json["fit"]["sensors"].size(), 2u);
  EXPECT_NEAR(json["fit"]["sensors"][1]["surface_seen_fraction"].get<double>(), 0.55, 1e-9);
  ASSERT_EQ(json["fit"]["doubtful_spans"].size(), 2u);
  EXPECT_EQ(json["fit"]["doubtful_spans"][0]["last_frame"], 21);

  ASSERT_EQ(Run({"jobs", "show", "--job", "j-gone"}), kExitOk) << err_.str();
  EXPECT_NE(out_.str().find("reenactment  r-gone"), std::string::npos) << out_.str();
  EXPECT_EQ(out_.str().find("fit "), std::string::npos) << out_.str();
}

}  // namespace
}  // namespace reenact::cli
