// The live body model end to end over loopback: the real reenactd plays a
// synthetic 2-sensor take of the procedural body in real time into the real
// reenact-server; as soon as the take shows up RECORDING (`reenact takes
// list`), `reenact jobs submit --method body --live` starts a
// live job and `reenact reenactments follow --json` subscribes to it. The
// preview must bring the mesh first, then posed frames with joints in take
// order, then the end (take complete); the same job then runs the offline
// method and stores a body reenactment. No timing is asserted (the latency
// is bench/live_e2e.cc's business).
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/subprocess.h"
#include "common/synth/synthesizer.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::CommandResult;
using testing::ReadText;
using testing::RunCommand;

// Starts a command in the background with its output in DIR/NAME.out/.err.
std::unique_ptr<Subprocess> StartCommand(const std::string& dir, const std::string& name,
                                         const std::vector<std::string>& argv) {
  SubprocessOptions options;
  options.stdout_path = dir + "/" + name + ".out";
  options.stderr_path = dir + "/" + name + ".err";
  auto child = Subprocess::Start(argv, options);
  EXPECT_TRUE(child.ok()) << child.status();
  return child.ok() ? std::move(*child) : nullptr;
}

class LiveFollowEndToEnd : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::temp_directory_path() / absl::StrCat("reenact_live_e2e_", ::getpid())).string();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (server_ != nullptr) {
      (void)server_->Signal(SIGTERM);
      (void)server_->Wait(20);
    }
    if (std::getenv("REENACT_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(dir_);
  }

  void StartServer() {
    server_ = StartCommand(dir_, "server",
                           {Bin("reenact-server"), "--data", dir_ + "/data", "--listen",
                            "127.0.0.1:0", "--port-file", dir_ + "/server.port", "--jobs", "1"});
    ASSERT_NE(server_, nullptr);
    for (int i = 0; i < 2400 && address_.empty(); ++i) {  // Up to 2 min under load.
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const std::string text = ReadText(dir_ + "/server.port");
      if (const auto nl = text.find('\n'); nl != std::string::npos) address_ = text.substr(0, nl);
    }
    ASSERT_FALSE(address_.empty()) << ReadText(dir_ + "/server.err");
  }

  // The id of the first take `reenact takes list` shows RECORDING (empty
  // after `timeout_s`).
  std::string WaitRecordingTake(double timeout_s) {
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      const CommandResult list = RunCommand(dir_, "takes-list",
                                            {Bin("reenact"), "takes", "list", "--server", address_,
                                             "--state", "recording", "--json"});
      const auto takes = nlohmann::json::parse(list.out, nullptr, false);
      if (list.exit_code == 0 && takes.is_array() && !takes.empty()) {
        return takes[0]["take_id"].get<std::string>();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return "";
  }

  std::string dir_;
  std::unique_ptr<Subprocess> server_;
  std::string address_;
};

TEST_F(LiveFollowEndToEnd, LiveBodyJobFollowsATakeWhileItIsRecorded) {
  synth::SynthOptions synth;
  // The sensors carry the jittered true skeleton (a device SDK stand-in):
  // these floors are the methods' own, apart from the tracker's accuracy.
  synth.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  synth.motion = "builtin:front-kick";
  synth.num_sensors = 2;
  synth.seconds = 2.5;
  synth.color_width = 960;
  synth.color_height = 540;
  synth.ground_truth_mesh = false;
  const std::string source = dir_ + "/source.mcap";
  auto synthesized = synth::SynthesizeTake(synth, source);
  ASSERT_TRUE(synthesized.ok()) << synthesized.status();
  ASSERT_NO_FATAL_FAILURE(StartServer());

  // The daemon plays the take in real time (no --fast), as a sensor would,
  // looped into a 6 s take: the live job starts a worker process and builds
  // its model while the take records, which on a loaded 2-core machine can
  // take more than the 2.5 s of the source alone.
  std::unique_ptr<Subprocess> daemon =
      StartCommand(dir_, "reenactd",
                   {Bin("reenactd"), "--server", address_, "--source", "playback:" + source,
                    "--loop", "--max-seconds", "6", "--once", "--take-name", "live", "--spool",
                    dir_ + "/spool", "--control", "127.0.0.1:0"});
  ASSERT_NE(daemon, nullptr);
  // The take id is the daemon's (time, name and a random suffix): found once
  // the take is open.
  const std::string take_id = WaitRecordingTake(20);
  ASSERT_FALSE(take_id.empty()) << ReadText(dir_ + "/reenactd.err");
  EXPECT_NE(take_id.find("live"), std::string::npos) << take_id;

  CommandResult submit;
  for (int attempt = 0; attempt < 20; ++attempt) {  // Unavailable while the take opens.
    submit = RunCommand(dir_, "submit",
                        {Bin("reenact"), "jobs", "submit", "--server", address_, "--take", take_id,
                         "--method", "body", "--model", "procedural", "--live", "--json"});
    if (submit.exit_code == 0 || submit.err.find("being opened") == std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(submit.exit_code, 0) << submit.err;
  const auto job = nlohmann::json::parse(submit.out, nullptr, false);
  ASSERT_FALSE(job.is_discarded()) << submit.out;
  const std::string job_id = job["job_id"].get<std::string>();
  EXPECT_EQ(job["state"], "running") << submit.out;
  EXPECT_EQ(job["progress"]["stage"], "following") << submit.out;

  std::unique_ptr<Subprocess> follow = StartCommand(
      dir_, "follow",
      {Bin("reenact"), "reenactments", "follow", "--server", address_, "--job", job_id, "--json"});
  ASSERT_NE(follow, nullptr);
  const auto daemon_exit = daemon->Wait(120);
  ASSERT_TRUE(daemon_exit.ok() && daemon_exit->exited && daemon_exit->exit_code == 0)
      << ReadText(dir_ + "/reenactd.err");
  const auto follow_exit = follow->Wait(120);
  ASSERT_TRUE(follow_exit.ok() && follow_exit->exited) << ReadText(dir_ + "/follow.err");
  EXPECT_EQ(follow_exit->exit_code, 0) << ReadText(dir_ + "/follow.err");

  // The preview: mesh, frames in take order with poses and joints, end.
  std::vector<nlohmann::json> events;
  std::istringstream lines(ReadText(dir_ + "/follow.out"));
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    events.push_back(nlohmann::json::parse(line, nullptr, false));
    ASSERT_FALSE(events.back().is_discarded()) << line;
  }
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events.front()["event"], "mesh") << events.front().dump();
  EXPECT_EQ(events.front()["model_name"], "procedural");
  EXPECT_GT(events.front()["vertices"].get<int64_t>(), 1000);
  int frames = 0;
  int64_t previous_sequence = 0, previous_index = -1;
  size_t i = 1;
  for (; i < events.size() && events[i]["event"] != "end"; ++i) {
    const nlohmann::json& e = events[i];
    if (e["event"] == "mesh") continue;  // The settled shape.
    ASSERT_EQ(e["event"], "frame") << e.dump();
    EXPECT_GT(e["sequence"].get<int64_t>(), previous_sequence);
    EXPECT_GT(e["frame_index"].get<int64_t>(), previous_index);
    EXPECT_EQ(e["joints"], 25);
    EXPECT_TRUE(e["valid"].get<bool>());
    EXPECT_GE(e["latency_ms"].get<double>(), 0.0);
    previous_sequence = e["sequence"].get<int64_t>();
    previous_index = e["frame_index"].get<int64_t>();
    ++frames;
  }
  ASSERT_LT(i, events.size()) << "no end event";
  const nlohmann::json& end = events[i];
  EXPECT_EQ(end["reason"], "take_complete") << end.dump();
  EXPECT_GE(end["frames_followed"].get<int64_t>(), frames);
  EXPECT_GE(frames, 10) << "a 6 s take at 30 fps should give more than 10 followed frames";
  ASSERT_EQ(i + 2, events.size());
  EXPECT_TRUE(events.back().contains("summary")) << events.back().dump();
  std::cout << "[ live     ] " << frames << " frames followed; " << events.back().dump() << "\n";

  // The same job goes on offline and stores a body reenactment.
  const CommandResult watch = RunCommand(
      dir_, "watch", {Bin("reenact"), "jobs", "watch", "--job", job_id, "--server", address_}, 900);
  EXPECT_EQ(watch.exit_code, 0) << watch.err << ReadText(dir_ + "/server.err");
  const CommandResult shown =
      RunCommand(dir_, "show",
                 {Bin("reenact"), "jobs", "show", "--job", job_id, "--server", address_, "--json"});
  const auto finished = nlohmann::json::parse(shown.out, nullptr, false);
  ASSERT_FALSE(finished.is_discarded()) << shown.out;
  EXPECT_EQ(finished["state"], "succeeded") << shown.out;
  EXPECT_EQ(finished["attempts"], 1) << shown.out;
  const std::string reenactment = finished["reenactment_id"].get<std::string>();
  ASSERT_FALSE(reenactment.empty());
  const CommandResult summary = RunCommand(
      dir_, "reenactment-show",
      {Bin("reenact"), "reenactments", "show", reenactment, "--server", address_, "--json"});
  ASSERT_EQ(summary.exit_code, 0) << summary.err;
  const auto stored = nlohmann::json::parse(summary.out, nullptr, false);
  ASSERT_FALSE(stored.is_discarded()) << summary.out;
  EXPECT_EQ(stored["method"], "body");
  EXPECT_EQ(stored["take_id"], take_id);
  EXPECT_EQ(stored["job_id"], job_id);
  EXPECT_FALSE(stored["options"].contains("live")) << summary.out;
  ASSERT_TRUE(stored.contains("body")) << summary.out;
  EXPECT_EQ(stored["body"]["model_name"], "procedural");
  EXPECT_GT(stored["frame_count"].get<int64_t>(), 60);
}

}  // namespace
}  // namespace reenact
