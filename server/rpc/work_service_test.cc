// The Work service over loopback: an in-process server that starts no
// workers of its own (--workers none), real reenact-worker processes that
// lease its jobs from another working folder (each running the fake worker,
// server/jobs/testing/fake_worker_main.cc, as its job program), and raw
// calls that play a worker gone wrong.
#include "server/rpc/work_service.h"

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/subprocess.h"
#include "common/base/time.h"
#include "common/io/reenactment_file.h"
#include "common/io/take_convert.h"
#include "common/io/testing/small_reenactment.h"
#include "common/rpc/auth.h"
#include "common/rpc/channel.h"
#include "common/testing/test_data.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/work_service.grpc.pb.h"
#include "server/jobs/testing/fake_worker_methods.h"
#include "server/jobs/testing/jobs_calls.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::IngestClient;
using testing::MakeOpenTake;
using testing::TestServer;

constexpr double kWaitS = 20.0;

// The bytes of a small valid reenactment file with the id `id`.
std::string SmallReenactmentBytes(const std::string& dir, const std::string& id) {
  const std::string path = dir + "/small.reen";
  reenact::testing::TestReenactmentOptions options;
  options.id = id;
  EXPECT_TRUE(WriteReenactmentFile(reenact::testing::MakeTestReenactment(options), path).ok());
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

ServerOptions NetworkOnly(double lease_ttl_s = 30.0) {
  ServerOptions options;
  options.jobs.methods = FakeWorkerMethods();
  options.jobs.local_workers = false;
  options.jobs.concurrency = 1;
  options.jobs.poll_period_s = 0.02;
  options.jobs.lease_ttl_s = lease_ttl_s;
  return options;
}

class Work : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = reenact::testing::MakeTempDir("work_service"); }
  void TearDown() override {
    for (auto& worker : workers_) {
      (void)worker->Signal(SIGKILL);
      (void)worker->Wait(5);
    }
    t_.reset();
    std::error_code error;
    fs::remove_all(dir_, error);
  }

  void StartServer(ServerOptions options) {
    t_ = TestServer::Start(dir_ + "/data", std::move(options));
    ASSERT_NE(t_, nullptr);
    jobs_ = v1::Jobs::NewStub(t_->channel);
    work_ = v1::Work::NewStub(t_->channel);
    IngestClient client(*t_->ingest);
    client.Open(MakeOpenTake("take", "daemon-a", 1));
    client.SendSets(1, 4, 1);
    client.Close(4);
    ASSERT_TRUE(client.Finish().ok());
  }

  v1::Job Submit(const std::map<std::string, std::string>& options) {
    return testing::SubmitJob(*jobs_, "take", "rigid-carved", options);
  }
  v1::Job Get(const std::string& job_id) { return testing::GetJob(*jobs_, job_id); }

  // Polls the job until `done` holds or kWaitS passes.
  v1::Job WaitFor(const std::string& job_id, const std::function<bool(const v1::Job&)>& done) {
    const int64_t until = SteadyNowNs() + SecondsToNs(kWaitS);
    v1::Job job = Get(job_id);
    while (!done(job) && SteadyNowNs() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      job = Get(job_id);
    }
    return job;
  }

  // A reenact-worker process against the test server, in a working folder
  // of its own, with its own scratch folder.
  Subprocess* StartWorker(const std::string& name, std::vector<std::string> extra = {}) {
    const std::string home = dir_ + "/" + name;
    fs::create_directories(home + "/scratch");
    std::vector<std::string> argv = {REENACT_WORKER_BINARY,
                                     "--server",
                                     t_->server->address(),
                                     "--scratch",
                                     home + "/scratch",
                                     "--name",
                                     name};
    argv.insert(argv.end(), extra.begin(), extra.end());
    SubprocessOptions options;
    options.working_dir = home;
    options.stdout_path = home + "/worker.log";
    options.stderr_path = home + "/worker.log";
    options.env["REENACT_WORKER_JOB_PROGRAM"] = REENACT_FAKE_WORKER;
    auto worker = Subprocess::Start(argv, options);
    EXPECT_TRUE(worker.ok()) << worker.status();
    if (!worker.ok()) return nullptr;
    workers_.push_back(std::move(*worker));
    return workers_.back().get();
  }

  std::string WorkerLog(const std::string& name) {
    std::ifstream in(dir_ + "/" + name + "/worker.log");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

  int StoredReenactments() {
    grpc::ClientContext context;
    v1::ListReenactmentsRequest request;
    v1::ListReenactmentsResponse response;
    EXPECT_TRUE(v1::Reenactments::NewStub(t_->channel)->List(&context, request, &response).ok());
    return response.reenactments_size();
  }

  v1::LeaseResponse Lease(double wait_s, grpc::Status* status,
                          v1::WorkProtocol protocol = v1::WORK_PROTOCOL_V1) {
    grpc::ClientContext context;
    v1::LeaseRequest request;
    request.set_protocol(protocol);
    request.set_worker_name("raw");
    request.set_wait_s(wait_s);
    v1::LeaseResponse response;
    *status = work_->Lease(&context, request, &response);
    return response;
  }

  grpc::Status Upload(const std::string& lease_id, int64_t declared, const std::string& data,
                      v1::UploadResponse* response) {
    grpc::ClientContext context;
    auto writer = work_->Upload(&context, response);
    v1::UploadChunk chunk;
    chunk.set_lease_id(lease_id);
    chunk.mutable_result()->set_file_bytes(declared);
    chunk.set_data(data);
    writer->Write(chunk);
    writer->WritesDone();
    return writer->Finish();
  }

  std::string dir_;
  std::unique_ptr<TestServer> t_;
  std::unique_ptr<v1::Jobs::Stub> jobs_;
  std::unique_ptr<v1::Work::Stub> work_;
  std::vector<std::unique_ptr<Subprocess>> workers_;
};

