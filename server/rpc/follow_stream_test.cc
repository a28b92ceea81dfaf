// Live jobs over loopback: a Server with a scripted live follower and the
// fake worker; takes recorded through Ingest while a live job follows them
// (Jobs.Submit live=true, Reenactments.Follow), then the same job runs
// offline and ends SUCCEEDED.
#include "server/rpc/follow_stream.h"
#include "server/jobs/testing/fake_worker_methods.h"

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::IngestClient;
using testing::MakeFrameSet;
using testing::MakeOpenTake;
using testing::SensorIds;
using testing::TestServer;

constexpr double kWaitS = 20.0;

// A follower that makes a mesh at the first set and a posed frame with 25
// joints per set; the factory refuses texture_scale=3 (as the real one's
// Validate() does: a value within the option's bounds that Submit takes).
class ScriptedFollower final : public LiveFollower {
 public:
  absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) override {
    LiveFit fit;
    if (pushed_ == 0) {
      fit.mesh.emplace();
      fit.mesh->set_model_name("scripted");
    }
    fit.frame.emplace();
    fit.frame->set_frame_index(pushed_++);
    fit.frame->set_stamp_ns(set.stamp_ns());
    fit.frame->mutable_body()->set_valid(true);
    for (int j = 0; j < 25; ++j) fit.frame->add_joints_in_world_m()->set_y(0.04 * j);
    fit.fit_ms = 1.0;
    return fit;
  }

 private:
  int pushed_ = 0;
};

ServerOptions LiveServerOptions(const std::string& worker = REENACT_FAKE_WORKER) {
  ServerOptions options;
  options.jobs.worker_path = worker;
  options.jobs.methods = FakeWorkerMethods();
  options.jobs.concurrency = 2;
  options.jobs.poll_period_s = 0.02;
  options.live.factory = [](const std::string&, const v1::TakeInfo&,
                            const std::vector<v1::SensorCalibration>&,
                            const std::map<std::string, std::string>& job_options)
      -> absl::StatusOr<std::unique_ptr<LiveFollower>> {
    if (const auto it = job_options.find("texture_scale");
        it != job_options.end() && it->second == "3") {
      return absl::InvalidArgumentError("colour denominator must be 1, 2, 4 or 8");
    }
    return std::make_unique<ScriptedFollower>();
  };
  return options;
}

// One Follow call read on its own thread.
class FollowReader {
 public:
  FollowReader(v1::Reenactments::Stub& stub, const std::string& job_id) {
    context_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::FollowRequest request;
    request.set_job_id(job_id);
    reader_ = stub.Follow(&context_, request);
    thread_ = std::thread([this] {
      v1::FollowEvent event;
      while (reader_->Read(&event)) {
        std::lock_guard<std::mutex> lock(mu_);
        events_.push_back(event);
        changed_.notify_all();
      }
      grpc::Status status = reader_->Finish();
      std::lock_guard<std::mutex> lock(mu_);
      status_ = status;
      done_ = true;
      changed_.notify_all();
    });
  }
  ~FollowReader() {
    context_.TryCancel();
    thread_.join();
  }
  // Waits for the first event (the mesh of a following job).
  bool WaitFirst() {
    std::unique_lock<std::mutex> lock(mu_);
    return changed_.wait_for(lock, std::chrono::seconds(static_cast<int>(kWaitS)), [&] {
      return !events_.empty() || done_;
    }) && !events_.empty();
  }
  // The events and the status, once the stream ended.
  std::vector<v1::FollowEvent> WaitEnd(grpc::Status* status) {
    std::unique_lock<std::mutex> lock(mu_);
    EXPECT_TRUE(changed_.wait_for(lock, std::chrono::seconds(static_cast<int>(kWaitS)),
                                  [&] { return done_; }));
    *status = status_;
    return events_;
  }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::FollowEvent>> reader_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable changed_;
  std::vector<v1::FollowEvent> events_;
  grpc::Status status_;
  bool done_ = false;
};

class FollowStreamTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = reenact::testing::MakeTempDir("follow_stream_test");
    Start(LiveServerOptions());
  }
  void TearDown() override {
    t_.reset();
    fs::remove_all(dir_);
  }
  void Start(ServerOptions options) {
    t_.reset();
    t_ = TestServer::Start(dir_ + "/data", std::move(options));
    ASSERT_NE(t_, nullptr);
    jobs_ = v1::Jobs::NewStub(t_->channel);
    reenactments_ = v1::Reenactments::NewStub(t_->channel);
  }

  // Opens take `take_id` (1 sensor) on `ingest` and waits for TakeOpened.
  static void Open(IngestClient& ingest, const std::string& take_id) {
    ASSERT_TRUE(ingest.Open(MakeOpenTake(take_id, "daemon-a", 1)));
    ASSERT_TRUE(ingest.ReadOpened().has_value());
  }

  // `live`: SubmitJobRequest.live.
  grpc::Status Submit(const std::string& take_id, const std::string& method,
                      const std::map<std::string, std::string>& options, v1::Job* job,
                      bool live = false) {
    grpc::ClientContext context;
    v1::SubmitJobRequest request;
    request.set_take_id(take_id);
    request.set_method(method);
    request.set_live(live);
    for (const auto& [k, v] : options) (*request.mutable_options())[k] = v;
    return jobs_->Submit(&context, request, job);
  }

  // Opens take-1 on `ingest`, submits a live body job (`job`) and follows
  // it; returns once the mesh of set 1 came (the subscription is in place).
  std::unique_ptr<FollowReader> StartFollowing(IngestClient& ingest, v1::Job* job) {
    Open(ingest, "take-1");
    const grpc::Status submitted =
        Submit("take-1", "body", {{"model", "procedural"}}, job, /*live=*/true);
    EXPECT_TRUE(submitted.ok()) << submitted.error_message();
    auto follow = std::make_unique<FollowReader>(*reenactments_, job->job_id());
    EXPECT_TRUE(ingest.SendSet(MakeFrameSet(1, SensorIds(1))));
    EXPECT_TRUE(follow->WaitFirst());
    return follow;
  }

  // Watches the job to its end.
  v1::Job WaitFinished(const std::string& job_id) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::WatchJobRequest request;
    request.set_job_id(job_id);
    auto reader = jobs_->Watch(&context, request);
    v1::JobEvent event;
    v1::Job last;
    while (reader->Read(&event)) last = event.job();
    EXPECT_TRUE(reader->Finish().ok());
    return last;
  }

  v1::Job Get(const std::string& job_id) {
    grpc::ClientContext context;
    v1::GetJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    EXPECT_TRUE(jobs_->Get(&context, request, &job).ok());
    return job;
  }

  std::string dir_;
  std::unique_ptr<TestServer> t_;
  std::unique_ptr<v1::Jobs::Stub> jobs_;
  std::unique_ptr<v1::Reenactments::Stub> reenactments_;
};

