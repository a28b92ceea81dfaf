// End to end over loopback, for recordings made without a skeleton tracker:
// a TUM RGB-D folder of a person (written here from `reenact tracker synth
// --sequence`, a held-out motion with its true joints) is brought in with
// `reenact import`, sent with `reenact takes upload` to the real
// `reenact-server`, and a body job on it succeeds: the server tracks the
// take's depth first. The fitted skeleton, exported as BVH, is measured
// against the true joints. The real Azure Kinect desk recording (nobody in
// it) gets a clear "no person in this take" instead. And a newcomer's whole
// path, timed: import, upload, body job, the tablet app in Chromium.
#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/base/subprocess.h"
#include "common/body/motion.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::CommandResult;
using testing::ReadText;
using testing::RunCommand;
using testing::StartServerForTest;

constexpr int kFrames = 45;
// The 20 body joints the tracker's figures use (no hand tips, thumbs or
// neck), by Kinect v2 name.
constexpr const char* kBodyJoints[] = {"SpineBase",     "SpineMid",   "SpineShoulder", "Head",
                                       "ShoulderLeft",  "ElbowLeft",  "WristLeft",     "HandLeft",
                                       "ShoulderRight", "ElbowRight", "WristRight",    "HandRight",
                                       "HipLeft",       "KneeLeft",   "AnkleLeft",     "FootLeft",
                                       "HipRight",      "KneeRight",  "AnkleRight",    "FootRight"};

class TrackedUploadE2e : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::MakeTempDir("tracked_upload_e2e");
    data_ = reenact::testing::TestDataDir();
  }

  void TearDown() override {
    if (server_ && server_->Running()) {
      (void)server_->Signal(SIGTERM);
      (void)server_->Wait(20);
    }
  }

  // Starts reenact-server with one job slot; returns its address.
  std::string StartServer() {
    std::string error;
    const std::string address = StartServerForTest(
        dir_ + "/data", {"--listen", "127.0.0.1:0", "--jobs", "1"}, &server_, &error);
    if (address.empty()) ADD_FAILURE() << error;
    return address;
  }

  // A recording of a person made without a skeleton tracker, as a newcomer
  // brings one: `reenact tracker synth --sequence` renders the depth of a
  // held-out motion (`motion_path`) with its true joints (`*meta`, from its
  // meta.json), written here as a TUM RGB-D folder and brought in with
  // `reenact import` as `take_path`.
  void RecordPerson(const std::string& motion_path, const std::string& take_path,
                    nlohmann::json* meta) {
    // A person's depth with true joints, as one fixed camera sees it, the whole
    // body in view (2.2-3.2 m away).
    const std::string seq = dir_ + "/seq";
    const CommandResult synth =
        RunCommand(dir_, "synth",
                   {Bin("reenact"), "tracker", "synth", "--out", seq, "--sequence", "--motion",
                    motion_path, "--images", std::to_string(kFrames), "--seed", "5",
                    "--min-distance", "2.2", "--max-distance", "3.2", "--data", data_});
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    *meta = nlohmann::json::parse(ReadText(seq + "/meta.json"), nullptr, false);
    ASSERT_TRUE(meta->is_object());
    ASSERT_EQ((*meta)["frames"].size(), static_cast<size_t>(kFrames));

    // Written as a TUM RGB-D folder: depth in 1/5000 m, a grey colour image
    // per frame, the camera's intrinsics in a calibration file.
    const std::string tum = dir_ + "/tum";
    fs::create_directories(tum + "/depth");
    fs::create_directories(tum + "/rgb");
    std::ofstream depth_txt(tum + "/depth.txt");
    std::ofstream rgb_txt(tum + "/rgb.txt");
    for (int i = 0; i < kFrames; ++i) {
      const cv::Mat mm = cv::imread(seq + "/" + (*meta)["frames"][i]["depth"].get<std::string>(),
                                    cv::IMREAD_UNCHANGED);
      ASSERT_EQ(mm.type(), CV_16UC1);
      cv::Mat tum_depth;
      mm.convertTo(tum_depth, CV_16UC1, 5.0);
      cv::imwrite(tum + "/depth/" + std::to_string(i) + ".png", tum_depth);
      cv::imwrite(tum + "/rgb/" + std::to_string(i) + ".png",
                  cv::Mat(mm.rows, mm.cols, CV_8UC3, cv::Scalar(120, 140, 160)));
      const double stamp_s = 50.0 + i / 30.0;
      depth_txt << std::fixed << std::setprecision(6) << stamp_s << " depth/" << i << ".png\n";
      rgb_txt << std::fixed << std::setprecision(6) << stamp_s + 0.003 << " rgb/" << i << ".png\n";
    }
    depth_txt.close();
    rgb_txt.close();
    const auto& k = (*meta)["frames"][0]["intrinsics"];
    {
      std::ofstream calibration(dir_ + "/calibration.txt");
      calibration << std::setprecision(10) << k[0].get<double>() << " " << k[1].get<double>() << " "
                  << k[2].get<double>() << " " << k[3].get<double>() << "\n";
    }
    const auto start = std::chrono::steady_clock::now();
    const CommandResult imported =
        RunCommand(dir_, "import",
                   {Bin("reenact"), "import", tum, "--intrinsics", dir_ + "/calibration.txt",
                    "--out", take_path, "--quiet"});
    import_s_ = SecondsSince(start);
    ASSERT_EQ(imported.exit_code, 0) << imported.err;
  }

  static double SecondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  // `reenact takes upload FILE --json`: the stored take's id, "" on failure.
  std::string Upload(const std::string& address, const std::string& take) {
    const CommandResult up = RunCommand(dir_, "upload",
                                        {Bin("reenact"), "takes", "upload", take, "--server",
                                         address, "--spool", dir_ + "/spool", "--json"});
    EXPECT_EQ(up.exit_code, 0) << up.err;
    const auto j = nlohmann::json::parse(up.out, nullptr, false);
    if (!j.is_object() || !j.contains("take_id")) {
      ADD_FAILURE() << up.out;
      return "";
    }
    return j["take_id"].get<std::string>();
  }

  std::string dir_;
  std::string data_;
  std::unique_ptr<Subprocess> server_;
  double import_s_ = 0.0;  // The last RecordPerson's `reenact import`.
};