TEST_F(Work, AWorkerElsewhereRunsAJobAndCleansItsScratch) {
  StartServer(NetworkOnly());
  const v1::Job job = Submit({{"fake_steps", "5"}});
  Subprocess* worker = StartWorker("w1", {"--once", "--wait", "10"});
  ASSERT_NE(worker, nullptr);
  const absl::StatusOr<ExitInfo> exit = worker->Wait(kWaitS);
  ASSERT_TRUE(exit.ok()) << WorkerLog("w1");
  EXPECT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << WorkerLog("w1");
  const v1::Job done = Get(job.job_id());
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error();
  EXPECT_EQ(done.attempts(), 1);
  EXPECT_EQ(StoredReenactments(), 1);
  EXPECT_TRUE(fs::is_empty(dir_ + "/w1/scratch")) << "the job's scratch folder is left";
}

TEST_F(Work, AKilledWorkerLosesItsLeaseAndASecondWorkerCompletesTheJob) {
  StartServer(NetworkOnly(/*lease_ttl_s=*/1.0));
  const v1::Job job = Submit({{"fake_steps", "100"}, {"fake_step_ms", "40"}});
  Subprocess* first = StartWorker("first", {"--once", "--wait", "10"});
  ASSERT_NE(first, nullptr);
  const v1::Job running = WaitFor(job.job_id(), [](const v1::Job& j) {
    return j.state() == v1::JOB_STATE_RUNNING && j.progress().fraction() > 0.02;
  });
  ASSERT_EQ(running.state(), v1::JOB_STATE_RUNNING) << WorkerLog("first");
  ASSERT_TRUE(first->Signal(SIGKILL).ok());
  (void)first->Wait(5);
  const int64_t killed_ns = SteadyNowNs();
  const v1::Job queued =
      WaitFor(job.job_id(), [](const v1::Job& j) { return j.state() == v1::JOB_STATE_QUEUED; });
  EXPECT_EQ(queued.state(), v1::JOB_STATE_QUEUED);
  // Queued again once the lease ran out: after about the 1 s TTL.
  EXPECT_LT(NsToSeconds(SteadyNowNs() - killed_ns), 3.0);

  Subprocess* second = StartWorker("second", {"--once", "--wait", "10"});
  ASSERT_NE(second, nullptr);
  const v1::Job done = WaitFor(job.job_id(), [](const v1::Job& j) {
    return j.state() == v1::JOB_STATE_SUCCEEDED || j.state() == v1::JOB_STATE_FAILED;
  });
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error() << WorkerLog("second");
  EXPECT_EQ(done.attempts(), 2);
  EXPECT_EQ(StoredReenactments(), 1);
  // Where each attempt ran and how it ended.
  ASSERT_EQ(done.attempt_history_size(), 2);
  EXPECT_EQ(done.attempt_history(0).worker(), "first");
  EXPECT_EQ(done.attempt_history(0).outcome(), "lease expired");
  EXPECT_EQ(done.attempt_history(1).number(), 2);
  EXPECT_EQ(done.attempt_history(1).worker(), "second");
  EXPECT_EQ(done.attempt_history(1).outcome(), "succeeded");
  EXPECT_GE(done.attempt_history(1).started_unix_ns(), done.attempt_history(0).ended_unix_ns());
}