TEST_F(FollowStreamTest, LiveJobFollowsTheTakeThenRunsOffline) {
  IngestClient ingest(*t_->ingest);
  v1::Job job;
  std::unique_ptr<FollowReader> follow = StartFollowing(ingest, &job);
  EXPECT_EQ(job.state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(job.progress().stage(), kFollowingStage);
  constexpr uint64_t kSets = 12;
  for (uint64_t s = 2; s <= kSets; ++s) ASSERT_TRUE(ingest.SendSet(MakeFrameSet(s, SensorIds(1))));
  ASSERT_TRUE(ingest.WaitAck(kSets));
  // The job's progress counts the frame sets followed.
  v1::Job following = Get(job.job_id());
  for (int i = 0; i < 1000 && following.progress().frames_done() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    following = Get(job.job_id());
  }
  EXPECT_EQ(following.state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(following.progress().stage(), kFollowingStage);
  EXPECT_GT(following.progress().frames_done(), 0);
  ASSERT_TRUE(ingest.Close(kSets));
  ASSERT_TRUE(ingest.Finish().ok());

  grpc::Status status;
  const std::vector<v1::FollowEvent> events = follow->WaitEnd(&status);
  EXPECT_TRUE(status.ok()) << status.error_message();
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events.front().mesh().model_name(), "scripted");
  uint64_t previous = 0;
  int frames = 0;
  for (size_t i = 1; i + 1 < events.size(); ++i) {
    const v1::FollowEvent& e = events[i];
    ASSERT_TRUE(e.has_frame());
    EXPECT_GT(e.sequence(), previous);
    EXPECT_EQ(e.frame().joints_in_world_m_size(), 25);
    EXPECT_TRUE(e.frame().body().valid());
    EXPECT_GT(e.arrived_unix_ns(), 0);
    EXPECT_GE(e.published_unix_ns(), e.arrived_unix_ns());
    previous = e.sequence();
    ++frames;
  }
  EXPECT_EQ(previous, kSets) << "the last set is always fitted";
  const v1::FollowEnd& end = events.back().end();
  EXPECT_EQ(end.reason(), v1::FOLLOW_END_REASON_TAKE_COMPLETE) << end.message();
  EXPECT_EQ(end.frames_received(), static_cast<int64_t>(kSets));
  EXPECT_EQ(end.frames_followed() + end.frames_skipped(), static_cast<int64_t>(kSets));
  EXPECT_GE(end.frames_followed(), frames);

  const v1::Job finished = WaitFinished(job.job_id());
  EXPECT_EQ(finished.state(), v1::JOB_STATE_SUCCEEDED) << finished.error();
  EXPECT_FALSE(finished.reenactment_id().empty());
  EXPECT_EQ(finished.attempts(), 1);
}

TEST_F(FollowStreamTest, SubmitOfARecordingTakeNeedsALiveBodyJob) {
  IngestClient ingest(*t_->ingest);
  Open(ingest, "take-1");
  v1::Job job;
  EXPECT_EQ(Submit("take-1", "body", {}, &job).error_code(), grpc::FAILED_PRECONDITION);
  const grpc::Status cannot = Submit("take-1", "rigid-cylinders", {}, &job, /*live=*/true);
  EXPECT_EQ(cannot.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(cannot.error_message().find("method rigid-cylinders cannot follow"), std::string::npos)
      << cannot.error_message();
  // "live" is the request's field, not an option.
  const grpc::Status option = Submit("take-1", "body", {{"live", "true"}}, &job);
  EXPECT_EQ(option.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(option.error_message().find("live is not an option"), std::string::npos)
      << option.error_message();
  EXPECT_EQ(Submit("take-1", "body", {}, &job, /*live=*/false).error_code(),
            grpc::FAILED_PRECONDITION);
  ASSERT_TRUE(ingest.Close(0));
  ASSERT_TRUE(ingest.Finish().ok());
}

TEST_F(FollowStreamTest, LiveJobsTakeJobSlotsAndAreRefusedWhenNoneIsFree) {
  // The fixture's server runs 2 jobs at once (--jobs 2).
  IngestClient ingest(*t_->ingest);
  Open(ingest, "take-1");
  const std::map<std::string, std::string> procedural = {{"model", "procedural"}};
  v1::Job first, second, third;
  ASSERT_TRUE(Submit("take-1", "body", procedural, &first, /*live=*/true).ok());
  ASSERT_TRUE(Submit("take-1", "body", procedural, &second, /*live=*/true).ok());
  const grpc::Status refused = Submit("take-1", "body", procedural, &third, /*live=*/true);
  EXPECT_EQ(refused.error_code(), grpc::RESOURCE_EXHAUSTED) << refused.error_message();
  EXPECT_NE(refused.error_message().find("--jobs"), std::string::npos);
  // An offline job waits for a slot while both follow.
  IngestClient other(*t_->ingest);
  Open(other, "take-2");
  ASSERT_TRUE(other.SendSets(1, 2, 1));
  ASSERT_TRUE(other.Close(2));
  ASSERT_TRUE(other.Finish().ok());
  v1::Job offline;
  ASSERT_TRUE(Submit("take-2", "body", {{"model", "procedural"}}, &offline).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(Get(offline.job_id()).state(), v1::JOB_STATE_QUEUED);
  // Cancelling a live job frees its slot, and the queued offline job takes it.
  grpc::ClientContext context;
  v1::CancelJobRequest cancel;
  cancel.set_job_id(first.job_id());
  v1::Job cancelled;
  ASSERT_TRUE(jobs_->Cancel(&context, cancel, &cancelled).ok());
  v1::JobState state = v1::JOB_STATE_QUEUED;
  for (int i = 0; i < 500 && state == v1::JOB_STATE_QUEUED; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    state = Get(offline.job_id()).state();
  }
  EXPECT_NE(state, v1::JOB_STATE_QUEUED);
  ASSERT_TRUE(ingest.Close(0));
  ASSERT_TRUE(ingest.Finish().ok());
}

TEST_F(FollowStreamTest, WithoutALiveFollowerRecordingTakesAreRefused) {
  ServerOptions options = LiveServerOptions();
  options.live.factory = nullptr;
  Start(std::move(options));
  IngestClient ingest(*t_->ingest);
  Open(ingest, "take-1");
  v1::Job job;
  const grpc::Status status = Submit("take-1", "body", {}, &job, /*live=*/true);
  EXPECT_EQ(status.error_code(), grpc::FAILED_PRECONDITION);
  EXPECT_NE(status.error_message().find("cannot follow"), std::string::npos);
  ASSERT_TRUE(ingest.Close(0));
  ASSERT_TRUE(ingest.Finish().ok());
}

TEST_F(FollowStreamTest, JobsThatFollowNothingGetOneEnd) {
  {
    IngestClient ingest(*t_->ingest);
    Open(ingest, "take-1");
    ASSERT_TRUE(ingest.SendSets(1, 3, 1));
    ASSERT_TRUE(ingest.Close(3));
    ASSERT_TRUE(ingest.Finish().ok());
  }
  // A live job of a complete take runs offline.
  v1::Job live;
  ASSERT_TRUE(Submit("take-1", "body", {}, &live, /*live=*/true).ok());
  EXPECT_FALSE(live.live());  // Its take had ended.
  v1::Job offline;
  ASSERT_TRUE(Submit("take-1", "body", {}, &offline).ok());
  for (const v1::Job& job : {live, offline}) {
    FollowReader follow(*reenactments_, job.job_id());
    grpc::Status status;
    const std::vector<v1::FollowEvent> events = follow.WaitEnd(&status);
    EXPECT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].end().reason(), v1::FOLLOW_END_REASON_NOT_FOLLOWING);
    EXPECT_FALSE(events[0].end().message().empty());
    EXPECT_EQ(WaitFinished(job.job_id()).state(), v1::JOB_STATE_SUCCEEDED);
  }
  grpc::Status status;
  {
    FollowReader follow(*reenactments_, "j-unknown");
    follow.WaitEnd(&status);
    EXPECT_EQ(status.error_code(), grpc::NOT_FOUND);
  }
  FollowReader follow(*reenactments_, "bad id!");
  follow.WaitEnd(&status);
  EXPECT_EQ(status.error_code(), grpc::INVALID_ARGUMENT);
}

TEST_F(FollowStreamTest, CancelStopsTheFollowAndNoWorkerRuns) {
  IngestClient ingest(*t_->ingest);
  v1::Job job;
  std::unique_ptr<FollowReader> follow = StartFollowing(ingest, &job);
  {
    grpc::ClientContext context;
    v1::CancelJobRequest request;
    request.set_job_id(job.job_id());
    v1::Job cancelled;
    ASSERT_TRUE(jobs_->Cancel(&context, request, &cancelled).ok());
    EXPECT_EQ(cancelled.state(), v1::JOB_STATE_CANCELLED);
  }
  grpc::Status status;
  const std::vector<v1::FollowEvent> events = follow->WaitEnd(&status);
  EXPECT_TRUE(status.ok());
  EXPECT_EQ(events.back().end().reason(), v1::FOLLOW_END_REASON_CANCELLED);
  ASSERT_TRUE(ingest.SendSet(MakeFrameSet(2, SensorIds(1))));
  ASSERT_TRUE(ingest.Close(2));
  ASSERT_TRUE(ingest.Finish().ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const v1::Job after = Get(job.job_id());
  EXPECT_EQ(after.state(), v1::JOB_STATE_CANCELLED);
  EXPECT_EQ(after.attempts(), 0);
}

TEST_F(FollowStreamTest, TheWorkerGetsNoLiveOnlyOptions) {
  const std::string args = dir_ + "/worker-args.txt";
  const std::string script = dir_ + "/worker.sh";
  std::ofstream(script) << "#!/bin/bash\necho \"$@\" > " << args
                        << "\necho '{\"error\":\"scripted failure\"}'\nexit 1\n";
  fs::permissions(script, fs::perms::owner_all);
  Start(LiveServerOptions(script));
  IngestClient ingest(*t_->ingest);
  Open(ingest, "take-1");
  v1::Job job;
  ASSERT_TRUE(Submit("take-1", "body", {{"shape_spacing", "3"}, {"model", "procedural"}}, &job,
                     /*live=*/true)
                  .ok());
  ASSERT_TRUE(ingest.SendSets(1, 2, 1));
  ASSERT_TRUE(ingest.Close(2));
  ASSERT_TRUE(ingest.Finish().ok());
  const v1::Job finished = WaitFinished(job.job_id());
  EXPECT_EQ(finished.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(finished.error(), "scripted failure");
  std::stringstream text;
  text << std::ifstream(args).rdbuf();
  EXPECT_NE(text.str().find("\"model\":\"procedural\""), std::string::npos) << text.str();
  EXPECT_EQ(text.str().find("live"), std::string::npos) << text.str();
  EXPECT_EQ(text.str().find("shape_spacing"), std::string::npos) << text.str();
}

TEST_F(FollowStreamTest, ALiveFitThatCannotStartFailsTheJob) {
  IngestClient ingest(*t_->ingest);
  Open(ingest, "take-1");
  v1::Job job;
  // Within the option's listed bounds, so Submit takes it (this server has
  // no deeper check); the follower refuses it.
  ASSERT_TRUE(Submit("take-1", "body", {{"texture_scale", "3"}}, &job, /*live=*/true).ok());
  const v1::Job finished = WaitFinished(job.job_id());
  EXPECT_EQ(finished.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(finished.error().find("colour denominator"), std::string::npos) << finished.error();
  ASSERT_TRUE(ingest.Close(0));
  ASSERT_TRUE(ingest.Finish().ok());
}

TEST_F(FollowStreamTest, ShutdownEndsTheFollowWithUnavailable) {
  IngestClient ingest(*t_->ingest);
  v1::Job job;
  std::unique_ptr<FollowReader> follow = StartFollowing(ingest, &job);
  std::thread stop([&] { t_->server->Shutdown(); });
  grpc::Status status;
  const std::vector<v1::FollowEvent> events = follow->WaitEnd(&status);
  stop.join();
  EXPECT_EQ(status.error_code(), grpc::UNAVAILABLE);
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().end().reason(), v1::FOLLOW_END_REASON_SHUTDOWN);
  (void)ingest.Finish();
}

}  // namespace
}  // namespace reenact::server
