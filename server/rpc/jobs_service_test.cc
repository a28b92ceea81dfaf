// The Jobs service end to end over loopback: a Server (in-process) with the
// fake worker (server/jobs/testing/fake_worker_main.cc) or small shell
// scripts as its worker program, and real takes recorded through Ingest.
#include "server/rpc/jobs_service.h"
#include "server/jobs/testing/fake_worker_methods.h"

#include <signal.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/base/time.h"
#include "common/rpc/auth.h"
#include "common/rpc/channel.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "server/recon/methods.h"
#include "server/server_flags.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::IngestClient;
using testing::MakeOpenTake;
using testing::TestServer;

// Every test's wait is bounded by this, seconds.
constexpr double kWaitS = 20.0;

ServerOptions JobOptions(const std::string& worker, int concurrency = 2) {
  ServerOptions options;
  options.jobs.worker_path = worker;
  options.jobs.methods = FakeWorkerMethods();
  options.jobs.concurrency = concurrency;
  options.jobs.poll_period_s = 0.02;
  options.jobs.cancel_grace_s = 5.0;
  options.jobs.shutdown_grace_s = 2.0;
  return options;
}

// A shell script worker in `dir`.
std::string Script(const std::string& dir, const std::string& name, const std::string& body) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << "#!/bin/bash\n" << body;
  fs::permissions(path, fs::perms::owner_all);
  return path;
}

