#include "server/worker/worker_protocol.h"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/base/time.h"
#include "common/testing/test_data.h"
#include "server/worker/eta.h"

namespace reenact::server {
namespace {

using ::testing::ElementsAre;
using ::testing::IsEmpty;

void Append(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::app);
  out << text;
}

TEST(WorkerProtocol, ProgressLineSetsStageFractionAndFrames) {
  WorkerReport report;
  std::vector<std::string> logs;
  EXPECT_TRUE(ApplyWorkerLine(
      R"({"stage":"register","fraction":0.42,"frames_done":120,"frames_total":300})", report,
      &logs));
  EXPECT_EQ(report.progress.stage(), "register");
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.42);
  EXPECT_EQ(report.progress.frames_done(), 120);
  EXPECT_EQ(report.progress.frames_total(), 300);
  EXPECT_THAT(logs, IsEmpty());

  // Frames alone are no progress (no stage, no fraction), yet are kept.
  EXPECT_FALSE(ApplyWorkerLine(R"({"frames_done":121})", report, &logs));
  EXPECT_EQ(report.progress.frames_done(), 121);
  // A fraction alone is progress; the stage stays.
  EXPECT_TRUE(ApplyWorkerLine(R"({"fraction":0.5})", report, &logs));
  EXPECT_EQ(report.progress.stage(), "register");
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.5);
  // Frames that are not integers are ignored.
  EXPECT_FALSE(ApplyWorkerLine(R"({"frames_done":1.5,"frames_total":"9"})", report, &logs));
  EXPECT_EQ(report.progress.frames_done(), 121);
  EXPECT_EQ(report.progress.frames_total(), 300);
}

TEST(WorkerProtocol, FractionIsClampedToZeroOne) {
  WorkerReport report;
  std::vector<std::string> logs;
  EXPECT_TRUE(ApplyWorkerLine(R"({"fraction":1.7})", report, &logs));
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 1.0);
  EXPECT_TRUE(ApplyWorkerLine(R"({"fraction":-0.3})", report, &logs));
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.0);
  EXPECT_TRUE(ApplyWorkerLine(R"({"fraction":0.25})", report, &logs));
  // JSON has no NaN or infinity, and a number too large for a double does
  // not parse: the line is a log line and the fraction stays.
  EXPECT_FALSE(ApplyWorkerLine(R"({"fraction":1e999})", report, &logs));
  EXPECT_THAT(logs, ElementsAre(R"({"fraction":1e999})"));
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.25);
  // A fraction that is no number is no progress.
  EXPECT_FALSE(ApplyWorkerLine(R"({"fraction":"0.9"})", report, &logs));
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.25);
}

TEST(WorkerProtocol, LogErrorAndResultLinesGoToTheWatchers) {
  WorkerReport report;
  std::vector<std::string> logs;
  EXPECT_FALSE(ApplyWorkerLine(R"({"log":"loading the take"})", report, &logs));
  EXPECT_FALSE(ApplyWorkerLine(R"({"result":{"frames":30}})", report, &logs));
  EXPECT_FALSE(ApplyWorkerLine(R"({"error":"no usable instant"})", report, &logs));
  EXPECT_THAT(logs, ElementsAre("loading the take", R"(result: {"frames":30})",
                                "error: no usable instant"));
  EXPECT_EQ(report.last_log, "loading the take");
  EXPECT_EQ(report.error, "no usable instant");
  // A log line that is no string is ignored.
  EXPECT_FALSE(ApplyWorkerLine(R"({"log":42})", report, &logs));
  EXPECT_EQ(logs.size(), 3u);
}

TEST(WorkerProtocol, ALineThatIsNoJsonObjectIsALogLine) {
  WorkerReport report;
  std::vector<std::string> logs;
  EXPECT_FALSE(ApplyWorkerLine(R"({"stage":"fit", "fraction":)", report, &logs));
  EXPECT_FALSE(ApplyWorkerLine("[1,2]", report, &logs));
  EXPECT_FALSE(ApplyWorkerLine("plain text", report, &logs));
  EXPECT_THAT(logs, ElementsAre(R"({"stage":"fit", "fraction":)", "[1,2]", "plain text"));
  EXPECT_EQ(report.last_log, "plain text");
  EXPECT_EQ(report.progress.stage(), "");
  // Log lines and stage names are cut.
  EXPECT_FALSE(ApplyWorkerLine(std::string(3000, 'x'), report, &logs));
  EXPECT_EQ(logs.back(), std::string(kMaxWorkerLogLineChars, 'x') + "...");
  EXPECT_TRUE(ApplyWorkerLine(R"({"stage":")" + std::string(100, 's') + R"("})", report, &logs));
  EXPECT_EQ(report.progress.stage(), std::string(64, 's') + "...");
}

