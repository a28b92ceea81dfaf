// End to end over loopback: `reenact import` turns the real Azure Kinect
// recording (../shared/data) and a TUM RGB-D folder written here into take
// files, `reenact takes upload` sends them to the real `reenact-server`, and
// the takes the server stores (read back with `reenact takes download`) hold
// the same depth pixels, colour bytes and calibrations. Then the upload's
// durability: the same command again changes nothing; an upload started
// while the server is away delivers once it is up; and a take the server
// holds in part (an upload cut off) is resumed where the server has it,
// every frame set stored exactly once.
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <thread>

#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/base/subprocess.h"
#include "common/ingest/take_file_sets.h"
#include "common/ingest/take_recorder.h"
#include "common/ingest/uplink.h"
#include "common/io/depth_codec.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::ReadText;
using testing::RunCommand;

// A port nothing listens on right now.
int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  socklen_t len = sizeof(addr);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

class TakeUploadE2e : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const std::string mkv = testing::TestDataPath("rgbd/azure-kinect-mkv/recording.mkv");
    if (!fs::exists(mkv)) {
      skip_ = new std::string("no Azure Kinect recording under ../shared/data");
      return;
    }
    dir_ = new std::string(testing::MakeTempDir("take_upload_e2e"));
    take_ = new std::string(*dir_ + "/azure.mcap");
    const auto imported =
        RunCommand(*dir_, "import", {Bin("reenact"), "import", mkv, "--out", *take_, "--quiet"});
    if (imported.exit_code != 0) {
      skip_ = new std::string("reenact import failed: " + imported.err);
      return;
    }
    // The recording holds one frame; the durability tests want a longer
    // take: a TUM RGB-D folder of kTumFrames 160x120 frames, imported.
    const std::string tum = *dir_ + "/tum";
    fs::create_directories(tum + "/depth");
    fs::create_directories(tum + "/rgb");
    std::ofstream depth_txt(tum + "/depth.txt");
    std::ofstream rgb_txt(tum + "/rgb.txt");
    for (int i = 0; i < kTumFrames; ++i) {
      cv::Mat depth(120, 160, CV_16UC1);
      cv::Mat rgb(120, 160, CV_8UC3);
      for (int y = 0; y < 120; ++y) {
        for (int x = 0; x < 160; ++x) {
          depth.at<uint16_t>(y, x) =
              (x + i) % 11 == 0 ? 0 : static_cast<uint16_t>((1200 + 2 * x + y + 5 * i) * 5);
          rgb.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x + i), static_cast<uint8_t>(y),
                                              static_cast<uint8_t>(7 * i));
        }
      }
      cv::imwrite(tum + "/depth/" + std::to_string(i) + ".png", depth);
      cv::imwrite(tum + "/rgb/" + std::to_string(i) + ".png", rgb);
      const double stamp_s = 100.0 + i / 30.0;
      depth_txt << std::fixed << std::setprecision(6) << stamp_s << " depth/" << i << ".png\n";
      rgb_txt << std::fixed << std::setprecision(6) << stamp_s + 0.004 << " rgb/" << i << ".png\n";
    }
    depth_txt.close();
    rgb_txt.close();
    tum_take_ = new std::string(*dir_ + "/tum.mcap");
    const auto tum_imported = RunCommand(
        *dir_, "import-tum", {Bin("reenact"), "import", tum, "--out", *tum_take_, "--quiet"});
    if (tum_imported.exit_code != 0) {
      skip_ = new std::string("reenact import of a TUM folder failed: " + tum_imported.err);
    }
  }

  void SetUp() override {
    if (skip_ != nullptr) GTEST_SKIP() << *skip_;
  }

  // Starts reenact-server on `port` (0: any) with `data`; returns its address.
  std::string StartServer(const std::string& data, int port = 0) {
    std::string error;
    const std::string address = testing::StartServerForTest(
        data, {"--listen", "127.0.0.1:" + std::to_string(port), "--workers", "none"}, &server_,
        &error);
    if (address.empty()) ADD_FAILURE() << error;
    return address;
  }

  void TearDown() override {
    if (server_ && server_->Running()) {
      (void)server_->Signal(SIGTERM);
      (void)server_->Wait(20);
    }
  }

  static nlohmann::json Json(const testing::CommandResult& r) {
    return nlohmann::json::parse(r.out, nullptr, /*allow_exceptions=*/false);
  }

  static inline std::string* skip_ = nullptr;
  static inline std::string* dir_ = nullptr;
  static inline std::string* take_ = nullptr;
  static inline std::string* tum_take_ = nullptr;
  static constexpr int kTumFrames = 24;
  std::unique_ptr<Subprocess> server_;
};