TEST_F(TrackedUploadE2e, AnImportedRecordingOfAPersonGetsSkeletonsAndABodyJob) {
  const std::string motion = data_ + "/mocap/cmu/131_03.bvh";
  if (!fs::exists(motion)) GTEST_SKIP() << "no CMU motion under ../shared/data";

  nlohmann::json meta;
  const std::string take = dir_ + "/person.mcap";
  ASSERT_NO_FATAL_FAILURE(RecordPerson(motion, take, &meta));
  const std::string address = StartServer();
  ASSERT_FALSE(address.empty());
  const std::string take_id = Upload(address, take);
  ASSERT_FALSE(take_id.empty());
  const CommandResult submit = RunCommand(
      dir_, "submit-body",
      {Bin("reenact"), "jobs", "submit", "--server", address, "--take", take_id, "--method", "body",
       "--model", "procedural", "--option", "atlas_px=256", "--wait", "--logs", "--json"});
  ASSERT_EQ(submit.exit_code, 0) << submit.err << "\n" << ReadText(dir_ + "/data.log");
  // The job's log says the take was tracked from its depth.
  const size_t track = submit.err.find("track: ");
  ASSERT_NE(track, std::string::npos) << submit.err;
  std::printf("%s\n", submit.err.substr(track, submit.err.find('\n', track) - track).c_str());
  const auto result = nlohmann::json::parse(submit.out, nullptr, false);
  ASSERT_TRUE(result.is_object() && result.contains("reenactment")) << submit.out;
  const std::string body = result["reenactment"].get<std::string>();

  // The fitted skeleton against the true joints, frame for frame, after one
  // rigid alignment of the whole sequence (the BVH's axes are its own).
  const std::string bvh = dir_ + "/body.bvh";
  const CommandResult exported =
      RunCommand(dir_, "export-bvh",
                 {Bin("reenact"), "export", "--server", address, "--reenactment", body, "--format",
                  "bvh", "--out", bvh, "--quiet"});
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  body::BvhOptions bvh_options;
  bvh_options.metres_per_unit = 1.0;  // The export's default unit, metres.
  const absl::StatusOr<body::Motion> fitted = body::ReadBvh(bvh, bvh_options);
  ASSERT_TRUE(fitted.ok()) << fitted.status();
  ASSERT_EQ(fitted->num_frames(), kFrames);
  std::vector<int> fitted_index;
  for (const char* name : kBodyJoints) {
    int f = -1;
    for (size_t j = 0; j < fitted->joints().size(); ++j) {
      if (fitted->joints()[j].name == name) f = static_cast<int>(j);
    }
    ASSERT_GE(f, 0) << name;
    fitted_index.push_back(f);
  }
  const int n = kFrames * static_cast<int>(fitted_index.size());
  Eigen::Matrix3Xd ours(3, n), truth(3, n);
  int c = 0;
  for (int i = 0; i < kFrames; ++i) {
    const std::vector<Eigen::Isometry3d> world = fitted->WorldFromJoints(i);
    for (size_t j = 0; j < fitted_index.size(); ++j, ++c) {
      ours.col(c) = world[fitted_index[j]].translation();
      const auto& p = meta["frames"][i]["joints_m"][kBodyJoints[j]];
      truth.col(c) = Eigen::Vector3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    }
  }
  const Eigen::Matrix4d aligned = Eigen::umeyama(ours, truth, /*with_scaling=*/false);
  const Eigen::Matrix3Xd moved =
      (aligned.topLeftCorner<3, 3>() * ours).colwise() + aligned.topRightCorner<3, 1>();
  const double mpjpe_mm = 1000.0 * (moved - truth).colwise().norm().mean();
  const Eigen::Matrix3d rotation = aligned.topLeftCorner<3, 3>();
  const double turn_deg =
      Eigen::AngleAxisd(rotation).angle() * 180.0 / M_PI;  // The BVH's axes against the camera's.
  std::printf(
      "body job on a tracked imported take: %d frames, fitted joints %.1f mm from the "
      "true ones (after one rigid alignment, %.1f degrees)\n",
      kFrames, mpjpe_mm, turn_deg);
  // One sensor's depth, a held-out motion: the tracker alone is 50-70 mm
  // from the truth on such sequences, the body fit on its skeletons 14 mm
  // when this was written.
  EXPECT_LT(mpjpe_mm, 40.0);
}

