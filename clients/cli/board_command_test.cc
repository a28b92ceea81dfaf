#include <filesystem>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "clients/cli/commands.h"
#include "common/board/board_detector.h"
#include "common/board/board_spec.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

TEST(RunBoard, WritesAPrintablePngOfTheStatedSize) {
  const std::string dir = testing::MakeTempDir("cli_board");
  const std::string path = dir + "/board.png";
  std::ostringstream out, err;
  ASSERT_EQ(RunBoard({"--out", path, "--dpi", "100", "--json"}, out, err), kExitOk) << err.str();
  const nlohmann::json info = nlohmann::json::parse(out.str());
  EXPECT_EQ(info["spec"], board::kDefaultBoardSpecText);
  EXPECT_EQ(info["dpi"].get<int>(), 100);
  EXPECT_NEAR(info["width_mm"].get<double>(), 414.0, 0.3);  // 374 mm grid + 2 x 20 mm.
  EXPECT_NEAR(info["height_mm"].get<double>(), 282.0, 0.3);
  const cv::Mat page = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_FALSE(page.empty());
  EXPECT_EQ(page.cols, info["width_px"].get<int>());
  EXPECT_EQ(page.rows, info["height_px"].get<int>());

  // The page seen straight on from 1 m by a camera with one pixel per dot.
  RgbImage image(page.cols, page.rows);
  for (int y = 0; y < page.rows; ++y) {
    for (int x = 0; x < page.cols; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = page.at<cv::Vec3b>(y, x)[2 - c];
    }
  }
  CameraIntrinsics intrinsics;
  intrinsics.width = page.cols;
  intrinsics.height = page.rows;
  intrinsics.fx = intrinsics.fy = 100 / 0.0254;
  intrinsics.cx = 0.5 * page.cols - 0.5;
  intrinsics.cy = 0.5 * page.rows - 0.5;
  auto found = board::DetectBoard(image, intrinsics, board::BoardSpec{});
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ(found->num_markers, 6);
  EXPECT_NEAR(found->camera_from_board.translation().z(), 1.0, 0.005);
  std::filesystem::remove_all(dir);
}

TEST(RunBoard, TextSummaryAndOtherSpecs) {
  const std::string dir = testing::MakeTempDir("cli_board_text");
  std::ostringstream out, err;
  ASSERT_EQ(RunBoard({"--out", dir + "/b.png", "--spec", "aruco:DICT_5X5_100:4x3:50:10:20", "--dpi",
                      "150", "--margin-mm", "12", "--no-caption"},
                     out, err),
            kExitOk)
      << err.str();
  EXPECT_NE(out.str().find("aruco:DICT_5X5_100:4x3:50:10:20"), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("= 254.0 x 194."), std::string::npos) << out.str();
  EXPECT_TRUE(std::filesystem::exists(dir + "/b.png"));
  std::filesystem::remove_all(dir);
}

TEST(RunBoard, BadArguments) {
  std::ostringstream out, err;
  EXPECT_EQ(RunBoard({}, out, err), kExitUsage);  // No --out.
  EXPECT_EQ(RunBoard({"--out", "/tmp/x.png", "--spec", "aruco:NOPE:3x2:110:22"}, out, err),
            kExitUsage);
  EXPECT_NE(err.str().find("aruco:NOPE"), std::string::npos) << err.str();
  EXPECT_EQ(RunBoard({"--out", "/tmp/x.png", "--dpi", "5"}, out, err), kExitUsage);
  EXPECT_EQ(RunBoard({"--out", "/nonexistent_folder_for_reenact/b.png", "--dpi", "50"}, out, err),
            kExitFailure);
}

}  // namespace
}  // namespace reenact::cli