TEST(WorkerProtocol, LinesAreAppliedUpToThePartialLastOne) {
  WorkerReport report;
  std::vector<std::string> logs;
  std::string pending =
      "{\"stage\":\"load\",\"fraction\":0.1}\r\n\n{\"log\":\"a\"}\n{\"stage\":\"fi";
  EXPECT_TRUE(ApplyWorkerLines(pending, report, &logs));
  EXPECT_EQ(report.progress.stage(), "load");
  EXPECT_THAT(logs, ElementsAre("a"));
  EXPECT_EQ(pending, "{\"stage\":\"fi");
  // Nothing new: the partial line waits.
  EXPECT_FALSE(ApplyWorkerLines(pending, report, &logs));
  EXPECT_EQ(pending, "{\"stage\":\"fi");
  pending += "t\",\"fraction\":0.5}\n";
  EXPECT_TRUE(ApplyWorkerLines(pending, report, &logs));
  EXPECT_EQ(report.progress.stage(), "fit");
  EXPECT_DOUBLE_EQ(report.progress.fraction(), 0.5);
  EXPECT_EQ(pending, "");
  // A line with no end that grew too long is taken as it is.
  pending = std::string(kMaxPendingBytes, 'y');
  EXPECT_FALSE(ApplyWorkerLines(pending, report, &logs));
  EXPECT_EQ(pending, "");
  EXPECT_EQ(logs.back(), std::string(kMaxWorkerLogLineChars, 'y') + "...");
}

TEST(WorkerProtocol, ReaderReadsWhatTheWorkerAppends) {
  const std::string path = testing::MakeTempDir("worker_protocol") + "/progress.jsonl";
  v1::JobProgress start;
  start.set_stage("starting");
  start.set_eta_s(-1);
  start.set_frames_done(7);
  WorkerOutputReader reader(path, start);
  std::vector<std::string> logs;
  // No file yet: nothing read, the job's progress kept.
  EXPECT_FALSE(reader.Read(&logs));
  EXPECT_EQ(reader.report().progress.stage(), "starting");
  EXPECT_EQ(reader.report().progress.frames_done(), 7);
  EXPECT_DOUBLE_EQ(reader.report().progress.eta_s(), -1);

  Append(path, "{\"log\":\"hello\"}\n{\"stage\":\"clouds\",\"fraction\":0.2");
  EXPECT_FALSE(reader.Read(&logs));
  EXPECT_THAT(logs, ElementsAre("hello"));
  EXPECT_EQ(reader.report().progress.stage(), "starting");
  Append(path, "}\n");
  EXPECT_TRUE(reader.Read(&logs));
  EXPECT_EQ(reader.report().progress.stage(), "clouds");
  EXPECT_DOUBLE_EQ(reader.report().progress.fraction(), 0.2);
  EXPECT_EQ(reader.report().progress.frames_done(), 7);
  EXPECT_FALSE(reader.Read(&logs));
  EXPECT_EQ(logs.size(), 1u);
}

TEST(WorkerProtocol, ArgsCarryTheJobWithoutLiveOnlyOptions) {
  methods::MethodSpec spec;
  spec.name = "body";
  methods::OptionSpec atlas;
  atlas.name = "atlas_px";
  methods::OptionSpec live_every;
  live_every.name = "live_every";
  live_every.live_only = true;
  spec.options = {atlas, live_every};
  v1::Job job;
  job.set_job_id("J1");
  job.set_take_id("T1");
  job.set_method("body");
  (*job.mutable_options())["atlas_px"] = "256";
  (*job.mutable_options())["live_every"] = "2";
  (*job.mutable_options())["note"] = "x";
  WorkerInvocation invocation;
  invocation.worker_path = "/bin/reenact-worker";
  invocation.take_path = "/data/takes/T1.mcap";
  invocation.out_path = "/data/reenactments/R1.reen";
  invocation.reenactment_id = "R1";
  EXPECT_THAT(WorkerArgs(job, &spec, invocation),
              ElementsAre("/bin/reenact-worker", "--take", "/data/takes/T1.mcap", "--method",
                          "body", "--options-json", R"({"atlas_px":"256","note":"x"})", "--out",
                          "/data/reenactments/R1.reen", "--reenactment-id", "R1", "--take-id", "T1",
                          "--job-id", "J1"));
  // Without a spec nothing is left out; asset roots join with commas.
  invocation.asset_roots = {"/assets/a", "/assets/b"};
  const std::vector<std::string> args = WorkerArgs(job, nullptr, invocation);
  ASSERT_EQ(args.size(), 17u);
  EXPECT_EQ(args[6], R"({"atlas_px":"256","live_every":"2","note":"x"})");
  EXPECT_EQ(args[15], "--assets");
  EXPECT_EQ(args[16], "/assets/a,/assets/b");
}

