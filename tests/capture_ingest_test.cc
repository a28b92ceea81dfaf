// End to end over loopback: the real `reenactd` plays synthetic takes into the
// real `reenact-server`, and the take the server stores is compared with the
// source frame by frame. Faults: the server is SIGKILLed mid-take and
// restarted on the same port; a sensor's stream ends mid-take.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "capture_daemon/sensors/fakenect_recording.h"
#include "clients/sdk/jobs_client.h"
#include "clients/sdk/reenactments_client.h"
#include "clients/sdk/takes_client.h"
#include "common/base/subprocess.h"
#include "common/io/depth_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "common/tracking/training_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::ReadText;

// Waits until `path` exists and is non-empty; returns its first line.
std::string WaitForLine(const std::string& path, double timeout_s, Subprocess* process) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    std::string text = ReadText(path);
    if (const auto nl = text.find('\n'); nl != std::string::npos) return text.substr(0, nl);
    if (process != nullptr && !process->Running()) return "";
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return "";
}

// Mean, median and share within 10 cm of joint errors (metres).
struct ErrorFigures {
  double mean_mm = 0.0;
  double median_mm = 0.0;
  double within_10cm = 0.0;
};
ErrorFigures Figures(std::vector<double> errors_m) {
  ErrorFigures f;
  if (errors_m.empty()) return f;
  std::sort(errors_m.begin(), errors_m.end());
  double sum_m = 0.0;
  for (const double e : errors_m) sum_m += e;
  const double n = static_cast<double>(errors_m.size());
  f.mean_mm = 1000.0 * sum_m / n;
  f.median_mm = 1000.0 * errors_m[errors_m.size() / 2];
  f.within_10cm = static_cast<double>(std::lower_bound(errors_m.begin(), errors_m.end(), 0.10) -
                                      errors_m.begin()) /
                  n;
  return f;
}

// A reenact-server child on 127.0.0.1. Logs go to <dir>/server.log.
class ServerProcess {
 public:
  explicit ServerProcess(std::string dir) : dir_(std::move(dir)) {}

  // Starts on `listen` ("127.0.0.1:0" picks a port) and waits for the
  // address it bound.
  void Start(const std::string& listen = "127.0.0.1:0") {
    const std::string port_file = dir_ + "/server.port";
    fs::remove(port_file);
    SubprocessOptions options;
    options.stderr_path = dir_ + "/server.log";
    options.stdout_path = dir_ + "/server.log";
    auto child = Subprocess::Start({Bin("reenact-server"), "--data", dir_ + "/data", "--listen",
                                    listen, "--port-file", port_file},
                                   options);
    ASSERT_TRUE(child.ok()) << child.status();
    process_ = std::move(*child);
    address_ = WaitForLine(port_file, 120, process_.get());  // Long under load.
    ASSERT_FALSE(address_.empty()) << "reenact-server did not start:\n"
                                   << ReadText(dir_ + "/server.log");
  }
  void Kill() {
    ASSERT_TRUE(process_->Signal(SIGKILL).ok());
    ASSERT_TRUE(process_->Wait(10).ok());
  }
  void Stop() {
    ASSERT_TRUE(process_->Signal(SIGTERM).ok());
    auto info = process_->Wait(20);
    ASSERT_TRUE(info.ok()) << info.status();
    EXPECT_TRUE(info->exited && info->exit_code == 0) << info->ToString() << "\n"
                                                      << ReadText(dir_ + "/server.log");
  }
  const std::string& address() const { return address_; }
  std::string log() const { return ReadText(dir_ + "/server.log"); }

 private:
  std::string dir_;
  std::unique_ptr<Subprocess> process_;
  std::string address_;
};

std::unique_ptr<Subprocess> StartDaemon(const std::string& dir, std::vector<std::string> args) {
  std::vector<std::string> argv = {Bin("reenactd"), "--control", "127.0.0.1:0", "--spool",
                                   dir + "/spool"};
  argv.insert(argv.end(), args.begin(), args.end());
  SubprocessOptions options;
  options.stderr_path = dir + "/daemon.log";
  options.stdout_path = dir + "/daemon.log";
  auto child = Subprocess::Start(argv, options);
  EXPECT_TRUE(child.ok()) << child.status();
  return child.ok() ? std::move(*child) : nullptr;
}

// Depth payloads of a take: (sensor id, frame index) -> encoded bytes.
using DepthFrames = std::map<std::pair<std::string, int64_t>, std::string>;

