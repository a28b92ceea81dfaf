// `reenact import` and `reenact take frame`: exit codes, and what the
// commands write, on the real Azure Kinect recording and on TUM folders.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "common/base/files.h"
#include "common/io/jpeg.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;

// A TUM folder of three 32x24 frames (depth 1000 + 10 i mm, colour 5 ms
// after each depth frame).
std::string WriteTum(const std::string& name) {
  const std::string dir = testing::MakeTempDir(name);
  fs::create_directories(dir + "/depth");
  fs::create_directories(dir + "/rgb");
  std::ofstream depth_txt(dir + "/depth.txt"), rgb_txt(dir + "/rgb.txt");
  depth_txt << "# timestamp filename\n";
  for (int i = 0; i < 3; ++i) {
    const std::string stamp = "100.0" + std::to_string(i * 3) + "0000";
    cv::imwrite(dir + "/depth/" + std::to_string(i) + ".png",
                cv::Mat(24, 32, CV_16UC1, cv::Scalar((1000 + 10 * i) * 5)));
    cv::imwrite(dir + "/rgb/" + std::to_string(i) + ".png",
                cv::Mat(24, 32, CV_8UC3, cv::Scalar(10, 20, 30)));
    depth_txt << stamp << " depth/" << i << ".png\n";
    rgb_txt << "100.0" << i * 3 << "5000 rgb/" << i << ".png\n";
  }
  return dir;
}