// A newcomer's path after the README's demo, step by step and timed: their
// own recording of a person (a TUM RGB-D folder) brought in with `reenact
// import`, sent with `reenact takes upload`, a body job as the README writes
// it, and the tablet app (reenact-server --http) showing the reenactment in
// Chromium. Prints each step's seconds and the glb's size.
TEST_F(TrackedUploadE2e, NewcomersPathFromARecordingToTheTablet) {
  const std::string motion = data_ + "/mocap/cmu/131_01.bvh";
  if (!fs::exists(motion)) GTEST_SKIP() << "no CMU motion under ../shared/data";
#ifndef REENACT_NODE
  GTEST_SKIP() << "no node: the tablet app cannot be checked";
#else
  nlohmann::json meta;
  const std::string take = dir_ + "/person.mcap";
  ASSERT_NO_FATAL_FAILURE(RecordPerson(motion, take, &meta));

  std::string error;
  const std::string http_port_file = dir_ + "/http.port";
  const std::string address =
      StartServerForTest(dir_ + "/data",
                         {"--listen", "127.0.0.1:0", "--jobs", "1", "--http", "127.0.0.1:0",
                          "--http-port-file", http_port_file},
                         &server_, &error);
  ASSERT_FALSE(address.empty()) << error;
  std::string http = ReadText(http_port_file);
  http = http.substr(0, http.find('\n'));
  ASSERT_FALSE(http.empty()) << ReadText(dir_ + "/data.log");

  auto start = std::chrono::steady_clock::now();
  const std::string take_id = Upload(address, take);
  ASSERT_FALSE(take_id.empty());
  const double upload_s = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  const CommandResult submit =
      RunCommand(dir_, "submit-body",
                 {Bin("reenact"), "jobs", "submit", "--server", address, "--take", take_id,
                  "--method", "body", "--model", "procedural", "--wait", "--json"});
  const double job_s = SecondsSince(start);
  ASSERT_EQ(submit.exit_code, 0) << submit.err << "\n" << ReadText(dir_ + "/data.log");
  const auto result = nlohmann::json::parse(submit.out, nullptr, false);
  ASSERT_TRUE(result.is_object() && result.contains("reenactment")) << submit.out;
  const std::string body = result["reenactment"].get<std::string>();

  const std::string glb = dir_ + "/body.glb";
  const CommandResult exported =
      RunCommand(dir_, "export-glb",
                 {Bin("reenact"), "export", "--server", address, "--reenactment", body, "--format",
                  "glb", "--out", glb, "--quiet"});
  ASSERT_EQ(exported.exit_code, 0) << exported.err;

  start = std::chrono::steady_clock::now();
  const CommandResult shown = RunCommand(
      dir_, "tablet",
      {REENACT_NODE, std::string(REENACT_SOURCE_DIR) + "/tests/web/show_reenactment.mjs", "--url",
       "http://" + http, "--reenactment", body, "--screenshot", dir_ + "/tablet.png"});
  const double tablet_s = SecondsSince(start);
  if (shown.exit_code == 77) GTEST_SKIP() << shown.err;
  ASSERT_EQ(shown.exit_code, 0) << shown.out << shown.err;
  const auto tablet = nlohmann::json::parse(shown.out, nullptr, false);
  ASSERT_TRUE(tablet.is_object()) << shown.out;
  EXPECT_EQ(tablet["frames"], kFrames) << shown.out;
  // The body stands 2.2-3.2 m from the camera the player frames it with:
  // it covers a few percent of the stage at least.
  EXPECT_GT(tablet["covered"].get<double>(), 0.02) << shown.out;
  std::printf(
      "newcomer's path (%d frames, one sensor): import %.1f s, takes upload %.1f s, body job "
      "%.1f s, tablet (Chromium start to first frame) %.1f s, first frame %d ms after the "
      "page's start, body.glb %.2f MB, body on %.1f %% of the stage\n",
      kFrames, import_s_, upload_s, job_s, tablet_s, tablet["first_frame_ms"].get<int>(),
      static_cast<double>(fs::file_size(glb)) / 1e6, 100.0 * tablet["covered"].get<double>());
#endif
}