TEST(WorkerProtocol, LastLogLineIsTheTailsLastLineElseTheLastLog) {
  EXPECT_EQ(LastLogLine("first\nsecond\r\n \n", "from stdout"), "second");
  EXPECT_EQ(LastLogLine("only", ""), "only");
  EXPECT_EQ(LastLogLine("\n\n", "from stdout"), "from stdout");
  EXPECT_EQ(LastLogLine("", ""), "(none)");
  EXPECT_EQ(LastLogLine(std::string(400, 'z'), ""), std::string(kMaxQuotedLogChars, 'z') + "...");
}

TEST(WorkerProtocol, LastWorkerLogReadsOnlyThisAttempt) {
  const std::string path = testing::MakeTempDir("worker_protocol_log") + "/worker.log";
  EXPECT_EQ(LastWorkerLog(path, 0, "no file"), "no file");
  Append(path, "--- attempt 1 ---\nan old failure\n--- attempt 2 ---\n");
  const int64_t offset = static_cast<int64_t>(std::filesystem::file_size(path));
  EXPECT_EQ(LastWorkerLog(path, offset, "from stdout"), "from stdout");
  Append(path, "worker_failed: out of memory\n");
  EXPECT_EQ(LastWorkerLog(path, offset, "from stdout"), "worker_failed: out of memory");
  // Only the tail of a long log is searched: a last line longer than it is
  // cut at its start.
  Append(path, std::string(kLogTailBytes + 100, 'q') + "\n");
  EXPECT_EQ(LastWorkerLog(path, offset, ""), std::string(kMaxQuotedLogChars, 'q') + "...");
}

TEST(Eta, ConstantRateGivesTheTimeLeft) {
  EtaEstimator eta(10.0);
  // 2% a second, sampled every half second for 30 s.
  double last = 0;
  for (int k = 0; k <= 60; ++k) {
    const int64_t t = SecondsToNs(0.5 * k);
    last = eta.Update(t, 0.01 * k);
  }
  // At 60%: 40% left at 2% a second.
  EXPECT_NEAR(last, 20.0, 1e-6);
}

TEST(Eta, TheRateIsMeasuredOverTheWindow) {
  EtaEstimator eta(10.0);
  double last = 0;
  // 1% a second for 20 s, then 2% a second for 20 s (one sample a second).
  for (int k = 0; k <= 40; ++k) {
    const double fraction = k <= 20 ? 0.01 * k : 0.2 + 0.02 * (k - 20);
    last = eta.Update(SecondsToNs(k), fraction);
  }
  // 40% left at the recent 2% a second (not the 1.5% of the whole run).
  EXPECT_NEAR(last, 20.0, 1e-6);
}

TEST(Eta, NoProgressGivesNoEtaAndTheEndGivesZero) {
  EtaEstimator eta(10.0);
  EXPECT_EQ(eta.Update(SecondsToNs(1), 0.3), -1);  // One sample: no rate.
  EXPECT_EQ(eta.Update(SecondsToNs(2), 0.3), -1);
  EXPECT_EQ(eta.Update(SecondsToNs(30), 0.3), -1);
  EXPECT_EQ(eta.Update(SecondsToNs(31), 0.2), -1);  // Going back: no ETA.
  EXPECT_EQ(eta.Update(SecondsToNs(32), 1.0), 0);
  // Two samples at one instant: no rate.
  EtaEstimator same(10.0);
  EXPECT_EQ(same.Update(5, 0.1), -1);
  EXPECT_EQ(same.Update(5, 0.2), -1);
}

}  // namespace
}  // namespace reenact::server
