#include "server/jobs/slurm_launcher.h"

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"
#include "server/jobs/testing/slurm_cluster.h"

namespace reenact::server {
namespace {

using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::HasSubstr;
using testing::OnPath;
using testing::PollUntil;
using testing::RunTool;
using testing::ToolOutput;

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

// Writes an executable shell script.
void WriteScript(const std::string& path, const std::string& text) {
  WriteFile(path, text);
  ::chmod(path.c_str(), 0755);
}

// ---- The config file -------------------------------------------------------

constexpr char kGoodConfig[] = R"(# Reenact's workers on the GPU partition.

partition = gpu
account = vision
time = 02:00:00
mem = 8G
qos = normal
cpus_per_task = 4
sbatch_arg = --gres=gpu:1
sbatch_arg = --constraint=a100
  worker = /opt/reenact/bin/reenact-worker
server = head.cluster:50051
token_file = /home/reenact/token
tls_ca = /home/reenact/ca.pem
scratch = /scratch/$USER
worker_wait_s = 30.5
log_dir = /shared/reenact/slurm-logs
max_pending = 2
max_jobs = 8
start_grace_s = 20
)";

TEST(SlurmConfig, ParsesEveryKey) {
  absl::StatusOr<SlurmLauncherOptions> options = ParseSlurmConfigText(kGoodConfig, "slurm.conf");
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->partition, "gpu");
  EXPECT_EQ(options->account, "vision");
  EXPECT_EQ(options->time_limit, "02:00:00");
  EXPECT_EQ(options->mem, "8G");
  EXPECT_EQ(options->qos, "normal");
  EXPECT_EQ(options->cpus_per_task, 4);
  EXPECT_THAT(options->extra_sbatch_args, ElementsAre("--gres=gpu:1", "--constraint=a100"));
  EXPECT_EQ(options->worker, "/opt/reenact/bin/reenact-worker");
  EXPECT_EQ(options->server_address, "head.cluster:50051");
  EXPECT_EQ(options->token_file, "/home/reenact/token");
  EXPECT_EQ(options->tls_ca, "/home/reenact/ca.pem");
  EXPECT_EQ(options->scratch, "/scratch/$USER");
  EXPECT_DOUBLE_EQ(options->worker_wait_s, 30.5);
  EXPECT_EQ(options->log_dir, "/shared/reenact/slurm-logs");
  EXPECT_EQ(options->max_pending, 2);
  EXPECT_EQ(options->max_jobs, 8);
  EXPECT_DOUBLE_EQ(options->start_grace_s, 20);
  // What the config does not set keeps its default.
  EXPECT_EQ(options->sbatch, "sbatch");
}

TEST(SlurmConfig, RequiredKeysAloneGiveDefaults) {
  absl::StatusOr<SlurmLauncherOptions> options =
      ParseSlurmConfigText("worker = /w\r\nserver = h:1\r\nlog_dir = /l\r\n", "c");
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->worker, "/w");
  EXPECT_EQ(options->cpus_per_task, 0);
  EXPECT_DOUBLE_EQ(options->worker_wait_s, 60);
  EXPECT_EQ(options->max_pending, 4);
  EXPECT_EQ(options->max_jobs, 16);
  EXPECT_TRUE(options->extra_sbatch_args.empty());
}

TEST(SlurmConfig, ReadsAFileAndSaysWhenItIsMissing) {
  const std::string dir = reenact::testing::MakeTempDir("slurm_config");
  const std::string path = dir + "/slurm-workers.conf";
  WriteFile(path, kGoodConfig);
  absl::StatusOr<SlurmLauncherOptions> options = ParseSlurmConfig(path);
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->partition, "gpu");

  WriteFile(path, "worker = /w\nserver = h:1\nlog_dir = /l\nmax_jobs = many\n");
  options = ParseSlurmConfig(path);
  EXPECT_EQ(options.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(options.status().message(), HasSubstr(path + ":4: max_jobs"));

  options = ParseSlurmConfig(dir + "/missing.conf");
  EXPECT_EQ(options.status().code(), absl::StatusCode::kNotFound);
  std::filesystem::remove_all(dir);
}