TEST_F(TrackedUploadE2e, ARecordingWithNobodyInItFailsClearly) {
  const std::string mkv = data_ + "/rgbd/azure-kinect-mkv/recording.mkv";
  if (!fs::exists(mkv)) GTEST_SKIP() << "no Azure Kinect recording under ../shared/data";
  const std::string take = dir_ + "/desk.mcap";
  const CommandResult imported =
      RunCommand(dir_, "import", {Bin("reenact"), "import", mkv, "--out", take, "--quiet"});
  ASSERT_EQ(imported.exit_code, 0) << imported.err;
  const std::string address = StartServer();
  ASSERT_FALSE(address.empty());
  const std::string take_id = Upload(address, take);
  ASSERT_FALSE(take_id.empty());
  const CommandResult submit =
      RunCommand(dir_, "submit-body",
                 {Bin("reenact"), "jobs", "submit", "--server", address, "--take", take_id,
                  "--method", "body", "--model", "procedural", "--wait", "--json"});
  std::printf("exit %d: %s\n", submit.exit_code, submit.err.c_str());
  EXPECT_NE(submit.exit_code, 0);
  EXPECT_NE((submit.out + submit.err).find("no person in this take"), std::string::npos)
      << submit.out << submit.err;
  // Where the server keeps its data is not the client's to know.
  EXPECT_EQ((submit.out + submit.err).find(dir_ + "/data"), std::string::npos)
      << submit.out << submit.err;
  // The take itself is kept.
  const CommandResult show = RunCommand(
      dir_, "show", {Bin("reenact"), "takes", "show", take_id, "--server", address, "--json"});
  EXPECT_EQ(show.exit_code, 0) << show.err;
}

}  // namespace
}  // namespace reenact