// Whether, within `timeout_s`, no process has `text` in its command line
// (a job's worker process carries its job id).
bool WaitNoProcessNaming(const std::string& text, double timeout_s) {
  const int64_t until = SteadyNowNs() + SecondsToNs(timeout_s);
  while (true) {
    bool found = false;
    std::error_code error;
    for (auto it = fs::directory_iterator("/proc", error); !error && it != fs::directory_iterator();
         it.increment(error)) {
      std::string cmdline = ReadFileToString(it->path().string() + "/cmdline").value_or("");
      std::replace(cmdline.begin(), cmdline.end(), '\0', ' ');
      // Zombies have an empty command line.
      if (cmdline.find(text) != std::string::npos) found = true;
    }
    if (!found) return true;
    if (SteadyNowNs() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// Records a complete take of `sets` frame sets.
void RecordTake(TestServer& t, const std::string& id, uint64_t sets = 3) {
  IngestClient client(*t.ingest);
  client.Open(MakeOpenTake(id, "daemon-a", 1));
  client.SendSets(1, sets, 1);
  client.Close(sets);
  ASSERT_TRUE(client.Finish().ok()) << id;
}

struct Jobs {
  std::unique_ptr<v1::Jobs::Stub> stub;

  explicit Jobs(TestServer& t) : stub(v1::Jobs::NewStub(t.channel)) {}

  grpc::Status Submit(const std::string& take_id, const std::string& method,
                      const std::map<std::string, std::string>& options, v1::Job* job) {
    grpc::ClientContext context;
    v1::SubmitJobRequest request;
    request.set_take_id(take_id);
    request.set_method(method);
    for (const auto& [k, v] : options) (*request.mutable_options())[k] = v;
    return stub->Submit(&context, request, job);
  }
  v1::Job SubmitOk(const std::string& take_id, const std::map<std::string, std::string>& options) {
    v1::Job job;
    const grpc::Status status = Submit(take_id, "rigid-carved", options, &job);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return job;
  }
  grpc::Status Get(const std::string& job_id, v1::Job* job) {
    grpc::ClientContext context;
    v1::GetJobRequest request;
    request.set_job_id(job_id);
    return stub->Get(&context, request, job);
  }
  grpc::Status Cancel(const std::string& job_id, v1::Job* job) {
    grpc::ClientContext context;
    v1::CancelJobRequest request;
    request.set_job_id(job_id);
    return stub->Cancel(&context, request, job);
  }
  grpc::Status List(v1::JobState state, const std::string& take_id, v1::ListJobsResponse* out) {
    grpc::ClientContext context;
    v1::ListJobsRequest request;
    request.set_state(state);
    request.set_take_id(take_id);
    return stub->List(&context, request, out);
  }
  // Every event of a Watch until the stream ends.
  grpc::Status Watch(const std::string& job_id, std::vector<v1::JobEvent>* events) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::WatchJobRequest request;
    request.set_job_id(job_id);
    auto reader = stub->Watch(&context, request);
    v1::JobEvent event;
    while (reader->Read(&event)) events->push_back(event);
    return reader->Finish();
  }
  // Polls Get until `done(job)` or kWaitS.
  v1::Job WaitFor(const std::string& job_id, const std::function<bool(const v1::Job&)>& done) {
    v1::Job job;
    const int64_t deadline_ns = SteadyNowNs() + SecondsToNs(kWaitS);
    while (SteadyNowNs() < deadline_ns) {
      if (Get(job_id, &job).ok() && done(job)) return job;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ADD_FAILURE() << "job " << job_id << " never got there; last: " << job.ShortDebugString();
    return job;
  }
  v1::Job WaitEnd(const std::string& job_id) {
    return WaitFor(job_id, [](const v1::Job& j) {
      return j.state() == v1::JOB_STATE_SUCCEEDED || j.state() == v1::JOB_STATE_FAILED ||
             j.state() == v1::JOB_STATE_CANCELLED;
    });
  }
};

TEST(JobsService, SubmitErrors) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_submit_errors");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  v1::Job job;
  EXPECT_EQ(jobs.Submit("nope", "rigid-carved", {}, &job).error_code(),
            grpc::StatusCode::NOT_FOUND);
  const grpc::Status bad_method = jobs.Submit("take1", "rigid-magic", {}, &job);
  EXPECT_EQ(bad_method.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(bad_method.error_message().find("rigid-cylinders, rigid-carved, body"),
            std::string::npos)
      << bad_method.error_message();
  EXPECT_EQ(jobs.Submit("../etc", "rigid-carved", {}, &job).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(jobs.Submit("take1", "rigid-carved", {{"", "x"}}, &job).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // A take still recording.
  IngestClient recording(*t->ingest);
  recording.Open(MakeOpenTake("take2", "daemon-a", 1));
  recording.SendSets(1, 2, 1);
  ASSERT_TRUE(recording.WaitAck(2));
  EXPECT_EQ(jobs.Submit("take2", "rigid-carved", {}, &job).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(jobs.Get("j-unknown", &job).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(jobs.Get("bad/id", &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(jobs.Cancel("j-unknown", &job).error_code(), grpc::StatusCode::NOT_FOUND);
  std::vector<v1::JobEvent> events;
  EXPECT_EQ(jobs.Watch("j-unknown", &events).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(events.empty());
  v1::ListJobsResponse list;
  ASSERT_TRUE(jobs.List(v1::JOB_STATE_UNSPECIFIED, "", &list).ok());
  EXPECT_EQ(list.jobs_size(), 0);
  // The body model (thesis ch. 4) is a method like the rigid ones: Submit
  // checks the option names and sizes, the worker the values (before it
  // loads the take).
  const grpc::Status body =
      jobs.Submit("take1", "body", {{"model", "procedural"}, {"atlas_px", "512"}}, &job);
  ASSERT_TRUE(body.ok()) << body.error_message();
  EXPECT_EQ(job.method(), "body");
  EXPECT_EQ(job.options().at("model"), "procedural");
  EXPECT_EQ(job.options().at("atlas_px"), "512");
}

TEST(JobsService, BodyModelsAreAssetNamesNeverServerPaths) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_assets");
  const std::string assets = dir + "/assets";
  std::filesystem::create_directories(assets + "/teacher");
  ServerOptions options = JobOptions(REENACT_FAKE_WORKER);
  options.jobs.asset_roots = {assets};
  // As reenact-server's main: the method checks its options against the
  // server's assets.
  options.jobs.check_job = [assets](const std::string& method,
                                    const std::map<std::string, std::string>& job_options) {
    return recon::CheckJob(method, job_options, {assets});
  };
  auto t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  v1::Job job;
  // A path is refused the same way whether or not it exists on the server:
  // the messages differ only by the client's own text.
  std::vector<std::string> messages;
  for (const std::string& path :
       {"makehuman:" + assets + "/teacher", "makehuman:" + assets + "/nobody",
        std::string("makehuman:/etc"), std::string("makehuman:../../etc"),
        std::string("makehuman:..")}) {
    const grpc::Status status = jobs.Submit("take1", "body", {{"model", path}}, &job);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << path;
    std::string message = status.error_message();
    message.replace(message.find(path), path.size(), "SPEC");
    messages.push_back(message);
    EXPECT_EQ(message, messages.front());
  }
  // Whether a name exists is the one thing said, with the names there are.
  const grpc::Status unknown = jobs.Submit("take1", "body", {{"model", "makehuman:etc"}}, &job);
  EXPECT_EQ(unknown.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_NE(unknown.error_message().find("it has makehuman:teacher"), std::string::npos)
      << unknown.error_message();
  EXPECT_EQ(unknown.error_message().find(assets), std::string::npos) << unknown.error_message();
  const grpc::Status named = jobs.Submit("take1", "body", {{"model", "makehuman:teacher"}}, &job);
  EXPECT_TRUE(named.ok()) << named.error_message();
}

TEST(JobsService, FinishedJobsPastTheirRetentionLoseFolderAndRowButNotTheReenactment) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_retention");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const v1::Job old_job = jobs.WaitEnd(jobs.SubmitOk("take1", {{"fake_steps", "2"}}).job_id());
  ASSERT_EQ(old_job.state(), v1::JOB_STATE_SUCCEEDED) << old_job.error();
  const std::string folder = dir + "/data/jobs/" + old_job.job_id();
  ASSERT_TRUE(std::filesystem::exists(folder + "/worker.log"));
  const int64_t cutoff = old_job.finished_unix_ns() + 1;
  const v1::Job new_job = jobs.WaitEnd(jobs.SubmitOk("take1", {{"fake_steps", "2"}}).job_id());
  ASSERT_GE(new_job.finished_unix_ns(), cutoff);

  const absl::StatusOr<int> swept = t->server->jobs().DeleteJobsFinishedBefore(cutoff);
  ASSERT_TRUE(swept.ok()) << swept.status();
  EXPECT_EQ(*swept, 1);
  EXPECT_FALSE(std::filesystem::exists(folder));
  v1::Job gone;
  EXPECT_EQ(jobs.Get(old_job.job_id(), &gone).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(std::filesystem::exists(dir + "/data/jobs/" + new_job.job_id()));
  // What the job made stays: retention is about logs, not results.
  EXPECT_TRUE(t->server->reenactments().Get(old_job.reenactment_id()).ok());
}

TEST(JobsService, WatchSeesProgressAndTheReenactment) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_success");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const v1::Job submitted =
      jobs.SubmitOk("take1", {{"fake_steps", "10"}, {"fake_step_ms", "60"}, {"voxel_mm", "8"}});
  EXPECT_EQ(submitted.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(submitted.take_id(), "take1");
  EXPECT_EQ(submitted.options().at("voxel_mm"), "8");
  EXPECT_GT(submitted.submitted_unix_ns(), 0);

  std::vector<v1::JobEvent> events;
  const grpc::Status watched = jobs.Watch(submitted.job_id(), &events);
  ASSERT_TRUE(watched.ok()) << watched.error_message();
  ASSERT_GE(events.size(), 3u);
  double last_fraction = 0;
  int increases = 0, log_lines = 0;
  bool saw_running = false, saw_eta = false;
  for (const v1::JobEvent& e : events) {
    EXPECT_GE(e.job().progress().fraction(), last_fraction);
    if (e.job().progress().fraction() > last_fraction) ++increases;
    last_fraction = e.job().progress().fraction();
    saw_running |= e.job().state() == v1::JOB_STATE_RUNNING;
    saw_eta |= e.job().state() == v1::JOB_STATE_RUNNING && e.job().progress().eta_s() > 0;
    log_lines += e.log_lines_size();
  }
  std::cout << "[ figures  ] events " << events.size() << ", fraction increases " << increases
            << ", log lines " << log_lines << "\n";
  EXPECT_GE(increases, 4);
  EXPECT_TRUE(saw_running);
  EXPECT_TRUE(saw_eta);
  EXPECT_GE(log_lines, 5);  // The first line, a line every second step, the result.
  const v1::Job end = events.back().job();
  ASSERT_EQ(end.state(), v1::JOB_STATE_SUCCEEDED) << end.error();
  EXPECT_DOUBLE_EQ(end.progress().fraction(), 1.0);
  EXPECT_EQ(end.progress().frames_done(), 10);
  EXPECT_EQ(end.progress().frames_total(), 10);
  EXPECT_EQ(end.attempts(), 1);
  EXPECT_GE(end.finished_unix_ns(), end.started_unix_ns());
  EXPECT_GE(end.started_unix_ns(), end.submitted_unix_ns());
  ASSERT_FALSE(end.reenactment_id().empty());
  auto summary = t->server->reenactments().Get(end.reenactment_id());
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->info().job_id(), end.job_id());
  EXPECT_EQ(summary->info().take_id(), "take1");
  // The worker got the take's file (the server's own workers read it in
  // place) and its log stays beside the job.
  const std::string job_dir = dir + "/data/jobs/" + end.job_id();
  const std::string log = ReadFileToString(job_dir + "/worker.log").value_or("");
  EXPECT_NE(log.find("takes/take1.mcap"), std::string::npos) << log;
  EXPECT_NE(log.find("--- attempt 1"), std::string::npos) << log;

  // Watching a finished job: one event, then the end.
  events.clear();
  ASSERT_TRUE(jobs.Watch(end.job_id(), &events).ok());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].job().state(), v1::JOB_STATE_SUCCEEDED);
  // Cancel of a finished job returns it as it is.
  v1::Job cancelled;
  ASSERT_TRUE(jobs.Cancel(end.job_id(), &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::JOB_STATE_SUCCEEDED);
}

TEST(JobsService, InvalidReenactmentFails) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_garbage");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const v1::Job job = jobs.WaitEnd(jobs.SubmitOk("take1", {{"fake_end", "garbage"}}).job_id());
  EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(job.error().find("is not usable"), std::string::npos) << job.error();
  EXPECT_TRUE(job.reenactment_id().empty());
  EXPECT_TRUE(t->server->reenactments().List().empty());
}

TEST(JobsService, WorkerErrorsFailTheJobNotTheServer) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_crash");
  const std::string segv = Script(dir, "segv.sh",
                                  "echo '{\"stage\":\"load\",\"fraction\":0.1}'\n"
                                  "echo 'loading the take went badly' >&2\n"
                                  "kill -SEGV $$\n");
  auto t = TestServer::Start(dir + "/data", JobOptions(segv));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const v1::Job crashed = jobs.WaitEnd(jobs.SubmitOk("take1", {}).job_id());
  EXPECT_EQ(crashed.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(crashed.error().find("worker killed by signal 11 (SIGSEGV)"), std::string::npos)
      << crashed.error();
  EXPECT_NE(crashed.error().find("last log: loading the take went badly"), std::string::npos)
      << crashed.error();
  std::cout << "[ figures  ] crash error: " << crashed.error() << "\n";
  // The compiled fake crashing mid-way, and a clean {"error"} failure.
  t.reset();
  t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  Jobs jobs2(*t);
  const v1::Job segv2 = jobs2.WaitEnd(jobs2.SubmitOk("take1", {{"fake_end", "segv"}}).job_id());
  EXPECT_NE(segv2.error().find("signal 11 (SIGSEGV); last log: fake worker: about to crash"),
            std::string::npos)
      << segv2.error();
  const v1::Job failed = jobs2.WaitEnd(jobs2.SubmitOk("take1", {{"fake_end", "fail"}}).job_id());
  EXPECT_EQ(failed.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(failed.error(), "fake failure at the end");
  // The server still answers and still runs jobs.
  v1::ListJobsResponse list;
  ASSERT_TRUE(jobs2.List(v1::JOB_STATE_FAILED, "take1", &list).ok());
  EXPECT_EQ(list.jobs_size(), 3);
  const v1::Job ok = jobs2.WaitEnd(jobs2.SubmitOk("take1", {}).job_id());
  EXPECT_EQ(ok.state(), v1::JOB_STATE_SUCCEEDED) << ok.error();
  // A worker program that does not exist.
  t.reset();
  t = TestServer::Start(dir + "/data", JobOptions(dir + "/no-such-worker"));
  ASSERT_NE(t, nullptr);
  Jobs jobs3(*t);
  const v1::Job missing = jobs3.WaitEnd(jobs3.SubmitOk("take1", {}).job_id());
  EXPECT_EQ(missing.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(missing.error().find("cannot start the worker"), std::string::npos) << missing.error();
}

TEST(JobsService, AFullQueueRefusesMoreJobsUntilOneRuns) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_queue_bound");
  ServerOptions options = JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1);
  options.jobs.max_queued_jobs = 2;
  auto t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const std::map<std::string, std::string> forever = {{"fake_steps", "100000"},
                                                      {"fake_step_ms", "20"}};
  const v1::Job running = jobs.SubmitOk("take1", forever);
  jobs.WaitFor(running.job_id(), [](const v1::Job& j) { return j.progress().fraction() > 0; });
  jobs.SubmitOk("take1", forever);
  const v1::Job second = jobs.SubmitOk("take1", forever);
  v1::Job job;
  const grpc::Status full = jobs.Submit("take1", "rigid-carved", forever, &job);
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(full.error_message().find("--max-queued-jobs"), std::string::npos)
      << full.error_message();
  // A queued job that goes makes room.
  ASSERT_TRUE(jobs.Cancel(second.job_id(), &job).ok());
  EXPECT_TRUE(jobs.Submit("take1", "rigid-carved", forever, &job).ok());
  ASSERT_TRUE(jobs.Cancel(running.job_id(), &job).ok());
}

// --job-memory-mb: a job whose estimate (from its options and the stored
// take's size) is over the budget is refused, naming both figures; an
// accepted job's worker runs under the budget (--memory-limit-mb).
TEST(JobsService, AJobOverTheMemoryBudgetIsRefusedAndTheWorkerRunsUnderIt) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_memory_budget");
  ServerOptions options = JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1);
  options.jobs.job_memory_mb = 2048;
  // A stand-in for recon::JobMemoryBytes: the take file and a MiB for each
  // of the fake worker's steps; what it was given is kept to check.
  auto seen = std::make_shared<std::vector<v1::Take>>();
  auto seen_mu = std::make_shared<std::mutex>();
  options.jobs.job_memory = [seen, seen_mu](const std::string&,
                                            const std::map<std::string, std::string>& job_options,
                                            const v1::Take& take) -> absl::StatusOr<int64_t> {
    {
      std::lock_guard<std::mutex> lock(*seen_mu);
      seen->push_back(take);
    }
    const auto it = job_options.find("fake_steps");
    const int64_t mb = it == job_options.end() ? 0 : std::stoll(it->second);
    return take.size_bytes() + (mb << 20);
  };
  auto t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->server->jobs().job_memory_mb(), 2048);
  RecordTake(*t, "take1", 4);
  Jobs jobs(*t);

  v1::Job job;
  const grpc::Status refused = jobs.Submit("take1", "rigid-carved", {{"fake_steps", "4096"}}, &job);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  for (const char* part : {"about 4097 MiB", "2048 MiB a job", "--job-memory-mb"}) {
    EXPECT_NE(refused.error_message().find(part), std::string::npos)
        << part << " in " << refused.error_message();
  }
  {
    // The estimate saw the stored take as the catalog knows it.
    std::lock_guard<std::mutex> lock(*seen_mu);
    ASSERT_EQ(seen->size(), 1u);
    EXPECT_EQ(seen->front().take_id(), "take1");
    EXPECT_EQ(seen->front().frame_set_count(), 4);
    EXPECT_GT(seen->front().size_bytes(), 0);
  }
  v1::ListJobsResponse listed;
  ASSERT_TRUE(jobs.List(v1::JOB_STATE_UNSPECIFIED, "take1", &listed).ok());
  EXPECT_EQ(listed.jobs_size(), 0);

  // Under the budget: queued, and its worker gets the budget as its limit.
  const v1::Job accepted = jobs.SubmitOk("take1", {{"fake_steps", "5"}});
  const v1::Job done = jobs.WaitEnd(accepted.job_id());
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error();
  const std::string log =
      ReadFileToString(dir + "/data/jobs/" + accepted.job_id() + "/worker.log").value_or("");
  EXPECT_NE(log.find("memory-limit-mb 2048"), std::string::npos) << log;
}

TEST(ServerFlags, JobMemoryBudget) {
  auto parsed = ParseServerCommandLine({"--data", "d", "--listen", "127.0.0.1:1"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.jobs.job_memory_mb, -1);  // Shared from the machine's.
  parsed =
      ParseServerCommandLine({"--data", "d", "--listen", "127.0.0.1:1", "--job-memory-mb", "0"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.jobs.job_memory_mb, 0);
  for (const char* bad : {"-1", "lots"}) {
    EXPECT_EQ(
        ParseServerCommandLine({"--data", "d", "--listen", "127.0.0.1:1", "--job-memory-mb", bad})
            .status()
            .code(),
        absl::StatusCode::kInvalidArgument)
        << bad;
  }
}

// Each token has its own bound on waiting jobs: one coach's loop cannot
// fill the queue for the others. A job names the token that submitted it,
// also after a restart.
TEST(JobsService, EachTokenHasItsOwnBoundOnWaitingJobs) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_token_bound");
  std::map<std::string, std::string> tokens;
  for (const auto& [name, role] :
       std::vector<std::pair<std::string, rpc::Role>>{{"admin", rpc::Role::kAdmin},
                                                      {"coach-a", rpc::Role::kCoach},
                                                      {"coach-b", rpc::Role::kCoach}}) {
    const absl::StatusOr<std::string> token = rpc::AddToken(dir + "/tokens.json", role, name);
    ASSERT_TRUE(token.ok()) << token.status();
    tokens[name] = *token;
  }
  ServerOptions options = JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1);
  options.auth_file = dir + "/tokens.json";
  options.jobs.max_queued_jobs_per_token = 2;
  auto t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  const auto stub = [&](const std::string& name) {
    rpc::ClientSecurity security;
    security.token = tokens.at(name);
    return v1::Jobs::NewStub(
        rpc::MakeClientChannel(t->server->address(), grpc::ChannelArguments(), security));
  };
  {
    rpc::ClientSecurity security;
    security.token = tokens.at("admin");
    auto ingest = v1::Ingest::NewStub(
        rpc::MakeClientChannel(t->server->address(), grpc::ChannelArguments(), security));
    IngestClient client(*ingest);
    client.Open(MakeOpenTake("take1", "daemon-a", 1));
    client.SendSets(1, 3, 1);
    client.Close(3);
    ASSERT_TRUE(client.Finish().ok());
  }
  Jobs coach_a(*t), coach_b(*t);
  coach_a.stub = stub("coach-a");
  coach_b.stub = stub("coach-b");
  const std::map<std::string, std::string> forever = {{"fake_steps", "100000"},
                                                      {"fake_step_ms", "20"}};
  const v1::Job running = coach_a.SubmitOk("take1", forever);
  EXPECT_EQ(running.submitted_by(), "coach-a");
  coach_a.WaitFor(running.job_id(), [](const v1::Job& j) { return j.progress().fraction() > 0; });
  const v1::Job first = coach_a.SubmitOk("take1", forever);
  coach_a.SubmitOk("take1", forever);
  v1::Job job;
  const grpc::Status full = coach_a.Submit("take1", "rigid-carved", forever, &job);
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(full.error_message().find("--max-queued-jobs-per-token 2"), std::string::npos)
      << full.error_message();
  // Another coach is not held back by the first one's jobs.
  const v1::Job other = coach_b.SubmitOk("take1", forever);
  EXPECT_EQ(other.submitted_by(), "coach-b");
  // One that goes makes room for its own token.
  ASSERT_TRUE(coach_a.Cancel(first.job_id(), &job).ok());
  EXPECT_TRUE(coach_a.Submit("take1", "rigid-carved", forever, &job).ok());
  ASSERT_TRUE(coach_a.Cancel(running.job_id(), &job).ok());
  // The submitter is kept in the catalog.
  coach_a.stub.reset();
  coach_b.stub.reset();
  t.reset();
  t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  Jobs again(*t);
  again.stub = stub("admin");
  v1::Job stored;
  ASSERT_TRUE(again.Get(other.job_id(), &stored).ok());
  EXPECT_EQ(stored.submitted_by(), "coach-b");
}

TEST(JobsService, CancelStopsRunningAndQueuedJobs) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_cancel");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const std::map<std::string, std::string> forever = {{"fake_steps", "100000"},
                                                      {"fake_step_ms", "20"}};
  const v1::Job running = jobs.SubmitOk("take1", forever);
  const v1::Job queued = jobs.SubmitOk("take1", forever);
  jobs.WaitFor(running.job_id(), [](const v1::Job& j) { return j.progress().fraction() > 0; });
  EXPECT_EQ(jobs.WaitFor(queued.job_id(), [](const v1::Job&) { return true; }).state(),
            v1::JOB_STATE_QUEUED);

  v1::Job job;
  ASSERT_TRUE(jobs.Cancel(queued.job_id(), &job).ok());
  EXPECT_EQ(job.state(), v1::JOB_STATE_CANCELLED);
  EXPECT_EQ(job.started_unix_ns(), 0);

  const int64_t start_ns = SteadyNowNs();
  ASSERT_TRUE(jobs.Cancel(running.job_id(), &job).ok());
  const double cancel_s = NsToSeconds(SteadyNowNs() - start_ns);
  std::cout << "[ figures  ] cancel of a running job answered in " << cancel_s << " s\n";
  EXPECT_EQ(job.state(), v1::JOB_STATE_CANCELLED) << job.error();
  EXPECT_EQ(job.error().rfind("cancelled by a client (worker local-", 0), 0u) << job.error();
  EXPECT_LT(cancel_s, 1.0);  // At once: the worker hears it at its next heartbeat.
  EXPECT_TRUE(WaitNoProcessNaming(running.job_id(), 5.0)) << "the cancelled job's worker runs on";
  EXPECT_TRUE(t->server->reenactments().List().empty());

  // A worker that ignores SIGTERM is killed after the grace period.
  t.reset();
  ServerOptions options = JobOptions(REENACT_FAKE_WORKER, 1);
  options.jobs.cancel_grace_s = 0.3;
  t = TestServer::Start(dir + "/data", options);
  ASSERT_NE(t, nullptr);
  Jobs jobs2(*t);
  std::map<std::string, std::string> stubborn = forever;
  stubborn["fake_ignore_term"] = "1";
  const v1::Job deaf = jobs2.SubmitOk("take1", stubborn);
  jobs2.WaitFor(deaf.job_id(), [](const v1::Job& j) { return j.progress().fraction() > 0; });
  ASSERT_TRUE(jobs2.Cancel(deaf.job_id(), &job).ok());
  EXPECT_EQ(job.state(), v1::JOB_STATE_CANCELLED);
  // SIGTERM, then SIGKILL 0.3 s later: gone well within a few seconds.
  EXPECT_TRUE(WaitNoProcessNaming(deaf.job_id(), 5.0)) << "the deaf worker was not killed";
}

TEST(JobsService, RestartRequeuesRunningJobs) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_restart");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  std::string job_id;
  {
    Jobs jobs(*t);
    job_id = jobs.SubmitOk("take1", {{"fake_hang_first", "1"}, {"fake_steps", "4"}}).job_id();
    jobs.WaitFor(job_id, [](const v1::Job& j) { return j.progress().fraction() > 0; });
    // A watch open across the shutdown ends with UNAVAILABLE.
    std::vector<v1::JobEvent> events;
    grpc::Status watched;
    std::thread watcher([&] { watched = jobs.Watch(job_id, &events); });
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    t->server->Shutdown();
    watcher.join();
    EXPECT_EQ(watched.error_code(), grpc::StatusCode::UNAVAILABLE) << watched.error_message();
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.back().job().state(), v1::JOB_STATE_RUNNING);
  }
  t.reset();
  // The catalog still says RUNNING.
  {
    auto catalog = Catalog::Open(dir + "/data/catalog.sqlite");
    ASSERT_TRUE(catalog.ok()) << catalog.status();
    auto stored = (*catalog)->GetJob(job_id);
    ASSERT_TRUE(stored.ok()) << stored.status();
    EXPECT_EQ(stored->state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(stored->attempts(), 1);
  }
  t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER));
  ASSERT_NE(t, nullptr);
  Jobs jobs(*t);
  const v1::Job end = jobs.WaitEnd(job_id);
  EXPECT_EQ(end.state(), v1::JOB_STATE_SUCCEEDED) << end.error();
  EXPECT_EQ(end.attempts(), 2);
  EXPECT_FALSE(end.reenactment_id().empty());
  const std::string log =
      ReadFileToString(dir + "/data/jobs/" + job_id + "/worker.log").value_or("");
  EXPECT_NE(log.find("--- attempt 1"), std::string::npos) << log;
  EXPECT_NE(log.find("--- attempt 2"), std::string::npos) << log;
}