// The error of `text` after the three required keys (lines 1 to 3).
absl::Status ErrorOf(const std::string& text) {
  return ParseSlurmConfigText("worker = /w\nserver = h:1\nlog_dir = /l\n" + text, "cfg").status();
}

TEST(SlurmConfig, ErrorsNameTheLineAndTheKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"colour = blue", "cfg:4: unknown key \"colour\""},
      {"# a comment\nmax_pending = 0", "cfg:5: max_pending: \"0\" is not an integer >= 1"},
      {"max_jobs = 3x", "cfg:4: max_jobs: \"3x\" is not an integer >= 1"},
      {"cpus_per_task = -1", "cfg:4: cpus_per_task: \"-1\" is not an integer >= 0"},
      {"\n\nworker_wait_s = soon", "cfg:6: worker_wait_s: \"soon\" is not seconds >= 0"},
      {"worker_wait_s = -2", "cfg:4: worker_wait_s: \"-2\" is not seconds >= 0"},
      {"worker_wait_s = inf", "cfg:4: worker_wait_s: \"inf\" is not seconds >= 0"},
      {"start_grace_s = 1s", "cfg:4: start_grace_s: \"1s\" is not seconds >= 0"},
      {"max_jobs = 99999999999", "cfg:4: max_jobs: \"99999999999\" is not an integer >= 1"},
      {"partition", "cfg:4: expected `key = value`"},
      {"partition =", "cfg:4: partition: no value"},
      {"partition = a\npartition = b", "cfg:5: partition: given again (first on line 4)"},
      {"server = h:2", "cfg:4: server: given again (first on line 2)"},
      {"sbatch_arg = gres", "cfg: sbatch_arg: \"gres\" is not a flag"},
  };
  for (const auto& [text, message] : cases) {
    const absl::Status status = ErrorOf(text);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << text;
    EXPECT_THAT(status.message(), HasSubstr(message)) << text;
  }
}

TEST(SlurmConfig, MissingRequiredKeysAreNamed) {
  for (const std::string key : {"worker", "server", "log_dir"}) {
    std::string text;
    for (const std::string other : {"worker = /w", "server = h:1", "log_dir = /l"}) {
      if (!absl::StartsWith(other, key + " ")) absl::StrAppend(&text, other, "\n");
    }
    const absl::Status status = ParseSlurmConfigText(text, "cfg").status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << key;
    EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("cfg: missing required key \"", key)));
  }
}

// ---- Options ---------------------------------------------------------------

SlurmLauncherOptions ValidOptions() {
  SlurmLauncherOptions options;
  options.worker = "/opt/reenact-worker";
  options.server_address = "head:50051";
  options.log_dir = "/var/log/reenact";
  return options;
}

TEST(SlurmLauncherOptions, ValidateNamesTheBadOption) {
  EXPECT_TRUE(ValidOptions().Validate().ok());
  const std::vector<std::pair<std::function<void(SlurmLauncherOptions&)>, std::string>> cases = {
      {[](auto& o) { o.worker.clear(); }, "worker: required"},
      {[](auto& o) { o.server_address.clear(); }, "server: required"},
      {[](auto& o) { o.server_address = "head"; }, "server: \"head\" is not HOST:PORT"},
      {[](auto& o) { o.server_address = "head:0"; }, "is not HOST:PORT"},
      {[](auto& o) { o.server_address = ":50051"; }, "is not HOST:PORT"},
      {[](auto& o) { o.log_dir.clear(); }, "log_dir: required"},
      {[](auto& o) { o.log_dir = "/logs/%u"; }, "log_dir: must not contain '%'"},
      {[](auto& o) { o.cpus_per_task = -1; }, "cpus_per_task"},
      {[](auto& o) { o.worker_wait_s = -1; }, "worker_wait_s"},
      {[](auto& o) { o.start_grace_s = -1; }, "start_grace_s"},
      {[](auto& o) { o.max_pending = 0; }, "max_pending"},
      {[](auto& o) { o.max_jobs = 0; }, "max_jobs"},
      {[](auto& o) {
         o.extra_sbatch_args = {"--gres=gpu:1", "gpu"};
       },
       "sbatch_arg: \"gpu\""},
      {[](auto& o) { o.squeue.clear(); }, "squeue"},
  };
  for (const auto& [change, message] : cases) {
    SlurmLauncherOptions options = ValidOptions();
    change(options);
    const absl::Status status = options.Validate();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << message;
    EXPECT_THAT(status.message(), HasSubstr(message));
  }
  SlurmLauncherOptions ipv6 = ValidOptions();
  ipv6.server_address = "[::1]:50051";
  EXPECT_TRUE(ipv6.Validate().ok());
}

