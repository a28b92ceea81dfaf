// reenact-server --workers slurm on a real one-node Slurm cluster (Debian's
// slurm-wlm and munge, deploy/slurm/test-cluster.sh; skipped, saying why,
// where it cannot run): a queued job becomes an sbatch batch job whose
// reenact-worker --once leases and runs it (with the fake worker as its job
// program), and cancelling a job scancels the batch job that runs it.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "server/jobs/slurm_launcher.h"
#include "server/jobs/testing/fake_worker_methods.h"
#include "server/jobs/testing/jobs_calls.h"
#include "server/jobs/testing/slurm_cluster.h"
#include "server/server.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

using testing::IngestClient;
using testing::MakeOpenTake;
using testing::PollUntil;

// A TCP port nothing listens on now (the kernel's pick for a socket bound
// and closed again); 0 when none could be had.
int FreeLoopbackPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return 0;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof(address);
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
    port = ntohs(address.sin_port);
  }
  ::close(fd);
  return port;
}

class SlurmWorkers : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    cluster_ = testing::SlurmTestCluster::Start(REENACT_SLURM_TEST_CLUSTER, &why);
    if (cluster_ == nullptr) GTEST_SKIP() << "SKIPPED: " << why;
    // The address goes into the launcher before the server starts.
    const int port = FreeLoopbackPort();
    ASSERT_GT(port, 0);
    const std::string address = absl::StrCat("127.0.0.1:", port);
    SlurmLauncherOptions slurm;
    slurm.worker = REENACT_WORKER_BINARY;
    slurm.server_address = address;
    slurm.worker_wait_s = 20;
    slurm.log_dir = cluster_->dir() + "/batch-logs";
    slurm.env = cluster_->env();
    // sbatch passes its environment on to the batch job, and the worker
    // runs the fake job program.
    slurm.env["REENACT_WORKER_JOB_PROGRAM"] = REENACT_FAKE_WORKER;
    absl::StatusOr<std::unique_ptr<SlurmLauncher>> launcher = SlurmLauncher::Create(slurm);
    ASSERT_TRUE(launcher.ok()) << launcher.status();
    launcher_ = launcher->get();

    ServerOptions options;
    options.data_dir = cluster_->dir() + "/data";
    options.listen_address = address;
    options.store.catalog_update_period_s = 3600;
    options.jobs.methods = FakeWorkerMethods();
    options.jobs.local_workers = false;
    options.jobs.poll_period_s = 0.05;
    options.jobs.lease_ttl_s = 10;
    options.jobs.launcher = std::move(*launcher);
    absl::StatusOr<std::unique_ptr<Server>> server = Server::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(*server);
    auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
    jobs_ = v1::Jobs::NewStub(channel);
    auto ingest = v1::Ingest::NewStub(channel);
    IngestClient client(*ingest);
    client.Open(MakeOpenTake("take", "daemon-a", 1));
    client.SendSets(1, 3, 1);
    client.Close(3);
    ASSERT_TRUE(client.Finish().ok());
  }

  void TearDown() override {
    jobs_.reset();
    if (server_ != nullptr) server_->Shutdown();
    server_.reset();
    cluster_.reset();
  }

  v1::Job Submit(const std::map<std::string, std::string>& options) {
    return testing::SubmitJob(*jobs_, "take", "rigid-carved", options);
  }
  v1::Job Get(const std::string& job_id) { return testing::GetJob(*jobs_, job_id); }

  std::unique_ptr<testing::SlurmTestCluster> cluster_;
  SlurmLauncher* launcher_ = nullptr;
  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::Jobs::Stub> jobs_;
};

TEST_F(SlurmWorkers, AJobRunsThroughSbatchAndCancelScancelsItsBatchJob) {
  const v1::Job job = Submit({{"fake_steps", "4"}});
  v1::Job done;
  EXPECT_TRUE(PollUntil(60, [&] {
    done = Get(job.job_id());
    return done.state() == v1::JOB_STATE_SUCCEEDED || done.state() == v1::JOB_STATE_FAILED;
  }));
  ASSERT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.error();
  EXPECT_GE(launcher_->submitted_total(), 1);
  ASSERT_EQ(done.attempt_history_size(), 1);
  const std::optional<std::string> batch =
      SlurmLauncher::BatchJobOf(done.attempt_history(0).worker());
  ASSERT_TRUE(batch.has_value()) << "worker " << done.attempt_history(0).worker();

  // A long job: once a batch job's worker runs it, cancel the job.
  const v1::Job slow = Submit({{"fake_steps", "2000"}, {"fake_step_ms", "50"}});
  v1::Job running;
  EXPECT_TRUE(PollUntil(60, [&] {
    running = Get(slow.job_id());
    return running.state() == v1::JOB_STATE_RUNNING && running.attempt_history_size() > 0;
  }));
  ASSERT_EQ(running.state(), v1::JOB_STATE_RUNNING);
  const std::optional<std::string> slow_batch =
      SlurmLauncher::BatchJobOf(running.attempt_history(0).worker());
  ASSERT_TRUE(slow_batch.has_value());
  EXPECT_EQ(cluster_->Squeue().count(*slow_batch), 1u);
  grpc::ClientContext context;
  v1::CancelJobRequest cancel;
  cancel.set_job_id(slow.job_id());
  v1::Job cancelled;
  ASSERT_TRUE(jobs_->Cancel(&context, cancel, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::JOB_STATE_CANCELLED);
  // scancel: the batch job leaves the queue.
  EXPECT_TRUE(PollUntil(20, [&] { return cluster_->Squeue().count(*slow_batch) == 0; }))
      << "batch job " << *slow_batch << " still in squeue";
}

}  // namespace
}  // namespace reenact::server