TEST(JobsService, ConcurrencyOneRunsJobsOneAfterTheOther) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_serial");
  auto t = TestServer::Start(dir + "/data", JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "take1");
  Jobs jobs(*t);
  const std::string trace = dir + "/trace.txt";
  const std::map<std::string, std::string> options = {
      {"fake_steps", "5"}, {"fake_step_ms", "40"}, {"fake_trace", trace}};
  const std::string first = jobs.SubmitOk("take1", options).job_id();
  const std::string second = jobs.SubmitOk("take1", options).job_id();
  EXPECT_EQ(jobs.WaitEnd(first).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(jobs.WaitEnd(second).state(), v1::JOB_STATE_SUCCEEDED);
  // The workers' own clocks: the second started after the first ended.
  std::istringstream lines(ReadFileToString(trace).value_or(""));
  std::map<std::string, int64_t> start_ns, end_ns;
  std::string what, id;
  int64_t ns = 0;
  while (lines >> what >> id >> ns) (what == "start" ? start_ns : end_ns)[id] = ns;
  ASSERT_EQ(start_ns.size(), 2u);
  ASSERT_EQ(end_ns.size(), 2u);
  std::cout << "[ figures  ] gap between the two workers "
            << NsToSeconds(start_ns[second] - end_ns[first]) * 1e3 << " ms\n";
  EXPECT_GE(start_ns[second], end_ns[first]);
  // Newest first, filtered by take and state.
  v1::ListJobsResponse list;
  ASSERT_TRUE(jobs.List(v1::JOB_STATE_SUCCEEDED, "take1", &list).ok());
  ASSERT_EQ(list.jobs_size(), 2);
  EXPECT_EQ(list.jobs(0).job_id(), second);
  EXPECT_EQ(list.jobs(1).job_id(), first);
  v1::ListJobsResponse other;
  ASSERT_TRUE(jobs.List(v1::JOB_STATE_UNSPECIFIED, "other", &other).ok());
  EXPECT_EQ(other.jobs_size(), 0);
}