// ---- Quoting and the batch job's command -----------------------------------

TEST(ShellQuote, LeavesPlainWordsAndQuotesTheRest) {
  EXPECT_EQ(ShellQuote("/opt/reenact/bin/reenact-worker"), "/opt/reenact/bin/reenact-worker");
  EXPECT_EQ(ShellQuote("head.cluster:50051"), "head.cluster:50051");
  EXPECT_EQ(ShellQuote(""), "''");
  EXPECT_EQ(ShellQuote("a b"), "'a b'");
  EXPECT_EQ(ShellQuote("$HOME"), "'$HOME'");
  EXPECT_EQ(ShellQuote("it's"), "'it'\\''s'");
  EXPECT_EQ(ShellQuote("~"), "'~'");
  EXPECT_EQ(ShellQuote("a=b"), "'a=b'");
}

TEST(ShellQuote, ShellGivesBackTheText) {
  const std::vector<std::string> texts = {
      "",          "plain",       "two words",
      "it's",      "\"double\"",  "$HOME and ${PATH}",
      "`date`",    "back\\slash", "semi;colon && pipe | star * ?",
      "new\nline", "'",           "''",
      "tab\there", "-dash",       "#hash",
      "!bang"};
  for (const std::string& text : texts) {
    const ToolOutput output = RunTool({"/bin/sh", "-c", "printf '%s' " + ShellQuote(text)});
    EXPECT_EQ(output.exit_code, 0) << text << ": " << output.err;
    EXPECT_EQ(output.out, text) << ShellQuote(text);
  }
}

TEST(SlurmLauncher, BatchJobOfReadsWorkerNames) {
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-123"), "123");
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-7"), "7");
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-12a"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-1 2"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job--5"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf("worker-3"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf("xslurm-job-3"), std::nullopt);
  EXPECT_EQ(SlurmLauncher::BatchJobOf(""), std::nullopt);
}

TEST(SlurmLauncher, SbatchArgsCarryEveryOption) {
  SlurmLauncherOptions options = ValidOptions();
  options.log_dir = "/var/log/reenact/";
  EXPECT_THAT(SbatchArgs(options),
              ElementsAre("--parsable", "--job-name=reenact-worker",
                          "--output=/var/log/reenact/slurm-%j.out", "--wrap",
                          "exec /opt/reenact-worker --server head:50051 --once --wait 60 "
                          "--name \"slurm-job-$SLURM_JOB_ID\""));

  options = *ParseSlurmConfigText(kGoodConfig, "c");
  options.scratch = "/scratch/my dir";
  options.worker_wait_s = 2.5;
  EXPECT_THAT(SbatchArgs(options),
              ElementsAre("--parsable", "--job-name=reenact-worker",
                          "--output=/shared/reenact/slurm-logs/slurm-%j.out", "--partition=gpu",
                          "--account=vision", "--time=02:00:00", "--mem=8G", "--qos=normal",
                          "--cpus-per-task=4", "--gres=gpu:1", "--constraint=a100", "--wrap",
                          "exec /opt/reenact/bin/reenact-worker --server head.cluster:50051 "
                          "--once --wait 2.5 --name \"slurm-job-$SLURM_JOB_ID\" "
                          "--token-file /home/reenact/token --tls-ca /home/reenact/ca.pem "
                          "--scratch '/scratch/my dir'"));
}