DepthFrames ReadDepth(const TakeReader& take) {
  DepthFrames frames;
  for (const auto& [id, calibration] : take.sensors()) {
    auto status = take.ForEach<v1::DepthImage>(
        SensorTopic(id, "depth"), [&](const v1::DepthImage& d) -> absl::Status {
          const auto [it, inserted] = frames.emplace(std::make_pair(id, d.frame_index()), d.data());
          EXPECT_TRUE(inserted) << id << " frame " << d.frame_index() << " stored twice";
          return absl::OkStatus();
        });
    EXPECT_TRUE(status.ok()) << status;
  }
  return frames;
}

// Parses `data` as a `Message` and writes it with `write`.
template <typename Message>
absl::Status Rewrite(const std::string& data, TakeWriter& writer,
                     absl::Status (TakeWriter::*write)(const Message&)) {
  Message message;
  if (!message.ParseFromString(data)) return absl::DataLossError("message does not parse");
  return (writer.*write)(message);
}

// Copies `in` to `out` with every message of `sensor_id` after host-clock
// offset `cut_s` from the start left out: a sensor whose cable is pulled.
void CutSensor(const std::string& in, const std::string& out, const std::string& sensor_id,
               double cut_s) {
  auto reader = TakeReader::Open(in);
  ASSERT_TRUE(reader.ok()) << reader.status();
  auto writer = TakeWriter::Open(out, (*reader)->info());
  ASSERT_TRUE(writer.ok()) << writer.status();
  for (const auto& [id, calibration] : (*reader)->sensors()) {
    ASSERT_TRUE((*writer)->AddSensor(calibration).ok());
  }
  const int64_t cut_ns = (*reader)->info().start_stamp_ns() + static_cast<int64_t>(cut_s * 1e9);
  const std::string prefix = "/sensor/" + sensor_id + "/";
  // File order (the recorded time order), so that playback sees the sensors
  // interleaved as they were captured.
  auto status = (*reader)->mcap().ForEachMessage(
      [&](const McapChannel& channel, const McapMessage& message) -> absl::Status {
        const std::string& topic = channel.topic;
        if (topic.rfind("/sensor/", 0) != 0) return absl::OkStatus();
        if (topic.rfind(prefix, 0) == 0 && static_cast<int64_t>(message.log_time_ns) >= cut_ns) {
          return absl::OkStatus();
        }
        const std::string stream = topic.substr(topic.rfind('/') + 1);
        TakeWriter& w = **writer;
        if (stream == "color") return Rewrite(message.data, w, &TakeWriter::WriteColor);
        if (stream == "depth") return Rewrite(message.data, w, &TakeWriter::WriteDepth);
        if (stream == "mask") return Rewrite(message.data, w, &TakeWriter::WriteMask);
        if (stream == "skeleton") return Rewrite(message.data, w, &TakeWriter::WriteSkeleton);
        return absl::OkStatus();  // Calibration: written by AddSensor.
      });
  ASSERT_TRUE(status.ok()) << status;
  ASSERT_TRUE((*writer)->Close().ok());
}

// Opens `path` with @mcap/core (tests/js/check_take.mjs), an MCAP reader
// written independently of ours, and compares its per-topic message counts
// with ours. Skipped (loudly) without node and the npm packages.
void ExpectIndependentReaderAgrees(const std::string& path, const TakeReader& ours) {
  const std::string js = std::string(REENACT_SOURCE_DIR) + "/tests/js";
  if (std::system("node --version > /dev/null 2>&1") != 0 ||
      !fs::exists(js + "/node_modules/@mcap/core")) {
    std::printf(
        "*** SKIPPED: node or tests/js/node_modules missing; the @mcap/core check of %s "
        "did not run ***\n",
        path.c_str());
    return;
  }
  const std::string out = path + ".check.json";
  const std::string command =
      "node '" + js + "/check_take.mjs' '" + path + "' > '" + out + "' 2>&1";
  const int rc = std::system(command.c_str());
  const std::string text = ReadText(out);
  EXPECT_EQ(rc, 0) << text;
  const nlohmann::json result = nlohmann::json::parse(text, nullptr, false);
  ASSERT_FALSE(result.is_discarded()) << text;
  EXPECT_TRUE(result["problems"].empty()) << result["problems"].dump(2);
  std::map<std::string, uint64_t> theirs, mine;
  for (const auto& [topic, n] : result["counts"].items()) theirs[topic] = n.get<uint64_t>();
  for (const TakeChannel& c : ours.channels()) mine[c.topic] = c.message_count;
  EXPECT_EQ(theirs, mine);
}

