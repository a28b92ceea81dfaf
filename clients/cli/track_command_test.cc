#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

struct Result {
  int code = 0;
  std::string out, err;
};

Result Track(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  Result r;
  r.code = RunTrack(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

TEST(RunTrack, FindsTheFivePeopleOfARealFrameAsJson) {
  const std::string png =
      testing::TestDataPath("rgbd/pcl-five-people/derived/five_people_depth_mm.png");
  REENACT_REQUIRE_TEST_FILE(png);
  const Result r = Track({"--depth", png, "--intrinsics", "kinect1", "--json"});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["width"], 640);
  ASSERT_EQ(j["people"].size(), 5u);
  for (const nlohmann::json& person : j["people"]) {
    ASSERT_EQ(person["joints"].size(), 25u);
    const nlohmann::json& head = person["joints"]["Head"];
    const nlohmann::json& hand = person["joints"]["HandLeft"];
    ASSERT_TRUE(head.contains("position_m") && head.contains("pixel") &&
                head.contains("confidence") && head.contains("state"));
    // Standing 1.5-3 m away; the head is above the SpineBase (y down).
    const double head_z = head["position_m"][2].get<double>();
    EXPECT_GT(head_z, 1.5);
    EXPECT_LT(head_z, 3.0);
    EXPECT_LT(head["position_m"][1].get<double>(),
              person["joints"]["SpineBase"]["position_m"][1].get<double>());
    const std::string state = hand["state"].get<std::string>();
    EXPECT_TRUE(state == "tracked" || state == "inferred" || state == "not_tracked") << state;
  }
}

TEST(RunTrack, RawDepthOfTheStatedSizeIsReadAndNobodyIsAnEmptyList) {
  // A flat wall 3 m away: nobody.
  const std::string path = testing::MakeTempDir("track_raw") + "/wall.raw";
  {
    std::ofstream out(path, std::ios::binary);
    for (int i = 0; i < 512 * 424; ++i) {
      const uint16_t mm = 3000;
      out.put(static_cast<char>(mm & 0xff));
      out.put(static_cast<char>(mm >> 8));
    }
  }
  const Result r =
      Track({"--depth", path, "--size", "512x424", "--intrinsics", "kinect2", "--json"});
  ASSERT_EQ(r.code, kExitOk) << r.err;
  EXPECT_TRUE(nlohmann::json::parse(r.out)["people"].empty());
  // The wrong size, a hostile size and bad intrinsics are clear errors.
  const Result wrong = Track({"--depth", path, "--size", "640x480", "--intrinsics", "kinect2"});
  EXPECT_NE(wrong.code, kExitOk);
  EXPECT_NE(wrong.err.find("bytes"), std::string::npos) << wrong.err;
  const Result huge = Track({"--depth", path, "--size", "99999x99999", "--intrinsics", "kinect2"});
  EXPECT_NE(huge.code, kExitOk);
  EXPECT_NE(huge.err.find("--size"), std::string::npos) << huge.err;
  const Result nan = Track({"--depth", path, "--size", "512x424", "--intrinsics", "nan,1,2,3"});
  EXPECT_NE(nan.code, kExitOk);
  const Result three = Track({"--depth", path, "--size", "512x424", "--intrinsics", "1,2,3"});
  EXPECT_NE(three.code, kExitOk);
  EXPECT_NE(three.err.find("--intrinsics"), std::string::npos) << three.err;
}

TEST(RunTrack, MissingAndCorruptFilesAreErrors) {
  EXPECT_NE(Track({"--depth", "/nonexistent.png", "--intrinsics", "kinect2"}).code, kExitOk);
  EXPECT_NE(Track({"--intrinsics", "kinect2"}).code, kExitOk);
  const std::string path = testing::MakeTempDir("track_corrupt") + "/corrupt.png";
  {
    std::ofstream out(path, std::ios::binary);
    out << "\x89PNG\r\n\x1a\n not really a png";
  }
  const Result r = Track({"--depth", path, "--intrinsics", "kinect2"});
  EXPECT_NE(r.code, kExitOk);
  EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
}

}  // namespace
}  // namespace reenact::cli