TEST(Import, TumFolderThenTakeFrame) {
  const std::string dir = WriteTum("cli_import_tum");
  std::ostringstream out, err;
  ASSERT_EQ(RunImport({dir, "--out", dir + "/take.mcap", "--json"}, out, err), kExitOk)
      << err.str();
  const nlohmann::json j = nlohmann::json::parse(out.str());
  EXPECT_EQ(j["format"], "tum");
  EXPECT_EQ(j["frames"], 3);
  EXPECT_EQ(j["frames_with_color"], 3);

  std::ostringstream frame_out, frame_err;
  ASSERT_EQ(RunTakeFrame({dir + "/take.mcap", "--sensor", "k0", "--index", "2", "--depth-png",
                          dir + "/d.png", "--color", dir + "/c.jpg", "--json"},
                         frame_out, frame_err),
            kExitOk)
      << frame_err.str();
  const nlohmann::json f = nlohmann::json::parse(frame_out.str());
  EXPECT_EQ(f["depth"]["min_mm"], 1020);
  EXPECT_EQ(f["depth"]["max_mm"], 1020);
  EXPECT_EQ(f["depth"]["device_stamp_ns"], 100'060'000'000);
  EXPECT_DOUBLE_EQ(f["calibration"]["depth_intrinsics"]["fx"].get<double>(), 525.0 * 32 / 640);
  const cv::Mat png = cv::imread(dir + "/d.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(png.type(), CV_16UC1);
  EXPECT_EQ(png.at<uint16_t>(3, 4), 1020);
  auto jpeg = ReadFileToString(dir + "/c.jpg");
  ASSERT_TRUE(jpeg.ok());
  auto rgb = DecodeJpeg(*jpeg);
  ASSERT_TRUE(rgb.ok()) << rgb.status();
  EXPECT_NEAR(rgb->at(5, 5, 0), 30, 3);  // R of the BGR (10, 20, 30) written above.

  // Text output, and the only sensor found without --sensor.
  std::ostringstream text, text_err;
  EXPECT_EQ(RunTakeFrame({dir + "/take.mcap", "--index", "0"}, text, text_err), kExitOk);
  EXPECT_NE(text.str().find("frame 0"), std::string::npos) << text.str();
}

// A real depth-only Kinect v2 sequence (../shared/data/rgbd-seq): a folder
// of depth PNGs in millimetres with its lens in meta.json becomes a take
// whose frames hold the same depth and whose calibration is that lens.
TEST(Import, DepthOnlyFolderOfARealSequence) {
  const std::string seq = testing::TestDataPath("rgbd-seq/utd-kinect2-a02-s2-t1");
  REENACT_REQUIRE_TEST_FILE(seq + "/meta.json");
  const std::string dir = testing::MakeTempDir("cli_import_depth_png");
  std::ostringstream out, err;
  ASSERT_EQ(RunImport({seq, "--out", dir + "/take.mcap", "--json"}, out, err), kExitOk)
      << err.str();
  const nlohmann::json j = nlohmann::json::parse(out.str());
  auto meta_text = ReadFileToString(seq + "/meta.json");
  ASSERT_TRUE(meta_text.ok());
  const nlohmann::json meta = nlohmann::json::parse(*meta_text);
  EXPECT_EQ(j["format"], "depth-png");
  EXPECT_EQ(j["frames"], meta["frames"].size());
  EXPECT_EQ(j["frames_with_color"], 0);
  EXPECT_EQ(j["depth"], (nlohmann::json{512, 424}));
  EXPECT_NEAR(j["duration_s"].get<double>(), (meta["frames"].size() - 1) / 30.0, 1e-6);

  std::ostringstream frame_out, frame_err;
  ASSERT_EQ(
      RunTakeFrame({dir + "/take.mcap", "--index", "5", "--depth-png", dir + "/d.png", "--json"},
                   frame_out, frame_err),
      kExitOk)
      << frame_err.str();
  const nlohmann::json f = nlohmann::json::parse(frame_out.str());
  EXPECT_DOUBLE_EQ(f["calibration"]["depth_intrinsics"]["fx"].get<double>(),
                   meta["intrinsics"][0].get<double>());
  const cv::Mat ours = cv::imread(dir + "/d.png", cv::IMREAD_UNCHANGED);
  const cv::Mat theirs =
      cv::imread(seq + "/" + meta["frames"][5]["depth"].get<std::string>(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(ours.type(), CV_16UC1);
  ASSERT_EQ(theirs.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(ours, theirs, cv::NORM_INF), 0.0) << "mm";

  // Flags that do not apply, and a folder with no lens.
  std::ostringstream e1, e2, e3, o;
  const std::string tum = WriteTum("cli_import_depth_png_tum");
  EXPECT_EQ(RunImport({tum, "--out", dir + "/t.mcap", "--fps", "15"}, o, e1), kExitUsage);
  EXPECT_EQ(RunImport({seq, "--out", dir + "/t.mcap", "--depth-units-per-m", "0.5"}, o, e2),
            kExitUsage);
  const std::string bare = testing::MakeTempDir("cli_import_depth_png_bare");
  cv::imwrite(bare + "/0.png", cv::Mat(4, 4, CV_16UC1, cv::Scalar(1000)));
  EXPECT_EQ(RunImport({bare, "--out", dir + "/b.mcap"}, o, e3), kExitFailure);
  EXPECT_NE(e3.str().find("--intrinsics"), std::string::npos) << e3.str();
  EXPECT_FALSE(fs::exists(dir + "/b.mcap"));
}

TEST(Import, ExitCodes) {
  const std::string dir = WriteTum("cli_import_codes");
  std::ostringstream out, err;
  // Usage errors: 2.
  EXPECT_EQ(RunImport({dir}, out, err), kExitUsage);  // No --out.
  EXPECT_EQ(RunImport({dir, "--out", dir + "/t.mcap", "--format", "bag"}, out, err), kExitUsage);
  EXPECT_EQ(RunImport({dir, "--out", dir + "/t.mcap", "--max-frames", "-1"}, out, err), kExitUsage);
  EXPECT_EQ(RunTakeFrame({dir + "/t.mcap"}, out, err), kExitUsage);  // No --index.
  // Data errors: 1.
  EXPECT_EQ(RunImport({dir + "/missing", "--out", dir + "/t.mcap"}, out, err), kExitFailure);
  std::ofstream(dir + "/depth.txt", std::ios::app) << "garbage line here\n";
  err.str("");
  EXPECT_EQ(RunImport({dir, "--out", dir + "/t.mcap"}, out, err), kExitFailure);
  EXPECT_NE(err.str().find("depth.txt line 5"), std::string::npos) << err.str();
  EXPECT_FALSE(fs::exists(dir + "/t.mcap"));
  std::ofstream(dir + "/x.mkv") << "not matroska";
  EXPECT_EQ(RunImport({dir + "/x.mkv", "--out", dir + "/t.mcap"}, out, err), kExitFailure);
  EXPECT_EQ(RunTakeFrame({dir + "/x.mkv", "--index", "0"}, out, err), kExitFailure);

  // --max-frames, then a frame past the end and an unknown sensor.
  const std::string good = WriteTum("cli_import_codes_good");
  ASSERT_EQ(RunImport({good, "--out", good + "/t.mcap", "--max-frames", "2", "--quiet"}, out, err),
            kExitOk)
      << err.str();
  EXPECT_EQ(RunTakeFrame({good + "/t.mcap", "--index", "1"}, out, err), kExitOk);
  EXPECT_EQ(RunTakeFrame({good + "/t.mcap", "--index", "2"}, out, err), kExitFailure);
  EXPECT_EQ(RunTakeFrame({good + "/t.mcap", "--sensor", "zz", "--index", "0"}, out, err),
            kExitFailure);
}

TEST(Import, AzureKinectRecording) {
  const std::string mkv = testing::TestDataPath("rgbd/azure-kinect-mkv/recording.mkv");
  if (!fs::exists(mkv)) {
    GTEST_SKIP() << "\n*** SKIPPED: the real Azure Kinect recording " << mkv << " is missing ***";
  }
  const std::string dir = testing::MakeTempDir("cli_import_mkv");
  std::ostringstream out, err;
  ASSERT_EQ(RunImport({mkv, "--out", dir + "/take.mcap", "--max-frames", "3", "--json"}, out, err),
            kExitOk)
      << err.str();
  const nlohmann::json j = nlohmann::json::parse(out.str());
  EXPECT_EQ(j["format"], "azure-mkv");
  EXPECT_EQ(j["frames"], 1);  // The shared recording holds one capture.
  EXPECT_EQ(j["frames_with_color"], 1);
  EXPECT_EQ(j["color"][0], 1280);

  std::ostringstream frame_out;
  ASSERT_EQ(RunTakeFrame({dir + "/take.mcap", "--sensor", "k0", "--index", "0", "--depth-png",
                          dir + "/d.png", "--color", dir + "/c.jpg", "--json"},
                         frame_out, err),
            kExitOk)
      << err.str();
  const cv::Mat mine = cv::imread(dir + "/d.png", cv::IMREAD_UNCHANGED);
  const cv::Mat truth =
      cv::imread(testing::TestDataPath("rgbd/azure-kinect-mkv/derived/depth_640x576_mm.png"),
                 cv::IMREAD_UNCHANGED);
  ASSERT_EQ(mine.type(), CV_16UC1);
  ASSERT_EQ(truth.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(mine, truth, cv::NORM_INF), 0.0);
  const cv::Mat color = cv::imread(dir + "/c.jpg");
  EXPECT_EQ(color.cols, 1280);
  EXPECT_EQ(color.rows, 720);
}

}  // namespace
}  // namespace reenact::cli