class CaptureIngestTest : public ::testing::Test {
 protected:
  // One 2-sensor synthetic take shared by the tests (1.5 s at 30 fps).
  static void SetUpTestSuite() {
    source_dir_ = new std::string(testing::MakeTempDir("capture_ingest_source"));
    source_ = new std::string(*source_dir_ + "/source.mcap");
    synth::SynthOptions options;
    options.motion = "builtin:front-kick";
    options.num_sensors = 2;
    options.seconds = 1.5;
    options.color_width = 960;
    options.color_height = 540;
    options.ground_truth_mesh = false;
    auto summary = synth::SynthesizeTake(options, *source_);
    ASSERT_TRUE(summary.ok()) << summary.status();
  }
  static void TearDownTestSuite() {
    fs::remove_all(*source_dir_);
    delete source_;
    delete source_dir_;
  }

  void SetUp() override {
    dir_ = testing::MakeTempDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  // A failed test keeps its folder (logs, takes) for a look.
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // The single take on the server, downloaded and opened.
  std::unique_ptr<TakeReader> DownloadOnlyTake(const std::string& address, v1::Take* take_out) {
    client::ConnectionOptions options;
    options.address = address;
    client::TakesClient client(options);
    auto takes = client.List();
    EXPECT_TRUE(takes.ok()) << takes.status();
    if (!takes.ok() || takes->size() != 1) {
      ADD_FAILURE() << "expected one take on the server";
      return nullptr;
    }
    *take_out = takes->front();
    const std::string path = dir_ + "/downloaded.mcap";
    auto bytes = client.Download(take_out->take_id(), path);
    EXPECT_TRUE(bytes.ok()) << bytes.status();
    EXPECT_EQ(*bytes, take_out->size_bytes());
    auto reader = TakeReader::Open(path);
    EXPECT_TRUE(reader.ok()) << reader.status();
    if (!reader.ok()) return nullptr;
    EXPECT_TRUE((*reader)->report().complete) << "downloaded take is not a finished MCAP file";
    return std::move(*reader);
  }

  std::string DaemonLog() const { return ReadText(dir_ + "/daemon.log"); }

  // Runs reenactd on the Kinect v1 backend with fakenect playing `recording`
  // into the server at `address` as one take, and waits for a clean exit.
  void RunFakenectDaemon(const std::string& address, const std::string& recording,
                         const std::string& take_name, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {Bin("reenactd"), "--control", "127.0.0.1:0", "--spool",
                                     dir_ + "/spool", "--server",  address,       "--source",
                                     "freenect:0",    "--once",    "--take-name", take_name};
    argv.insert(argv.end(), extra.begin(), extra.end());
    SubprocessOptions options;
    options.env["LD_LIBRARY_PATH"] = FAKENECT_LIBRARY_DIR;
    options.env["FAKENECT_PATH"] = recording;
    options.stderr_path = dir_ + "/daemon.log";
    options.stdout_path = dir_ + "/daemon.log";
    auto daemon = Subprocess::Start(argv, options);
    ASSERT_TRUE(daemon.ok()) << daemon.status();
    auto exit = (*daemon)->Wait(120);
    ASSERT_TRUE(exit.ok()) << exit.status() << "\n" << DaemonLog();
    ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n" << DaemonLog();
  }

  static std::string* source_dir_;
  static std::string* source_;
  std::string dir_;
};

std::string* CaptureIngestTest::source_dir_ = nullptr;
std::string* CaptureIngestTest::source_ = nullptr;

TEST_F(CaptureIngestTest, EveryFrameOfTwoSensorsIsStoredBitIdentical) {
  ServerProcess server(dir_);
  ASSERT_NO_FATAL_FAILURE(server.Start());
  // The body tracker runs on every frame of a source without skeletons
  // (--tracker auto), so the fast playback keeps pace only where the tracker
  // has the cores: the test keeps to the bytes.
  auto daemon = StartDaemon(dir_, {"--server", server.address(), "--source", "playback:" + *source_,
                                   "--fast", "--once", "--take-name", "kick", "--tracker", "off"});
  ASSERT_NE(daemon, nullptr);
  auto exit = daemon->Wait(120);
  ASSERT_TRUE(exit.ok()) << exit.status() << "\n" << DaemonLog();
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n" << DaemonLog();

  auto source = TakeReader::Open(*source_);
  ASSERT_TRUE(source.ok());
  const DepthFrames expected = ReadDepth(**source);
  v1::Take take;
  auto stored = DownloadOnlyTake(server.address(), &take);
  ASSERT_NE(stored, nullptr);
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(take.name(), "kick");
  const DepthFrames got = ReadDepth(*stored);
  ASSERT_EQ(got.size(), expected.size()) << "frames stored vs frames in the source";
  int identical = 0;
  for (const auto& [key, bytes] : expected) {
    auto it = got.find(key);
    ASSERT_NE(it, got.end()) << key.first << " frame " << key.second << " missing";
    identical += it->second == bytes;
  }
  EXPECT_EQ(identical, static_cast<int>(expected.size())) << "depth frames not bit-identical";
  EXPECT_EQ(take.frame_set_count(), (*source)->frame_count());
  for (const auto& sensor : take.sensors()) {
    EXPECT_EQ(sensor.frame_count(), (*source)->frame_count()) << sensor.sensor_id();
  }
  // Colour, masks and skeletons arrived too.
  for (const auto& [id, calibration] : (*source)->sensors()) {
    for (const char* stream : {"color", "mask", "skeleton"}) {
      uint64_t in_source = 0, in_stored = 0;
      for (const auto& c : (*source)->channels()) {
        if (c.topic == SensorTopic(id, stream)) in_source = c.message_count;
      }
      for (const auto& c : stored->channels()) {
        if (c.topic == SensorTopic(id, stream)) in_stored = c.message_count;
      }
      EXPECT_EQ(in_stored, in_source) << SensorTopic(id, stream);
    }
  }

  // The same take through the `reenact takes` commands.
  auto reenact = [&](std::vector<std::string> args) {
    args.insert(args.begin(), Bin("reenact"));
    args.insert(args.end(), {"--server", server.address()});
    SubprocessOptions options;
    options.stdout_path = dir_ + "/cli.out";
    options.stderr_path = dir_ + "/cli.err";
    fs::remove(options.stdout_path);
    auto child = Subprocess::Start(args, options);
    EXPECT_TRUE(child.ok()) << child.status();
    auto info = (*child)->Wait(60);
    EXPECT_TRUE(info.ok()) << info.status();
    return std::make_pair(info.ok() && info->exited ? info->exit_code : -1,
                          ReadText(options.stdout_path));
  };
  auto [list_code, list_json] = reenact({"takes", "list", "--json"});
  ASSERT_EQ(list_code, 0) << ReadText(dir_ + "/cli.err");
  EXPECT_NE(list_json.find("\"take_id\": \"" + take.take_id() + "\""), std::string::npos)
      << list_json;
  auto [show_code, show_text] = reenact({"takes", "show", take.take_id()});
  ASSERT_EQ(show_code, 0) << ReadText(dir_ + "/cli.err");
  EXPECT_NE(show_text.find("complete"), std::string::npos) << show_text;
  const std::string via_cli = dir_ + "/via_cli.mcap";
  auto [download_code, download_text] =
      reenact({"takes", "download", take.take_id(), "--out", via_cli, "--quiet"});
  ASSERT_EQ(download_code, 0) << ReadText(dir_ + "/cli.err");
  EXPECT_EQ(ReadText(via_cli), ReadText(dir_ + "/downloaded.mcap"));
  EXPECT_EQ(reenact({"takes", "show", "no-such-take"}).first, 1);
  auto [delete_code, delete_text] = reenact({"takes", "delete", take.take_id()});
  ASSERT_EQ(delete_code, 0) << ReadText(dir_ + "/cli.err");
  EXPECT_EQ(reenact({"takes", "show", take.take_id()}).first, 1) << "deleted take still shown";
  server.Stop();
}

TEST_F(CaptureIngestTest, ServerKilledMidTakeAndRestartedStoresEveryFrameOnce) {
  ServerProcess server(dir_);
  ASSERT_NO_FATAL_FAILURE(server.Start());
  // Real-time pacing, looping the 1.5 s source for 4 s, so that the kill
  // lands in the middle of the take.
  auto daemon = StartDaemon(dir_, {"--server", server.address(), "--source", "playback:" + *source_,
                                   "--loop", "--max-seconds", "4", "--once"});
  ASSERT_NE(daemon, nullptr);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_NO_FATAL_FAILURE(server.Kill());
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  const std::string address = server.address();
  ASSERT_NO_FATAL_FAILURE(server.Start(address));
  auto exit = daemon->Wait(120);
  ASSERT_TRUE(exit.ok()) << exit.status() << "\n" << DaemonLog();
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n" << DaemonLog();

  v1::Take take;
  auto stored = DownloadOnlyTake(server.address(), &take);
  ASSERT_NE(stored, nullptr);
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  // Every FrameSet once: sequences 1..N without a gap or a repeat.
  auto records = stored->ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  ASSERT_TRUE(records.ok()) << records.status();
  std::set<uint64_t> sequences;
  for (const auto& r : *records) {
    EXPECT_TRUE(sequences.insert(r.sequence()).second) << "sequence " << r.sequence() << " twice";
  }
  ASSERT_FALSE(sequences.empty());
  EXPECT_EQ(*sequences.begin(), 1u);
  EXPECT_EQ(*sequences.rbegin(), sequences.size());
  EXPECT_EQ(static_cast<int64_t>(sequences.size()), take.frame_set_count());
  // Exactly the sets the daemon numbered (its take_stopped event); about 4 s
  // at 30 fps, fewer when a loaded machine makes the real-time playback drop
  // sets before they are numbered (not a loss: they never entered the take).
  const std::string log = DaemonLog();
  const size_t stopped = log.find("take_stopped");
  const size_t field = log.find("frame_sets=", stopped);
  ASSERT_NE(field, std::string::npos) << log;
  const long numbered = std::strtol(log.c_str() + field + 11, nullptr, 10);
  EXPECT_EQ(static_cast<long>(sequences.size()), numbered);
  std::printf("stored %zu frame sets of the %ld the daemon numbered (4 s at 30 fps: 120)\n",
              sequences.size(), numbered);
  EXPECT_GE(static_cast<double>(sequences.size()), 60.0);
  EXPECT_LE(static_cast<double>(sequences.size()), 128.0);
  // Every frame once per sensor, frame indices contiguous, depth identical to
  // the source frame it loops over.
  auto source = TakeReader::Open(*source_);
  ASSERT_TRUE(source.ok());
  const DepthFrames expected = ReadDepth(**source);
  const int64_t source_frames = (*source)->frame_count();
  const DepthFrames got = ReadDepth(*stored);
  std::map<std::string, int64_t> per_sensor;
  int mismatched = 0;
  for (const auto& [key, bytes] : got) {
    ++per_sensor[key.first];
    auto it = expected.find({key.first, key.second % source_frames});
    mismatched += (it == expected.end() || it->second != bytes);
  }
  EXPECT_EQ(mismatched, 0);
  // The server appended to the file after the crash; any MCAP reader must
  // still open it.
  ExpectIndependentReaderAgrees(dir_ + "/downloaded.mcap", *stored);
  for (const auto& [id, count] : per_sensor) {
    EXPECT_EQ(count, static_cast<int64_t>(sequences.size())) << id;
    EXPECT_EQ(got.count({id, count - 1}), 1u) << id << ": frame indices are not 0.." << count - 1;
  }
  server.Stop();
}

TEST_F(CaptureIngestTest, SensorEndingMidTakeLeavesAValidTake) {
  const std::string cut = dir_ + "/cut.mcap";
  ASSERT_NO_FATAL_FAILURE(CutSensor(*source_, cut, "k1", 0.75));
  ServerProcess server(dir_);
  ASSERT_NO_FATAL_FAILURE(server.Start());
  auto daemon = StartDaemon(
      dir_, {"--server", server.address(), "--source", "playback:" + cut, "--fast", "--once"});
  ASSERT_NE(daemon, nullptr);
  auto exit = daemon->Wait(120);
  ASSERT_TRUE(exit.ok()) << exit.status() << "\n" << DaemonLog();
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n" << DaemonLog();

  auto source = TakeReader::Open(cut);
  ASSERT_TRUE(source.ok());
  const DepthFrames expected = ReadDepth(**source);
  v1::Take take;
  auto stored = DownloadOnlyTake(server.address(), &take);
  ASSERT_NE(stored, nullptr);
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  const DepthFrames got = ReadDepth(*stored);
  EXPECT_EQ(got.size(), expected.size());
  int mismatched = 0;
  for (const auto& [key, bytes] : expected) {
    auto it = got.find(key);
    mismatched += (it == got.end() || it->second != bytes);
  }
  EXPECT_EQ(mismatched, 0) << "depth frames missing or not bit-identical";
  std::map<std::string, v1::TakeSensor> sensors;
  for (const auto& s : take.sensors()) sensors[s.sensor_id()] = s;
  ASSERT_EQ(sensors.size(), 2u);
  EXPECT_EQ(sensors["k0"].frame_count(), (*source)->frame_count());
  EXPECT_NEAR(static_cast<double>(sensors["k1"].frame_count()), 0.5 * (*source)->frame_count(),
              1.0);
  EXPECT_EQ(sensors["k0"].lost_stamp_ns(), 0);
  EXPECT_NE(sensors["k1"].lost_stamp_ns(), 0) << "the end of k1's stream was not recorded";
  // The FrameSets after the cut hold k0 only and name k1 as missing.
  auto records = stored->ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_FALSE(records->empty());
  const auto& last = records->back();
  ASSERT_EQ(last.missing_sensor_ids_size(), 1);
  EXPECT_EQ(last.missing_sensor_ids(0), "k1");
  server.Stop();
}

// A Kinect v1 through libfreenect, played by libfreenect's own fakenect
// library from a recording this test writes: reenactd registers the raw depth
// to colour, segments, encodes and streams it like a live Kinect.
TEST_F(CaptureIngestTest, FakenectRecordingStreamsThroughTheKinectV1Backend) {
  const std::string fakenect_dir = FAKENECT_LIBRARY_DIR;
  if (!fs::exists(fakenect_dir + "/libfreenect.so.0.5")) {
    GTEST_SKIP() << "libfreenect's fakenect library is not installed in " << fakenect_dir;
  }
  const std::string recording = dir_ + "/recording";
  fs::create_directories(recording);
  capture::fakenect::WriteRecording(recording);
  ServerProcess server(dir_);
  ASSERT_NO_FATAL_FAILURE(server.Start());
  ASSERT_NO_FATAL_FAILURE(RunFakenectDaemon(server.address(), recording, "kinect-v1", {}));

  v1::Take take;
  auto stored = DownloadOnlyTake(server.address(), &take);
  ASSERT_NE(stored, nullptr);
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  ASSERT_EQ(stored->sensors().size(), 1u);
  const auto& [id, calibration] = *stored->sensors().begin();
  EXPECT_EQ(calibration.model(), "kinect_v1");
  auto depth = stored->ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
  auto color = stored->ReadAll<v1::ColorImage>(SensorTopic(id, "color"));
  ASSERT_TRUE(depth.ok() && color.ok());
  // Every recorded frame, each with its colour.
  EXPECT_EQ(static_cast<int>(depth->size()), capture::fakenect::kFrames);
  EXPECT_EQ(color->size(), depth->size());
  // The moving box 1.2 m away survives registration: its centre in the
  // registered depth reads 1200 mm within the Kinect v1 step there plus the
  // change of camera: registered depth is z in the colour camera, which the
  // Kinect v1 extrinsics (t_z = -10.9 mm and a small rotation) move by up to
  // about 15 mm at this point.
  const double tolerance_mm = capture::fakenect::ToleranceMm(1200.0) + 20.0;
  for (const auto& d : *depth) {
    auto decoded = DecodeDepth(d.data());
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    ASSERT_EQ(decoded->width, d.width_px());
    const int i = static_cast<int>(d.frame_index());
    const int x = 200 + 8 * i + 60, y = 240;
    const double got_mm = decoded->at(x, y);
    EXPECT_NEAR(got_mm, 1200.0, tolerance_mm) << "frame " << i;
    std::printf("fakenect frame %d: box centre %.0f mm (scene 1200 mm)\n", i, got_mm);
  }
  server.Stop();
}

TEST_F(CaptureIngestTest, FakenectRecordingOfAPersonGetsTrackedSkeletons) {
  // A Kinect v1 recording of a person (depth synthesised from a motion that
  // training never saw, structured-light noise) through the Kinect v1
  // backend: reenactd registers the depth, segments nobody (the tracker
  // finds the person itself, and its segmentation becomes the frames'
  // mask) and tracks a skeleton in every frame; a body job on the take
  // fits the body model to it.
  const std::string fakenect_dir = FAKENECT_LIBRARY_DIR;
  if (!fs::exists(fakenect_dir + "/libfreenect.so.0.5")) {
    GTEST_SKIP() << "libfreenect's fakenect library is not installed in " << fakenect_dir;
  }
  const std::string motion = testing::TestDataPath("mocap/cmu/01_01.bvh");
  REENACT_REQUIRE_TEST_FILE(motion);
  const v1::SensorCalibration nominal = capture::KinectV1DefaultCalibration("k", "s");
  auto depth_k = FromProto(nominal.depth_intrinsics());
  ASSERT_TRUE(depth_k.ok()) << depth_k.status();
  tracking::TrainingDataOptions o = tracking::SequenceOptions(motion, 20, 2.0, 2.5, 31);
  o.camera = *depth_k;
  o.structured_light_fraction = 1.0;
  auto images = tracking::SynthesizeTrainingImages(o, /*keep_full_frames=*/true);
  ASSERT_TRUE(images.ok()) << images.status();
  std::vector<capture::fakenect::Frame> frames;
  for (const tracking::TrainingImage& image : *images) {
    ASSERT_EQ(image.full_depth_mm.width, capture::fakenect::kW);
    ASSERT_EQ(image.full_depth_mm.height, capture::fakenect::kH);
    capture::fakenect::Frame f;
    f.depth_mm = image.full_depth_mm.data;
    f.rgb.assign(capture::fakenect::kW * capture::fakenect::kH * 3, 128);
    frames.push_back(std::move(f));
  }
  const std::string recording = dir_ + "/person";
  fs::create_directories(recording);
  capture::fakenect::WriteFrames(recording, frames);
  ServerProcess server(dir_);
  ASSERT_NO_FATAL_FAILURE(server.Start());
  ASSERT_NO_FATAL_FAILURE(RunFakenectDaemon(server.address(), recording, "kinect-v1-person",
                                            {"--segmentation", "off"}));

  v1::Take take;
  auto stored = DownloadOnlyTake(server.address(), &take);
  ASSERT_NE(stored, nullptr);
  ASSERT_EQ(stored->sensors().size(), 1u);
  const auto& [id, calibration] = *stored->sensors().begin();
  // The stored depth camera is the registered one (the colour camera); its
  // world_from_depth takes its points back to the raw depth camera, the
  // frame of the synthesised truth.
  auto world_from_depth = FromProto(calibration.world_from_depth());
  ASSERT_TRUE(world_from_depth.ok());
  auto skeletons = stored->ReadAll<v1::Skeleton>(SensorTopic(id, "skeleton"));
  ASSERT_TRUE(skeletons.ok()) << skeletons.status();
  EXPECT_EQ(static_cast<int>(skeletons->size()), static_cast<int>(frames.size())) << DaemonLog();
  std::vector<double> torso_errors_m;
  for (const v1::Skeleton& skeleton : *skeletons) {
    EXPECT_EQ(skeleton.source(), "reenact-tracker");
    const int64_t i = skeleton.frame_index();
    ASSERT_GE(i, 0);
    ASSERT_LT(i, static_cast<int64_t>(images->size()));
    for (const v1::Joint& joint : skeleton.joints()) {
      const auto j = body::KinectV2JointFromName(joint.name());
      ASSERT_TRUE(j.has_value()) << joint.name();
      if (*j != body::KinectV2Joint::kSpineBase && *j != body::KinectV2Joint::kSpineMid &&
          *j != body::KinectV2Joint::kSpineShoulder) {
        continue;
      }
      const Eigen::Vector3d p = *world_from_depth * FromProto(joint.position_in_depth_m());
      const double error_m = (p - (*images)[i].joints_in_camera_m[body::Index(*j)]).norm();
      torso_errors_m.push_back(error_m);
    }
  }
  ASSERT_FALSE(torso_errors_m.empty());
  const ErrorFigures torso = Figures(torso_errors_m);
  std::printf(
      "fakenect person: %zu skeletons for %zu frames, torso joints from the truth: mean %.1f mm, "
      "median %.1f mm, %.0f %% within 10 cm\n",
      skeletons->size(), frames.size(), torso.mean_mm, torso.median_mm, 100.0 * torso.within_10cm);
  // Without a mask the tracker segments by itself; the head behind the
  // raised arm is a piece of its own that joins the person (step 4 of
  // person_segmentation.h; without it: mean 115 mm, 78 % within 10 cm).
  // Measured: mean 37.5 mm, median 37.7 mm, 100 % within 10 cm.
  EXPECT_LT(torso.mean_mm, 60.0);
  EXPECT_LT(torso.median_mm, 60.0);
  EXPECT_GT(torso.within_10cm, 0.9);

  // The tracker's segmentation went out as the frames' mask (the body index
  // of each skeleton), so the body job sees the person apart from the room.
  auto masks = stored->ReadAll<v1::ActorMask>(SensorTopic(id, "mask"));
  ASSERT_TRUE(masks.ok()) << masks.status();
  EXPECT_EQ(masks->size(), skeletons->size());

  // A body job on the take: it succeeds, and its fitted joints lie on the
  // synthesised person's.
  client::ConnectionOptions connection;
  connection.address = server.address();
  client::JobsClient jobs(connection);
  auto job = jobs.Submit(take.take_id(), "body");
  ASSERT_TRUE(job.ok()) << job.status();
  auto done = jobs.Watch(job->job_id(), [](const v1::JobEvent&) { return true; });
  ASSERT_TRUE(done.ok()) << done.status();
  ASSERT_EQ(done->state(), v1::JOB_STATE_SUCCEEDED) << done->error() << "\n"
                                                    << ReadText(dir_ + "/server.log");
  client::ReenactmentsClient reenactments(connection);
  auto body = reenactments.Fetch(done->reenactment_id(), /*skip_keyframes=*/true);
  ASSERT_TRUE(body.ok()) << body.status();
  ASSERT_TRUE(body->is_body());
  // Errors of the trunk and legs (which one Kinect v1 at 2 m sees) and of
  // the arms (shoulders to hands: in this take the person stands side-on
  // with the near arm raised before the face and the far arm hidden).
  std::vector<double> seen_errors_m;
  double arm_sum_m = 0.0;
  int arm_n = 0, fitted = 0;
  for (const ReenactmentFrame& frame : body->frames) {
    if (frame.joints_in_world_m.size() != body::kNumKinectV2Joints) continue;
    // Instants follow the stored frames one to one (one sensor).
    ASSERT_LT(frame.frame_index, static_cast<int>(skeletons->size()));
    const int64_t i = (*skeletons)[frame.frame_index].frame_index();
    ++fitted;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      using body::KinectV2Joint;
      const auto joint = static_cast<KinectV2Joint>(j);
      // The take's world is the raw depth camera's frame (see above).
      const double error_m =
          (frame.joints_in_world_m[j] - (*images)[i].joints_in_camera_m[j]).norm();
      switch (joint) {
        case KinectV2Joint::kHandTipLeft:
        case KinectV2Joint::kHandTipRight:
        case KinectV2Joint::kThumbLeft:
        case KinectV2Joint::kThumbRight:
          break;
        case KinectV2Joint::kShoulderLeft:
        case KinectV2Joint::kElbowLeft:
        case KinectV2Joint::kWristLeft:
        case KinectV2Joint::kHandLeft:
        case KinectV2Joint::kShoulderRight:
        case KinectV2Joint::kElbowRight:
        case KinectV2Joint::kWristRight:
        case KinectV2Joint::kHandRight:
          arm_sum_m += error_m;
          ++arm_n;
          break;
        default:
          seen_errors_m.push_back(error_m);
      }
    }
  }
  ASSERT_FALSE(seen_errors_m.empty());
  ASSERT_GT(arm_n, 0);
  const ErrorFigures seen = Figures(seen_errors_m);
  const double arms_mm = 1000.0 * arm_sum_m / arm_n;
  std::printf(
      "fakenect person, body job: %d of %zu instants fitted; trunk and legs MPJPE %.1f mm, "
      "PCK@10cm %.0f %%; arms %.1f mm\n",
      fitted, frames.size(), seen.mean_mm, 100.0 * seen.within_10cm, arms_mm);
  EXPECT_EQ(fitted, static_cast<int>(frames.size()));
  // Measured: 47.7 mm, 88 %; the arms 393 mm (the tracker's own arms are
  // as far off here: a side view with the arms before the face, which its
  // training resolves poorly).
  EXPECT_LT(seen.mean_mm, 70.0);
  EXPECT_GT(seen.within_10cm, 0.8);
  server.Stop();
}

}  // namespace
}  // namespace reenact