TEST_F(Work, AnExpiredAttemptsUploadIsRefusedAndAnAttemptCommitsOnce) {
  StartServer(NetworkOnly(/*lease_ttl_s=*/0.5));
  const v1::Job job = Submit({});
  grpc::Status status;
  const v1::LeaseResponse first = Lease(5, &status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(first.has_lease());
  EXPECT_EQ(first.lease().job().job_id(), job.job_id());
  EXPECT_EQ(first.lease().ttl_s(), 0.5);
  // No heartbeat: the lease ends and the job is queued again.
  WaitFor(job.job_id(), [](const v1::Job& j) { return j.state() == v1::JOB_STATE_QUEUED; });
  const std::string stale = SmallReenactmentBytes(dir_, first.lease().reenactment_id());
  v1::UploadResponse response;
  const grpc::Status late =
      Upload(first.lease().lease_id(), static_cast<int64_t>(stale.size()), stale, &response);
  EXPECT_EQ(late.error_code(), grpc::StatusCode::ABORTED) << late.error_message();
  EXPECT_EQ(StoredReenactments(), 0);

  // The second attempt beats while it works, then uploads once.
  const v1::LeaseResponse second = Lease(5, &status);
  ASSERT_TRUE(second.has_lease());
  const std::string file = SmallReenactmentBytes(dir_, second.lease().reenactment_id());
  EXPECT_EQ(second.lease().job().attempts(), 2);
  {
    grpc::ClientContext context;
    v1::HeartbeatRequest beat;
    beat.set_lease_id(second.lease().lease_id());
    beat.mutable_progress()->set_stage("fuse");
    beat.mutable_progress()->set_fraction(0.5);
    beat.add_log_lines("halfway");
    v1::HeartbeatResponse answer;
    ASSERT_TRUE(work_->Heartbeat(&context, beat, &answer).ok());
    EXPECT_EQ(Get(job.job_id()).progress().stage(), "fuse");
  }
  const grpc::Status stored =
      Upload(second.lease().lease_id(), static_cast<int64_t>(file.size()), file, &response);
  ASSERT_TRUE(stored.ok()) << stored.error_message();
  EXPECT_EQ(response.job().state(), v1::JOB_STATE_SUCCEEDED);
  const grpc::Status again =
      Upload(second.lease().lease_id(), static_cast<int64_t>(file.size()), file, &response);
  EXPECT_EQ(again.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_EQ(StoredReenactments(), 1);
}

TEST_F(Work, BadCallsGetClearStatusesAndStoreNothing) {
  StartServer(NetworkOnly());
  const v1::Job job = Submit({});
  grpc::Status status;
  Lease(0, &status, v1::WORK_PROTOCOL_UNSPECIFIED);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  {
    grpc::ClientContext context;
    v1::LeaseRequest request;
    request.set_protocol(v1::WORK_PROTOCOL_V1);
    request.add_methods("no-such-method");
    v1::LeaseResponse response;
    EXPECT_EQ(work_->Lease(&context, request, &response).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT);
  }
  const v1::LeaseResponse lease = Lease(5, &status);
  ASSERT_TRUE(lease.has_lease());
  const std::string& id = lease.lease().lease_id();
  v1::UploadResponse response;
  // A hostile size: refused before anything is written.
  EXPECT_EQ(Upload(id, int64_t{1} << 60, "x", &response).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // More bytes than declared, fewer than declared, no valid reenactment.
  EXPECT_EQ(Upload(id, 2, "xyz", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Upload(id, 10, "xyz", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Get(job.job_id()).state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(Upload(id, 3, "xyz", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Get(job.job_id()).state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(StoredReenactments(), 0);
  // Unknown leases.
  grpc::ClientContext context;
  v1::HeartbeatRequest beat;
  beat.set_lease_id("no-such-lease");
  v1::HeartbeatResponse answer;
  EXPECT_EQ(work_->Heartbeat(&context, beat, &answer).error_code(), grpc::StatusCode::ABORTED);
  // No leftovers beside the reenactments.
  for (const auto& entry : fs::directory_iterator(dir_ + "/data/reenactments")) {
    EXPECT_EQ(entry.path().extension(), ".reen") << entry.path();
  }
}

// A lease is bound to the credential that took it: another worker's token
// can neither beat, read, upload nor fail it, whatever it knows of its id,
// and the job goes on under its own worker.
TEST_F(Work, ALeaseServesOnlyTheCredentialThatTookIt) {
  std::map<std::string, std::string> tokens;
  for (const auto& [name, role] :
       std::vector<std::pair<std::string, rpc::Role>>{{"admin", rpc::Role::kAdmin},
                                                      {"worker-a", rpc::Role::kWorker},
                                                      {"worker-b", rpc::Role::kWorker}}) {
    const absl::StatusOr<std::string> token = rpc::AddToken(dir_ + "/tokens.json", role, name);
    ASSERT_TRUE(token.ok()) << token.status();
    tokens[name] = *token;
  }
  ServerOptions options = NetworkOnly();
  options.auth_file = dir_ + "/tokens.json";
  t_ = TestServer::Start(dir_ + "/data", options);
  ASSERT_NE(t_, nullptr);
  const auto channel = [&](const std::string& name) {
    rpc::ClientSecurity security;
    security.token = tokens.at(name);
    return rpc::MakeClientChannel(t_->server->address(), grpc::ChannelArguments(), security);
  };
  const auto admin = channel("admin");
  {
    auto ingest = v1::Ingest::NewStub(admin);
    IngestClient client(*ingest);
    client.Open(MakeOpenTake("take", "daemon-a", 1));
    client.SendSets(1, 4, 1);
    client.Close(4);
    ASSERT_TRUE(client.Finish().ok());
  }
  jobs_ = v1::Jobs::NewStub(admin);
  const v1::Job job = Submit({});
  auto work_a = v1::Work::NewStub(channel("worker-a"));
  auto work_b = v1::Work::NewStub(channel("worker-b"));
  v1::LeaseResponse leased;
  {
    grpc::ClientContext context;
    v1::LeaseRequest request;
    request.set_protocol(v1::WORK_PROTOCOL_V1);
    request.set_worker_name("a");
    request.set_wait_s(5);
    ASSERT_TRUE(work_a->Lease(&context, request, &leased).ok());
  }
  ASSERT_TRUE(leased.has_lease());
  const std::string& id = leased.lease().lease_id();
  const auto beat = [&](v1::Work::Stub& work) {
    grpc::ClientContext context;
    v1::HeartbeatRequest request;
    request.set_lease_id(id);
    request.mutable_progress()->set_stage("stolen");
    request.mutable_progress()->set_fraction(0.9);
    v1::HeartbeatResponse answer;
    return work.Heartbeat(&context, request, &answer).error_code();
  };
  EXPECT_EQ(beat(*work_b), grpc::StatusCode::PERMISSION_DENIED);
  {
    grpc::ClientContext context;
    v1::ReadTakeRequest request;
    request.set_lease_id(id);
    auto reader = work_b->ReadTake(&context, request);
    v1::TakeChunk chunk;
    int64_t read = 0;
    while (reader->Read(&chunk)) read += static_cast<int64_t>(chunk.data().size());
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::PERMISSION_DENIED);
    EXPECT_EQ(read, 0);
  }
  const std::string file = SmallReenactmentBytes(dir_, leased.lease().reenactment_id());
  const auto upload = [&](v1::Work::Stub& work, v1::UploadResponse* response) {
    grpc::ClientContext context;
    auto writer = work.Upload(&context, response);
    v1::UploadChunk chunk;
    chunk.set_lease_id(id);
    chunk.mutable_result()->set_file_bytes(static_cast<int64_t>(file.size()));
    chunk.set_data(file);
    writer->Write(chunk);
    writer->WritesDone();
    return writer->Finish().error_code();
  };
  v1::UploadResponse response;
  EXPECT_EQ(upload(*work_b, &response), grpc::StatusCode::PERMISSION_DENIED);
  {
    grpc::ClientContext context;
    v1::FailRequest request;
    request.set_lease_id(id);
    request.set_error("another worker says it failed");
    v1::FailResponse response;
    EXPECT_EQ(work_b->Fail(&context, request, &response).error_code(),
              grpc::StatusCode::PERMISSION_DENIED);
  }
  // Nothing of that reached the job; its own worker goes on and ends it.
  v1::Job now = Get(job.job_id());
  EXPECT_EQ(now.state(), v1::JOB_STATE_RUNNING);
  EXPECT_NE(now.progress().stage(), "stolen");
  {
    grpc::ClientContext context;
    v1::ListReenactmentsResponse listed;
    ASSERT_TRUE(v1::Reenactments::NewStub(admin)->List(&context, {}, &listed).ok());
    EXPECT_EQ(listed.reenactments_size(), 0);
  }
  EXPECT_EQ(beat(*work_a), grpc::StatusCode::OK);
  ASSERT_EQ(upload(*work_a, &response), grpc::StatusCode::OK);
  EXPECT_EQ(response.job().state(), v1::JOB_STATE_SUCCEEDED);
}

TEST_F(Work, ATakeSelectionStreamsOnlyTheFramesItNamesAndTheAttemptCountsTheBytes) {
  StartServer(NetworkOnly());
  const v1::Job job = Submit({});
  grpc::Status status;
  const v1::LeaseResponse lease = Lease(5, &status);
  ASSERT_TRUE(status.ok() && lease.has_lease()) << status.error_message();
  const std::string lease_id = lease.lease().lease_id();
  // Reads into `path`; the bytes, or -1 with *status set.
  auto read = [&](const v1::TakeSelection* selection, const std::string& input,
                  const std::string& path, grpc::Status* status) -> int64_t {
    grpc::ClientContext context;
    v1::ReadTakeRequest request;
    request.set_lease_id(lease_id);
    request.set_input(input);
    if (selection != nullptr) *request.mutable_selection() = *selection;
    auto reader = work_->ReadTake(&context, request);
    v1::TakeChunk chunk;
    std::string data;
    int64_t stated = -1;
    while (reader->Read(&chunk)) {
      EXPECT_EQ(chunk.offset(), static_cast<int64_t>(data.size()));
      stated = chunk.file_bytes();
      data.append(chunk.data());
    }
    *status = reader->Finish();
    if (!status->ok()) return -1;
    EXPECT_EQ(stated, static_cast<int64_t>(data.size()));
    std::ofstream(path, std::ios::binary) << data;
    return static_cast<int64_t>(data.size());
  };
  const int64_t whole = read(nullptr, "", dir_ + "/whole.mcap", &status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(whole, lease.lease().take_bytes());
  const v1::TakeSelection nothing;
  const int64_t index = read(&nothing, "", dir_ + "/index.mcap", &status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  v1::TakeSelection first_two;
  v1::FrameRange* range = first_two.add_depth();
  range->set_sensor_id("k0");
  range->set_first(0);
  range->set_end(2);
  *first_two.add_color() = *range;
  const int64_t selected = read(&first_two, "", dir_ + "/selected.mcap", &status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  std::printf("[ selection ] whole take %lld bytes, without images %lld, frames 0-1 %lld\n",
              static_cast<long long>(whole), static_cast<long long>(index),
              static_cast<long long>(selected));
  EXPECT_LT(index, whole);
  EXPECT_GT(selected, index);
  EXPECT_LT(selected, whole);

  auto full = ReadRecordedTake(dir_ + "/whole.mcap");
  auto part = ReadRecordedTake(dir_ + "/selected.mcap");
  ASSERT_TRUE(full.ok() && part.ok()) << full.status() << part.status();
  ASSERT_EQ(part->frames.size(), full->frames.size());
  ASSERT_EQ(part->frame_sets.size(), full->frame_sets.size());
  for (size_t i = 0; i < part->frames.size(); ++i) {
    const SensorFrame& p = part->frames[i];
    const SensorFrame& f = full->frames[i];
    ASSERT_TRUE(p.depth && p.color && f.depth && f.color);
    const bool kept = p.frame_index < 2;
    EXPECT_EQ(p.depth->data, kept ? f.depth->data : "") << p.frame_index;
    EXPECT_EQ(p.color->data, kept ? f.color->data : "") << p.frame_index;
    EXPECT_EQ(p.depth->host_stamp_ns, f.depth->host_stamp_ns);
  }

  // Bad selections, and a selection of an input.
  v1::TakeSelection unknown = first_two;
  unknown.mutable_depth(0)->set_sensor_id("no-such-sensor");
  EXPECT_EQ(read(&unknown, "", dir_ + "/bad.mcap", &status), -1);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_EQ(read(&nothing, "prepare", dir_ + "/bad.mcap", &status), -1);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_EQ(read(&nothing, "", dir_ + "/bad.mcap", &status), index) << "the lease still reads";
  ASSERT_TRUE(status.ok()) << status.error_message();
  // Nothing the selections made is left in the server's data folder.
  for (const auto& entry : fs::recursive_directory_iterator(dir_ + "/data")) {
    EXPECT_EQ(entry.path().filename().string().rfind("selection-", 0), std::string::npos)
        << entry.path();
  }

  const v1::Job running = Get(job.job_id());
  ASSERT_FALSE(running.attempt_history().empty());
  EXPECT_EQ(running.attempt_history().rbegin()->read_bytes(), whole + 2 * index + selected);
  // A lease that ended reads nothing.
  grpc::ClientContext context;
  v1::FailRequest fail;
  fail.set_lease_id(lease_id);
  fail.set_error("enough");
  v1::FailResponse failed;
  ASSERT_TRUE(work_->Fail(&context, fail, &failed).ok());
  EXPECT_EQ(read(&nothing, "", dir_ + "/bad.mcap", &status), -1);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();
}

TEST_F(Work, ACancelledJobStopsItsWorkersJob) {
  StartServer(NetworkOnly());
  const v1::Job job = Submit({{"fake_steps", "400"}, {"fake_step_ms", "50"}});
  Subprocess* worker = StartWorker("w1", {"--once", "--wait", "10"});
  ASSERT_NE(worker, nullptr);
  WaitFor(job.job_id(), [](const v1::Job& j) { return j.progress().fraction() > 0.01; });
  grpc::ClientContext context;
  v1::CancelJobRequest request;
  request.set_job_id(job.job_id());
  v1::Job cancelled;
  ASSERT_TRUE(jobs_->Cancel(&context, request, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::JOB_STATE_CANCELLED);
  const absl::StatusOr<ExitInfo> exit = worker->Wait(kWaitS);
  ASSERT_TRUE(exit.ok()) << "the worker went on after the cancel\n" << WorkerLog("w1");
  EXPECT_NE(WorkerLog("w1").find("lease_lost"), std::string::npos) << WorkerLog("w1");
  EXPECT_EQ(Get(job.job_id()).state(), v1::JOB_STATE_CANCELLED);
  EXPECT_EQ(StoredReenactments(), 0);
}

TEST_F(Work, AWorkerOutlivesAServerRestart) {
  StartServer(NetworkOnly());
  const std::string address = t_->server->address();
  Subprocess* worker = StartWorker("w1", {"--loop"});
  ASSERT_NE(worker, nullptr);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  t_.reset();  // The server goes; the worker keeps trying.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ServerOptions options = NetworkOnly();
  options.data_dir = dir_ + "/data";
  options.listen_address = address;
  auto server = Server::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto channel = grpc::CreateChannel((*server)->address(), grpc::InsecureChannelCredentials());
  jobs_ = v1::Jobs::NewStub(channel);
  const v1::Job job = Submit({{"fake_steps", "3"}});
  const v1::Job done = WaitFor(job.job_id(), [](const v1::Job& j) {
    return j.state() == v1::JOB_STATE_SUCCEEDED || j.state() == v1::JOB_STATE_FAILED;
  });
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error() << WorkerLog("w1");
  EXPECT_NE(WorkerLog("w1").find("server_unreachable"), std::string::npos);
  ASSERT_TRUE(worker->Signal(SIGTERM).ok());
  const absl::StatusOr<ExitInfo> exit = worker->Wait(kWaitS);
  ASSERT_TRUE(exit.ok());
  EXPECT_EQ(exit->exit_code, 3) << exit->ToString();  // Stopped by SIGTERM.
  jobs_.reset();
  server->reset();
}

// A segmented job's parts, each a lease of its own (raw calls play the
// workers): prepare first, then both segments at once with prepare's upload
// as their input, then the stitch with all three; a part given back runs
// again; the stitch's upload is the job's reenactment.
TEST_F(Work, ASegmentedJobLeasesItsPartsInOrderAndHandsOnTheirUploads) {
  StartServer(NetworkOnly());
  auto submit = [&](const std::string& method, int segments, v1::Job* job) {
    grpc::ClientContext context;
    v1::SubmitJobRequest request;
    request.set_take_id("take");
    request.set_method(method);
    request.set_segments(segments);
    return jobs_->Submit(&context, request, job);
  };
  v1::Job job;
  // A hostile count is refused (every registered method can split a take).
  EXPECT_EQ(submit("body", 65, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit("body", -1, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  ASSERT_TRUE(submit("body", 2, &job).ok());
  ASSERT_EQ(job.parts_size(), 4);
  EXPECT_EQ(job.parts(0).state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.parts(1).state(), v1::JOB_STATE_UNSPECIFIED);

  auto read = [&](const std::string& lease_id, const std::string& input, std::string* data) {
    grpc::ClientContext context;
    v1::ReadTakeRequest request;
    request.set_lease_id(lease_id);
    request.set_input(input);
    auto reader = work_->ReadTake(&context, request);
    v1::TakeChunk chunk;
    data->clear();
    while (reader->Read(&chunk)) data->append(chunk.data());
    return reader->Finish();
  };
  grpc::Status status;
  v1::UploadResponse uploaded;
  const v1::LeaseResponse prepare = Lease(5, &status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(prepare.has_lease());
  EXPECT_EQ(prepare.lease().part(), "prepare");
  EXPECT_EQ(prepare.lease().inputs_size(), 0);
  EXPECT_FALSE(Lease(0, &status).has_lease()) << "the segments wait for prepare";
  ASSERT_TRUE(Upload(prepare.lease().lease_id(), 4, "PREP", &uploaded).ok());
  EXPECT_EQ(uploaded.job().state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(uploaded.job().parts(0).file_bytes(), 4);

  std::map<std::string, std::string> leases;  // part -> lease id
  for (int k = 0; k < 2; ++k) {
    const v1::LeaseResponse segment = Lease(5, &status);
    ASSERT_TRUE(segment.has_lease()) << status.error_message();
    ASSERT_EQ(segment.lease().inputs_size(), 1);
    EXPECT_EQ(segment.lease().inputs(0).name(), "prepare");
    EXPECT_EQ(segment.lease().inputs(0).bytes(), 4);
    leases[segment.lease().part()] = segment.lease().lease_id();
  }
  ASSERT_TRUE(leases.count("segment-1") && leases.count("segment-2"));
  EXPECT_EQ(Get(job.job_id()).state(), v1::JOB_STATE_RUNNING);
  std::string data;
  ASSERT_TRUE(read(leases["segment-1"], "prepare", &data).ok());
  EXPECT_EQ(data, "PREP");
  EXPECT_EQ(read(leases["segment-1"], "segment-2", &data).error_code(),
            grpc::StatusCode::NOT_FOUND);
  ASSERT_TRUE(Upload(leases["segment-1"], 2, "S1", &uploaded).ok());
  {
    // The second segment's worker drains: the part is queued again.
    grpc::ClientContext context;
    v1::FailRequest fail;
    fail.set_lease_id(leases["segment-2"]);
    fail.set_error("node drains");
    fail.set_give_back(true);
    v1::FailResponse answer;
    ASSERT_TRUE(work_->Fail(&context, fail, &answer).ok());
    EXPECT_EQ(answer.job().state(), v1::JOB_STATE_RUNNING);
  }
  const v1::LeaseResponse again = Lease(5, &status);
  ASSERT_TRUE(again.has_lease());
  EXPECT_EQ(again.lease().part(), "segment-2");
  ASSERT_TRUE(Upload(again.lease().lease_id(), 3, "S2!", &uploaded).ok());

  const v1::LeaseResponse stitch = Lease(5, &status);
  ASSERT_TRUE(stitch.has_lease());
  EXPECT_EQ(stitch.lease().part(), "stitch");
  ASSERT_EQ(stitch.lease().inputs_size(), 3);
  for (const auto& [input, expected] : std::map<std::string, std::string>{
           {"prepare", "PREP"}, {"segment-1", "S1"}, {"segment-2", "S2!"}}) {
    ASSERT_TRUE(read(stitch.lease().lease_id(), input, &data).ok()) << input;
    EXPECT_EQ(data, expected) << input;
  }
  const std::string file = SmallReenactmentBytes(dir_, stitch.lease().reenactment_id());
  ASSERT_TRUE(
      Upload(stitch.lease().lease_id(), static_cast<int64_t>(file.size()), file, &uploaded).ok());
  const v1::Job done = Get(job.job_id());
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error();
  EXPECT_EQ(done.reenactment_id(), stitch.lease().reenactment_id());
  for (const v1::JobPart& part : done.parts()) {
    EXPECT_EQ(part.state(), v1::JOB_STATE_SUCCEEDED) << part.name();
    ASSERT_GE(part.attempt_history_size(), 1) << part.name();
    EXPECT_EQ(part.attempt_history(part.attempt_history_size() - 1).worker(), "raw");
  }
  ASSERT_EQ(done.parts(2).attempt_history_size(), 2);
  EXPECT_EQ(done.parts(2).attempt_history(0).outcome(), "given back");
  EXPECT_EQ(StoredReenactments(), 1);
}

// A part that fails fails its job and ends the other parts' leases; a
// cancel ends them all; a restart queues a running part again and keeps
// the parts that finished.
TEST_F(Work, ASegmentedJobFailsCancelsAndRestartsByItsParts) {
  StartServer(NetworkOnly());
  auto submit = [&]() {
    grpc::ClientContext context;
    v1::SubmitJobRequest request;
    request.set_take_id("take");
    request.set_method("body");
    request.set_segments(2);
    v1::Job job;
    EXPECT_TRUE(jobs_->Submit(&context, request, &job).ok());
    return job;
  };
  auto beat = [&](const std::string& lease_id) {
    grpc::ClientContext context;
    v1::HeartbeatRequest request;
    request.set_lease_id(lease_id);
    v1::HeartbeatResponse answer;
    return work_->Heartbeat(&context, request, &answer).error_code();
  };
  grpc::Status status;
  v1::UploadResponse uploaded;
  // Prepared, then both segments leased.
  auto start_segments = [&](std::vector<std::string>* segment_leases) {
    const v1::LeaseResponse prepare = Lease(5, &status);
    ASSERT_TRUE(prepare.has_lease());
    ASSERT_TRUE(Upload(prepare.lease().lease_id(), 1, "P", &uploaded).ok());
    for (int k = 0; k < 2; ++k) {
      const v1::LeaseResponse segment = Lease(5, &status);
      ASSERT_TRUE(segment.has_lease());
      segment_leases->push_back(segment.lease().lease_id());
    }
  };

  const v1::Job failing = submit();
  std::vector<std::string> leases;
  start_segments(&leases);
  ASSERT_EQ(leases.size(), 2u);
  {
    grpc::ClientContext context;
    v1::FailRequest fail;
    fail.set_lease_id(leases[0]);
    fail.set_error("out of memory");
    v1::FailResponse answer;
    ASSERT_TRUE(work_->Fail(&context, fail, &answer).ok());
  }
  v1::Job job = Get(failing.job_id());
  EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(job.error().find("failed: out of memory"), std::string::npos) << job.error();
  EXPECT_EQ(beat(leases[1]), grpc::StatusCode::ABORTED);
  EXPECT_EQ(job.parts(3).state(), v1::JOB_STATE_CANCELLED);  // The stitch never ran.

  const v1::Job cancelled = submit();
  leases.clear();
  start_segments(&leases);
  {
    grpc::ClientContext context;
    v1::CancelJobRequest request;
    request.set_job_id(cancelled.job_id());
    v1::Job answer;
    ASSERT_TRUE(jobs_->Cancel(&context, request, &answer).ok());
    EXPECT_EQ(answer.state(), v1::JOB_STATE_CANCELLED);
  }
  for (const std::string& lease : leases) EXPECT_EQ(beat(lease), grpc::StatusCode::ABORTED);
  EXPECT_FALSE(Lease(0, &status).has_lease()) << "nothing of the cancelled job stays queued";

  // A restart with one segment done and one running.
  const v1::Job restarted = submit();
  leases.clear();
  start_segments(&leases);
  ASSERT_TRUE(Upload(leases[0], 1, "S", &uploaded).ok());
  t_.reset();
  ServerOptions options = NetworkOnly();
  t_ = TestServer::Start(dir_ + "/data", std::move(options));
  ASSERT_NE(t_, nullptr);
  jobs_ = v1::Jobs::NewStub(t_->channel);
  work_ = v1::Work::NewStub(t_->channel);
  job = Get(restarted.job_id());
  int succeeded = 0;
  for (const v1::JobPart& part : job.parts()) {
    succeeded += part.state() == v1::JOB_STATE_SUCCEEDED ? 1 : 0;
  }
  EXPECT_EQ(succeeded, 2) << "prepare and one segment are kept";
  const v1::LeaseResponse requeued = Lease(5, &status);
  ASSERT_TRUE(requeued.has_lease()) << status.error_message();
  EXPECT_EQ(requeued.lease().job().job_id(), restarted.job_id());
  EXPECT_TRUE(requeued.lease().part().starts_with("segment-")) << requeued.lease().part();
  ASSERT_TRUE(Upload(requeued.lease().lease_id(), 1, "S", &uploaded).ok());
  const v1::LeaseResponse stitch = Lease(5, &status);
  ASSERT_TRUE(stitch.has_lease());
  EXPECT_EQ(stitch.lease().part(), "stitch");
}

}  // namespace
}  // namespace reenact::server