// Per sensor and frame index, the encoded depth and colour of a take.
struct TakeContent {
  std::map<std::pair<std::string, int64_t>, std::string> depth;
  std::map<std::pair<std::string, int64_t>, std::string> color;
};

TakeContent ReadContent(const TakeReader& take) {
  TakeContent content;
  for (const auto& [id, calibration] : take.sensors()) {
    auto depth = take.ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    EXPECT_TRUE(depth.ok()) << depth.status();
    if (depth.ok()) {
      for (const auto& d : *depth) content.depth[{id, d.frame_index()}] = d.data();
    }
    auto color = take.ReadAll<v1::ColorImage>(SensorTopic(id, "color"));
    EXPECT_TRUE(color.ok()) << color.status();
    if (color.ok()) {
      for (const auto& c : *color) content.color[{id, c.frame_index()}] = c.data();
    }
  }
  return content;
}

TEST_F(TakeUploadE2e, AnAzureRecordingBecomesAStoredTakeFrameForFrame) {
  const std::string address = StartServer(*dir_ + "/data-a");
  ASSERT_FALSE(address.empty());
  const auto up = RunCommand(*dir_, "upload-a",
                             {Bin("reenact"), "takes", "upload", *take_, "--server", address,
                              "--spool", *dir_ + "/spool-a", "--json"});
  ASSERT_EQ(up.exit_code, 0) << up.err;
  const nlohmann::json j = Json(up);
  ASSERT_TRUE(j.is_object()) << up.out;
  const std::string take_id = j["take_id"];
  std::printf("uploaded %s: %d frame sets, %d frames, %.1f MiB in %.2f s\n", take_id.c_str(),
              j["frame_sets"].get<int>(), j["frames"].get<int>(),
              j["size_bytes"].get<double>() / (1 << 20), j["seconds"].get<double>());
  EXPECT_FALSE(fs::exists(*dir_ + "/spool-a/" + take_id)) << "the spool is removed once stored";
  // The spool holds people's frames: its user's alone.
  EXPECT_EQ(fs::status(*dir_ + "/spool-a").permissions() & fs::perms::all, fs::perms::owner_all);

  const std::string stored = *dir_ + "/stored-a.mcap";
  const auto down = RunCommand(*dir_, "download-a",
                               {Bin("reenact"), "takes", "download", take_id, "--server", address,
                                "--out", stored, "--quiet"});
  ASSERT_EQ(down.exit_code, 0) << down.err;
  auto source = TakeReader::Open(*take_);
  auto copy = TakeReader::Open(stored);
  ASSERT_TRUE(source.ok() && copy.ok());
  ASSERT_EQ((*copy)->sensors().size(), (*source)->sensors().size());
  for (const auto& [id, calibration] : (*source)->sensors()) {
    ASSERT_EQ((*copy)->sensors().count(id), 1u) << id;
    EXPECT_TRUE(
        google::protobuf::util::MessageDifferencer::Equals(calibration, (*copy)->sensors().at(id)))
        << id;
  }
  const TakeContent a = ReadContent(**source);
  const TakeContent b = ReadContent(**copy);
  ASSERT_FALSE(a.depth.empty());
  EXPECT_EQ(b.depth.size(), a.depth.size());
  EXPECT_EQ(b.color.size(), a.color.size());
  EXPECT_EQ(j["frames"].get<size_t>(), a.depth.size());
  int worst_mm = 0;
  int64_t pixels = 0;
  for (const auto& [key, data] : a.depth) {
    ASSERT_EQ(b.depth.count(key), 1u) << key.first << " " << key.second;
    auto x = DecodeDepth(data);
    auto y = DecodeDepth(b.depth.at(key));
    ASSERT_TRUE(x.ok() && y.ok());
    ASSERT_EQ(x->width, y->width);
    ASSERT_EQ(x->height, y->height);
    for (int v = 0; v < x->height; ++v) {
      for (int u = 0; u < x->width; ++u) {
        worst_mm = std::max(worst_mm, std::abs(int{x->at(u, v)} - int{y->at(u, v)}));
        ++pixels;
      }
    }
  }
  for (const auto& [key, data] : a.color) {
    ASSERT_EQ(b.color.count(key), 1u);
    EXPECT_EQ(b.color.at(key), data) << "colour of " << key.first << " " << key.second;
  }
  std::printf(
      "stored take vs file: %lld depth pixels, largest difference %d mm; %zu colour "
      "frames byte-identical\n",
      static_cast<long long>(pixels), worst_mm, a.color.size());
  EXPECT_EQ(worst_mm, 0);

  // The same command again: the server has the whole take, nothing is added.
  const auto again = RunCommand(*dir_, "upload-a2",
                                {Bin("reenact"), "takes", "upload", *take_, "--server", address,
                                 "--spool", *dir_ + "/spool-a", "--json"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const nlohmann::json k = Json(again);
  EXPECT_EQ(k["take_id"], take_id);
  EXPECT_TRUE(k["resumed"].get<bool>());
  EXPECT_EQ(k["server_held_at_start"], j["frame_sets"]);
  EXPECT_EQ(k["frame_sets_sent"], 0);
  EXPECT_EQ(k["frames"], j["frames"]);
  const auto list =
      RunCommand(*dir_, "list-a", {Bin("reenact"), "takes", "list", "--server", address, "--json"});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_EQ(Json(list).size(), 1u) << list.out;

  // Not a take: a clear error, exit 1, nothing stored.
  const std::string junk = *dir_ + "/junk.mcap";
  {
    std::ofstream f(junk);
    f << "no take here";
  }
  const auto bad = RunCommand(*dir_, "upload-junk",
                              {Bin("reenact"), "takes", "upload", junk, "--server", address});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("junk.mcap"), std::string::npos) << bad.err;
}

TEST_F(TakeUploadE2e, AnUploadWaitsForAServerThatIsAway) {
  const int port = FreePort();
  SubprocessOptions options;
  options.stdout_path = *dir_ + "/upload-b.out";
  options.stderr_path = *dir_ + "/upload-b.err";
  auto upload = Subprocess::Start(
      {Bin("reenact"), "takes", "upload", *tum_take_, "--server",
       "127.0.0.1:" + std::to_string(port), "--spool", *dir_ + "/spool-b", "--json"},
      options);
  ASSERT_TRUE(upload.ok()) << upload.status();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_TRUE((*upload)->Running()) << ReadText(options.stderr_path);
  ASSERT_FALSE(StartServer(*dir_ + "/data-b", port).empty());
  auto exit = (*upload)->Wait(120);
  ASSERT_TRUE(exit.ok()) << exit.status();
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << ReadText(options.stderr_path);
  const nlohmann::json j = nlohmann::json::parse(ReadText(options.stdout_path), nullptr, false);
  ASSERT_TRUE(j.is_object());
  EXPECT_GE(j["reconnects"].get<int>(), 1);
  EXPECT_EQ(j["frame_sets"].get<int>(), kTumFrames);
  std::printf("after %d reconnects: %d frame sets stored\n", j["reconnects"].get<int>(),
              j["frame_sets"].get<int>());
}

TEST_F(TakeUploadE2e, AnInterruptedUploadResumesWhereTheServerHoldsIt) {
  const std::string address = StartServer(*dir_ + "/data-c");
  ASSERT_FALSE(address.empty());
  auto sets = ingest::TakeFileSets::Open(*tum_take_);
  ASSERT_TRUE(sets.ok()) << sets.status();
  const int64_t total = (*sets)->plan().frame_sets;
  ASSERT_GE(total, 4);
  const int64_t first = total / 2;
  const std::string take_id = "resumed-tum";
  {
    // An upload cut off after `first` durable sets: what the command does,
    // stopped before its end.
    ingest::TakeRecorderOptions options;
    options.spool_root = *dir_ + "/spool-c-partial";
    auto recorder = ingest::TakeRecorder::Start(ingest::MakeIngestChannel(address, options.uplink),
                                                options, take_id, ingest::kTakeUploadDaemonId,
                                                (*sets)->info(), (*sets)->sensors());
    ASSERT_TRUE(recorder.ok()) << recorder.status();
    int64_t added = 0;
    const absl::Status status = (*sets)->ForEach([&](v1::FrameSet set) {
      if (added == first) return absl::CancelledError("cut off");
      ++added;
      return (*recorder)->Add(std::move(set));
    });
    ASSERT_TRUE(absl::IsCancelled(status)) << status;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while ((*recorder)->Stats().durable_sequence < static_cast<uint64_t>(first) &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ASSERT_EQ((*recorder)->Stats().durable_sequence, static_cast<uint64_t>(first));
    (*recorder)->Abort();
  }
  const auto show = RunCommand(
      *dir_, "show-c", {Bin("reenact"), "takes", "show", take_id, "--server", address, "--json"});
  ASSERT_EQ(show.exit_code, 0) << show.err;
  std::printf("before resuming: %s\n", show.out.c_str());

  const auto up = RunCommand(*dir_, "upload-c",
                             {Bin("reenact"), "takes", "upload", *tum_take_, "--server", address,
                              "--take-id", take_id, "--spool", *dir_ + "/spool-c", "--json"});
  ASSERT_EQ(up.exit_code, 0) << up.err;
  const nlohmann::json j = Json(up);
  EXPECT_TRUE(j["resumed"].get<bool>());
  EXPECT_EQ(j["server_held_at_start"].get<int64_t>(), first);
  EXPECT_EQ(j["frame_sets_sent"].get<int64_t>(), total - first);
  EXPECT_EQ(j["frame_sets"].get<int64_t>(), total);

  // Every set once, in order, with the file's frames.
  const std::string stored = *dir_ + "/stored-c.mcap";
  ASSERT_EQ(RunCommand(*dir_, "download-c",
                       {Bin("reenact"), "takes", "download", take_id, "--server", address, "--out",
                        stored, "--quiet"})
                .exit_code,
            0);
  auto copy = TakeReader::Open(stored);
  ASSERT_TRUE(copy.ok());
  auto records = (*copy)->ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(static_cast<int64_t>(records->size()), total);
  for (size_t i = 0; i < records->size(); ++i) EXPECT_EQ((*records)[i].sequence(), i + 1);
  auto source = TakeReader::Open(*tum_take_);
  ASSERT_TRUE(source.ok());
  const TakeContent a = ReadContent(**source);
  const TakeContent b = ReadContent(**copy);
  EXPECT_EQ(a.depth, b.depth);
  EXPECT_EQ(a.color.size(), b.color.size());
  std::printf("resumed at set %lld of %lld; stored %zu depth frames, identical to the file\n",
              static_cast<long long>(first + 1), static_cast<long long>(total), b.depth.size());
}

}  // namespace
}  // namespace reenact