// ---- The launcher with stand-in Slurm programs -----------------------------

// sbatch, squeue and scancel as small scripts: sbatch records its calls and
// prints ids from 101 on, squeue prints `squeue.out`, scancel records its
// calls.
class FakeSlurmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = reenact::testing::MakeTempDir("fake_slurm");
    WriteScript(dir_ + "/sbatch", absl::StrCat(R"(#!/bin/sh
if [ "$1" = --version ]; then echo "slurm 0.0.0"; exit 0; fi
d=)",
                                               dir_, R"(
echo "$*" >> "$d/sbatch.calls"
echo "$(( $(wc -l < "$d/sbatch.calls") + 100 ));fake-cluster"
)"));
    WriteScript(dir_ + "/squeue", absl::StrCat("#!/bin/sh\ncat ", dir_, "/squeue.out\n"));
    WriteScript(dir_ + "/scancel",
                absl::StrCat("#!/bin/sh\necho \"$*\" >> ", dir_, "/scancel.calls\n"));
    WriteFile(dir_ + "/squeue.out", "");
    options_ = ValidOptions();
    options_.log_dir = dir_ + "/logs";
    options_.sbatch = dir_ + "/sbatch";
    options_.squeue = dir_ + "/squeue";
    options_.scancel = dir_ + "/scancel";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::vector<std::string> Calls(const std::string& name) const {
    const std::string calls = ReadFileToString(dir_ + "/" + name + ".calls").value_or("");
    return absl::StrSplit(calls, '\n', absl::SkipEmpty());
  }

  std::string dir_;
  SlurmLauncherOptions options_;
};