// Deleting a take deletes what was made from it: its reenactments (images of
// the person), its finished jobs' folders and rows; a take with a job still
// running is refused; --keep-derived keeps them.
grpc::Status DeleteTake(TestServer& t, const std::string& id, v1::DeleteTakeResponse* out) {
  grpc::ClientContext context;
  v1::DeleteTakeRequest request;
  request.set_take_id(id);
  return t.takes->Delete(&context, request, out);
}

TEST(JobsService, DeletingATakeDeletesItsReenactmentsAndJobFolders) {
  for (const bool keep_derived : {false, true}) {
    const std::string dir = reenact::testing::MakeTempDir(std::string("jobs_privacy_") +
                                                          (keep_derived ? "keep" : "delete"));
    ServerOptions options = JobOptions(REENACT_FAKE_WORKER, /*concurrency=*/1);
    options.keep_derived = keep_derived;
    auto t = TestServer::Start(dir + "/data", options);
    ASSERT_NE(t, nullptr);
    RecordTake(*t, "person");
    RecordTake(*t, "other");
    Jobs jobs(*t);
    const v1::Job done = jobs.WaitEnd(jobs.SubmitOk("person", {}).job_id());
    ASSERT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error();
    const v1::Job kept = jobs.WaitEnd(jobs.SubmitOk("other", {}).job_id());
    ASSERT_EQ(kept.state(), v1::JOB_STATE_SUCCEEDED) << kept.error();
    const std::string reen = t->server->reenactments().PathFor(done.reenactment_id());
    const std::string job_dir = dir + "/data/jobs/" + done.job_id();
    ASSERT_TRUE(fs::exists(reen));
    ASSERT_TRUE(fs::exists(job_dir));
    // A job still running holds the take.
    const v1::Job slow = jobs.SubmitOk("person", {{"fake_steps", "200"}, {"fake_step_ms", "50"}});
    jobs.WaitFor(slow.job_id(),
                 [](const v1::Job& j) { return j.state() == v1::JOB_STATE_RUNNING; });
    v1::DeleteTakeResponse response;
    if (!keep_derived) {
      const grpc::Status held = DeleteTake(*t, "person", &response);
      EXPECT_EQ(held.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << held.error_message();
      EXPECT_NE(held.error_message().find(slow.job_id()), std::string::npos);
      EXPECT_TRUE(t->server->takes().GetTake("person").ok());  // Nothing was deleted.
    }
    v1::Job cancelled;
    ASSERT_TRUE(jobs.Cancel(slow.job_id(), &cancelled).ok());
    jobs.WaitEnd(slow.job_id());
    const grpc::Status deleted = DeleteTake(*t, "person", &response);
    ASSERT_TRUE(deleted.ok()) << deleted.error_message();
    EXPECT_EQ(fs::exists(reen), keep_derived);
    EXPECT_EQ(fs::exists(job_dir), keep_derived);
    EXPECT_EQ(response.reenactments_deleted(), keep_derived ? 0 : 1);
    EXPECT_EQ(response.jobs_deleted(), keep_derived ? 0 : 2);
    v1::Job gone;
    EXPECT_EQ(jobs.Get(done.job_id(), &gone).error_code(),
              keep_derived ? grpc::StatusCode::OK : grpc::StatusCode::NOT_FOUND);
    // The other take's reenactment and job are untouched.
    EXPECT_TRUE(fs::exists(t->server->reenactments().PathFor(kept.reenactment_id())));
    EXPECT_TRUE(jobs.Get(kept.job_id(), &gone).ok());
    std::cout << "[ figures  ] keep_derived=" << keep_derived << ": freed "
              << response.freed_bytes() << " bytes\n";
  }
}

// `reenact-server --data out/server` from a shell: the workers run in their
// job's folder, so the take's path they get must not be relative.
TEST(JobsService, RelativeDataFolderStillReachesTheTake) {
  const std::string dir = reenact::testing::MakeTempDir("jobs_relative");
  const fs::path previous = fs::current_path();
  fs::current_path(dir);
  {
    auto t = TestServer::Start("data", JobOptions(REENACT_FAKE_WORKER));
    ASSERT_NE(t, nullptr);
    RecordTake(*t, "take1");
    Jobs jobs(*t);
    const v1::Job end = jobs.WaitEnd(jobs.SubmitOk("take1", {{"fake_steps", "2"}}).job_id());
    EXPECT_EQ(end.state(), v1::JOB_STATE_SUCCEEDED) << end.error();
  }
  fs::current_path(previous);
}

TEST(ServerFlags, JobsAndWorker) {
  auto parsed = ParseServerCommandLine(
      {"--data", "/tmp/d", "--listen", "127.0.0.1:0", "--jobs", "3", "--worker", "/opt/w"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.jobs.concurrency, 3);
  EXPECT_EQ(parsed->options.jobs.worker_path, "/opt/w");
  // The registry's methods are reenact-server's own (server_main.cc).
  EXPECT_TRUE(parsed->options.jobs.methods.empty());
  parsed = ParseServerCommandLine({"--data", "/tmp/d", "--listen", "127.0.0.1:0"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->options.jobs.concurrency, 0);  // One per hardware thread.
  EXPECT_TRUE(parsed->options.jobs.worker_path.empty());
  EXPECT_EQ(
      ParseServerCommandLine({"--data", "d", "--listen", ":1", "--jobs", "-1"}).status().code(),
      absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(
      ParseServerCommandLine({"--data", "d", "--listen", ":1", "--jobs", "two"}).status().code(),
      absl::StatusCode::kInvalidArgument);
}

TEST(ServerFlags, WorkersAndLeases) {
  auto parsed = ParseServerCommandLine(
      {"--data", "d", "--listen", "127.0.0.1:1", "--workers", "local:4", "--lease-ttl", "12"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_TRUE(parsed->options.jobs.local_workers);
  EXPECT_EQ(parsed->options.jobs.concurrency, 4);
  EXPECT_EQ(parsed->options.jobs.lease_ttl_s, 12.0);
  parsed = ParseServerCommandLine({"--data", "d", "--listen", "127.0.0.1:1", "--workers", "none"});
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_FALSE(parsed->options.jobs.local_workers);
  for (const char* bad : {"local:0", "local:x", "remote", "local:2:3", ""}) {
    EXPECT_EQ(ParseServerCommandLine({"--data", "d", "--listen", "127.0.0.1:1", "--workers", bad})
                  .status()
                  .code(),
              absl::StatusCode::kInvalidArgument)
        << bad;
  }
  EXPECT_EQ(ParseServerCommandLine(
                {"--data", "d", "--listen", "127.0.0.1:1", "--workers", "local:2", "--jobs", "3"})
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::server