TEST_F(FakeSlurmTest, CreateChecksSbatchAndMakesTheLogFolder) {
  absl::StatusOr<std::unique_ptr<SlurmLauncher>> launcher = SlurmLauncher::Create(options_);
  ASSERT_TRUE(launcher.ok()) << launcher.status();
  EXPECT_TRUE(std::filesystem::is_directory(dir_ + "/logs"));

  options_.sbatch = dir_ + "/no-such-sbatch";
  launcher = SlurmLauncher::Create(options_);
  EXPECT_EQ(launcher.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(launcher.status().message(), HasSubstr("no-such-sbatch"));

  options_.sbatch = "/bin/false";
  EXPECT_EQ(SlurmLauncher::Create(options_).status().code(), absl::StatusCode::kFailedPrecondition);
  options_.worker.clear();
  EXPECT_EQ(SlurmLauncher::Create(options_).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST_F(FakeSlurmTest, SubmitsWithinThePendingAndTotalLimits) {
  options_.max_pending = 3;
  options_.max_jobs = 4;
  auto launcher = *SlurmLauncher::Create(options_);
  launcher->Reconcile(10);
  EXPECT_EQ(launcher->submitted_total(), 3);
  EXPECT_EQ(launcher->pending(), 3);
  EXPECT_EQ(launcher->running(), 0);
  const std::vector<std::string> calls = Calls("sbatch");
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_THAT(calls[0], HasSubstr("--output=" + dir_ + "/logs/slurm-%j.out"));

  // Two start running: squeue is asked again after a second at most, and
  // one more batch job makes max_jobs.
  WriteFile(dir_ + "/squeue.out", "101 RUNNING\n102 CONFIGURING\n103 PENDING\n");
  EXPECT_TRUE(PollUntil(
      5, [&] { return launcher->running() == 2; }, [&] { launcher->Reconcile(10); }));
  EXPECT_EQ(launcher->submitted_total(), 4);
  EXPECT_EQ(launcher->pending(), 2);

  // All end (one still listed as COMPLETED); none is wanted any more.
  WriteFile(dir_ + "/squeue.out", "101 COMPLETED\n");
  EXPECT_TRUE(PollUntil(
      5, [&] { return launcher->pending() + launcher->running() == 0; },
      [&] { launcher->Reconcile(0); }));
  EXPECT_EQ(launcher->submitted_total(), 4);
}

TEST_F(FakeSlurmTest, StartedBatchJobsStandForQueuedJobsForAWhile) {
  options_.start_grace_s = 0.5;
  auto launcher = *SlurmLauncher::Create(options_);
  launcher->Reconcile(2);
  ASSERT_EQ(launcher->submitted_total(), 2);
  WriteFile(dir_ + "/squeue.out", "101 RUNNING\n102 RUNNING\n");
  EXPECT_TRUE(PollUntil(
      5, [&] { return launcher->running() == 2; }, [&] { launcher->Reconcile(2); }));
  EXPECT_EQ(launcher->submitted_total(), 2);
  // Two jobs still wait after the grace: their workers took none.
  EXPECT_TRUE(PollUntil(
      5, [&] { return launcher->submitted_total() == 4; }, [&] { launcher->Reconcile(2); }));
  EXPECT_EQ(launcher->pending(), 2);
}

TEST_F(FakeSlurmTest, BacksOffWhenSbatchFails) {
  auto launcher = *SlurmLauncher::Create(options_);
  const auto count_runs = [&] {
    return ReadFileToString(dir_ + "/sbatch.runs").value_or("").size();
  };
  // Every run of the failing sbatch leaves a mark.
  WriteScript(dir_ + "/sbatch", absl::StrCat("#!/bin/sh\n[ \"$1\" = --version ] && exit 0\n"
                                             "printf x >> ",
                                             dir_, "/sbatch.runs\nexit 1\n"));
  for (int i = 0; i < 5; ++i) launcher->Reconcile(1);
  EXPECT_EQ(count_runs(), 1u);
  EXPECT_EQ(launcher->submitted_total(), 0);
  EXPECT_EQ(launcher->pending(), 0);

  // It tries again after the back-off, and goes on once sbatch works.
  EXPECT_TRUE(PollUntil(
      5, [&] { return count_runs() >= 2; }, [&] { launcher->Reconcile(1); }));
  WriteScript(dir_ + "/sbatch", "#!/bin/sh\necho 7\n");
  EXPECT_TRUE(PollUntil(
      10, [&] { return launcher->submitted_total() == 1; }, [&] { launcher->Reconcile(1); }));
  EXPECT_EQ(launcher->pending(), 1);
}

TEST_F(FakeSlurmTest, CancelAndShutdownOnlyTouchItsOwnBatchJobs) {
  auto launcher = *SlurmLauncher::Create(options_);
  launcher->Reconcile(2);
  ASSERT_EQ(launcher->pending(), 2);
  EXPECT_EQ(launcher->Cancel("999").code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(Calls("scancel").empty());

  EXPECT_TRUE(launcher->Cancel("101").ok());
  EXPECT_THAT(Calls("scancel"), ElementsAre("101"));
  EXPECT_EQ(launcher->pending(), 1);
  EXPECT_EQ(launcher->Cancel("101").code(), absl::StatusCode::kNotFound);

  WriteFile(dir_ + "/squeue.out", "102 PENDING\n");
  launcher->Shutdown();
  EXPECT_THAT(Calls("scancel"), ElementsAre("101", "--state=PENDING 102"));
  // This scancel fails to cancel it: a second Shutdown tries again.
  launcher->Shutdown();
  EXPECT_THAT(Calls("scancel"), ElementsAre("101", "--state=PENDING 102", "--state=PENDING 102"));
  WriteFile(dir_ + "/squeue.out", "");
  launcher->Shutdown();
  EXPECT_EQ(launcher->pending(), 0);
  launcher->Shutdown();
  EXPECT_EQ(Calls("scancel").size(), 4u);
  // No submits after Shutdown.
  launcher->Reconcile(5);
  EXPECT_EQ(launcher->submitted_total(), 2);

  WriteScript(options_.scancel, "#!/bin/sh\necho 'scancel: error: no' >&2\nexit 1\n");
  auto other = *SlurmLauncher::Create(options_);
  other->Reconcile(1);
  const absl::Status cancelled = other->Cancel("103");  // sbatch's third id.
  EXPECT_EQ(cancelled.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(cancelled.message(), HasSubstr("scancel: error: no"));
  EXPECT_EQ(other->pending(), 1);
}

// ---- The launcher with a real one-node Slurm cluster -----------------------

// A worker that records its job id and arguments (NUL-separated) in
// argv.<job id>, then runs until release.<job id> exists (30 s at most).
constexpr char kRecordingWorker[] = R"(#!/bin/sh
d=DIR
{ printf '%s\0' "$SLURM_JOB_ID"; for arg in "$@"; do printf '%s\0' "$arg"; done; } > "$d/argv.$SLURM_JOB_ID.tmp"
mv "$d/argv.$SLURM_JOB_ID.tmp" "$d/argv.$SLURM_JOB_ID"
i=0
while [ ! -e "$d/release.$SLURM_JOB_ID" ] && [ $i -lt 300 ]; do sleep 0.1; i=$((i + 1)); done
)";

class SlurmClusterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    cluster_ = testing::SlurmTestCluster::Start(REENACT_SLURM_TEST_CLUSTER, &why);
    if (cluster_ == nullptr) GTEST_SKIP() << "SKIPPED: " << why;
    dir_ = cluster_->dir();
    env_ = cluster_->env();
    files_ = dir_ + "/test";
    std::filesystem::create_directories(files_ + "/bin dir");
    // No blank in the file name itself: Slurm's proctrack/linuxproc reads
    // /proc/PID/stat with scanf and would miss a process whose name has one.
    worker_ = files_ + "/bin dir/worker's-$x.sh";
    std::string script = kRecordingWorker;
    script.replace(script.find("DIR"), 3, ShellQuote(files_));
    WriteScript(worker_, script);
  }

  void TearDown() override { cluster_.reset(); }

  SlurmLauncherOptions Options() const {
    SlurmLauncherOptions options;
    options.worker = worker_;
    options.server_address = "head.example:50051";
    options.token_file = files_ + "/tok'en \"file\"";
    options.tls_ca = files_ + "/ca $HOME.pem";
    options.scratch = files_ + "/scratch\\dir `x`";
    options.worker_wait_s = 7.5;
    options.log_dir = files_ + "/logs";
    options.env = env_;
    return options;
  }

  std::map<std::string, std::string> Squeue() const { return cluster_->Squeue(); }

  // The arguments the worker of batch job `id` recorded (its job id first);
  // empty until it ran.
  std::vector<std::string> RecordedArgv(const std::string& id) const {
    const std::string text = ReadFileToString(files_ + "/argv." + id).value_or("");
    return absl::StrSplit(text, '\0', absl::SkipEmpty());
  }

  std::vector<std::string> BatchJobIds() const {
    std::vector<std::string> ids;
    for (const auto& [id, state] : Squeue()) ids.push_back(id);
    return ids;
  }

  std::string dir_;
  std::string files_;
  std::string worker_;
  std::map<std::string, std::string> env_;
  std::unique_ptr<testing::SlurmTestCluster> cluster_;
};

TEST_F(SlurmClusterTest, RunsWorkersCancelsAndEnds) {
  SlurmLauncherOptions options = Options();
  absl::StatusOr<std::unique_ptr<SlurmLauncher>> created = SlurmLauncher::Create(options);
  ASSERT_TRUE(created.ok()) << created.status();
  SlurmLauncher& launcher = **created;

  // Two queued jobs: two batch jobs, however often it is asked while they
  // wait and while their workers start.
  launcher.Reconcile(2);
  EXPECT_EQ(launcher.submitted_total(), 2);
  EXPECT_EQ(launcher.pending(), 2);
  const std::vector<std::string> ids = BatchJobIds();
  ASSERT_EQ(ids.size(), 2u);
  EXPECT_TRUE(PollUntil(
      20, [&] { return launcher.running() == 2; },
      [&] {
        launcher.Reconcile(2);
        EXPECT_EQ(launcher.submitted_total(), 2);
      }));
  EXPECT_EQ(launcher.pending(), 0);
  launcher.Reconcile(2);
  EXPECT_EQ(launcher.submitted_total(), 2);
  // From here on the workers have leased the two jobs: none is queued.

  // Each worker got its batch job's name and the quoted values intact.
  for (const std::string& id : ids) {
    EXPECT_TRUE(PollUntil(10, [&] { return !RecordedArgv(id).empty(); })) << id;
    const std::vector<std::string> expected = {id,
                                               "--server",
                                               options.server_address,
                                               "--once",
                                               "--wait",
                                               "7.5",
                                               "--name",
                                               "slurm-job-" + id,
                                               "--token-file",
                                               options.token_file,
                                               "--tls-ca",
                                               options.tls_ca,
                                               "--scratch",
                                               options.scratch};
    EXPECT_THAT(RecordedArgv(id), ElementsAreArray(expected));
    EXPECT_EQ(SlurmLauncher::BatchJobOf("slurm-job-" + id), id);
  }

  // Cancel ends the first one.
  ASSERT_TRUE(launcher.Cancel(ids[0]).ok());
  EXPECT_EQ(launcher.running(), 1);
  EXPECT_TRUE(PollUntil(10, [&] { return Squeue().count(ids[0]) == 0; }));

  // Shutdown leaves the running one alone (nothing is pending).
  launcher.Shutdown();
  EXPECT_EQ(Squeue()[ids[1]], "RUNNING");
  EXPECT_EQ(launcher.running(), 1);

  // The second one ends by itself; Reconcile learns it and submits no more.
  WriteFile(files_ + "/release." + ids[1], "");
  EXPECT_TRUE(PollUntil(
      15, [&] { return launcher.running() == 0; }, [&] { launcher.Reconcile(0); }));
  launcher.Reconcile(2);
  EXPECT_EQ(launcher.submitted_total(), 2);
  EXPECT_TRUE(PollUntil(10, [&] { return Squeue().empty(); }));
  EXPECT_TRUE(std::filesystem::exists(options.log_dir + "/slurm-" + ids[1] + ".out"));
}

TEST_F(SlurmClusterTest, ShutdownCancelsThePendingBatchJobs) {
  SlurmLauncherOptions options = Options();
  options.max_pending = 2;
  // They may not start for an hour: they stay pending.
  options.extra_sbatch_args = {"--begin=now+3600"};
  absl::StatusOr<std::unique_ptr<SlurmLauncher>> created = SlurmLauncher::Create(options);
  ASSERT_TRUE(created.ok()) << created.status();
  SlurmLauncher& launcher = **created;

  // Five queued jobs, but at most two batch jobs pending.
  for (int i = 0; i < 3; ++i) launcher.Reconcile(5);
  EXPECT_EQ(launcher.submitted_total(), 2);
  EXPECT_EQ(launcher.pending(), 2);
  std::map<std::string, std::string> states = Squeue();
  ASSERT_EQ(states.size(), 2u);
  for (const auto& [id, state] : states) EXPECT_EQ(state, "PENDING") << id;

  launcher.Shutdown();
  EXPECT_EQ(launcher.pending(), 0);
  EXPECT_TRUE(PollUntil(10, [&] { return Squeue().empty(); }));
  launcher.Shutdown();
  launcher.Reconcile(5);
  EXPECT_EQ(launcher.submitted_total(), 2);
}

}  // namespace
}  // namespace reenact::server
