#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/commands.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

// Synthesises a two-sensor take of `seconds` at 480x270 colour into `path`.
void SynthesizeSmallTake(const std::string& path, double seconds) {
  std::ostringstream out, err;
  ASSERT_EQ(
      RunSynth({"--motion", "builtin:arm-raise", "--seconds", std::to_string(seconds), "--sensors",
                "2", "--color-width", "480", "--color-height", "270", "--out", path, "--quiet"},
               out, err),
      kExitOk)
      << err.str();
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::map<std::string, int64_t> ChannelCounts(const nlohmann::json& info) {
  std::map<std::string, int64_t> counts;
  for (const auto& c : info.value("channels", nlohmann::json::array())) {
    counts[c["topic"].get<std::string>()] = c["messages"].get<int64_t>();
  }
  return counts;
}

nlohmann::json TakeInfoJson(const std::string& path, std::string* err_text = nullptr) {
  std::ostringstream out, err;
  const int code = RunTakeInfo({path, "--json"}, out, err);
  EXPECT_EQ(code, kExitOk) << err.str();
  if (err_text) *err_text = err.str();
  return code == kExitOk ? nlohmann::json::parse(out.str()) : nlohmann::json();
}

// Big-endian 32-bit value at `offset`.
uint32_t ReadU32(const std::string& bytes, size_t offset) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<uint8_t>(bytes[offset + i]);
  return v;
}

TEST(RunTakeInfo, ListsSensorsAndChannelCounts) {
  const std::string path = testing::MakeTempDir("take_info") + "/take.mcap";
  SynthesizeSmallTake(path, 0.3);
  const nlohmann::json info = TakeInfoJson(path);
  ASSERT_TRUE(info.contains("sensors"));
  ASSERT_EQ(info["sensors"].size(), 2u);
  EXPECT_EQ(info["sensors"][0]["id"].get<std::string>(), "k0");
  EXPECT_EQ(info["sensors"][1]["id"].get<std::string>(), "k1");
  const int64_t frames = info["frames"].get<int64_t>();
  ASSERT_GT(frames, 0);
  const auto counts = ChannelCounts(info);
  for (const char* id : {"k0", "k1"}) {
    for (const char* stream : {"color", "depth", "mask"}) {
      const std::string topic = std::string("/sensor/") + id + "/" + stream;
      ASSERT_TRUE(counts.count(topic)) << topic;
      EXPECT_EQ(counts.at(topic), frames) << topic;
    }
    // Like a real depth camera, a synthetic sensor gives no skeleton by
    // default (the capture daemon tracks one).
    const std::string skeleton = std::string("/sensor/") + id + "/skeleton";
    EXPECT_EQ(counts.count(skeleton) ? counts.at(skeleton) : 0, 0) << skeleton;
    EXPECT_EQ(counts.at(std::string("/sensor/") + id + "/calibration"), 1);
  }
  EXPECT_EQ(counts.at("/ground_truth/joints"), frames);
  EXPECT_TRUE(info["read"]["complete"].get<bool>());
}

TEST(RunTakeInfo, TruncatedTakeOpensAndReportsDamage) {
  const std::string dir = testing::MakeTempDir("take_truncated");
  const std::string full = dir + "/full.mcap";
  const std::string cut = dir + "/cut.mcap";
  // Long enough for several 4 MiB chunks, so that whole chunks survive.
  SynthesizeSmallTake(full, 1.2);
  std::filesystem::copy_file(full, cut);
  const auto full_bytes = std::filesystem::file_size(full);
  std::filesystem::resize_file(cut, full_bytes * 6 / 10);

  const nlohmann::json whole = TakeInfoJson(full);
  std::string err;
  const nlohmann::json damaged = TakeInfoJson(cut, &err);
  ASSERT_FALSE(damaged.is_null());
  EXPECT_FALSE(damaged["read"]["complete"].get<bool>());
  const uint64_t stop = damaged["read"]["stop_offset"].get<uint64_t>();
  std::cout << "full take " << full_bytes << " bytes, cut to " << full_bytes * 6 / 10
            << ", reading stopped at byte " << stop << "\n";
  EXPECT_LE(stop, full_bytes * 6 / 10);
  EXPECT_NE(err.find("damaged"), std::string::npos) << err;
  EXPECT_NE(err.find(std::to_string(stop)), std::string::npos) << err;

  const auto full_counts = ChannelCounts(whole);
  const auto cut_counts = ChannelCounts(damaged);
  for (const auto& [topic, count] : cut_counts) {
    ASSERT_TRUE(full_counts.count(topic)) << topic;
    EXPECT_LE(count, full_counts.at(topic)) << topic;
  }
  for (const char* topic :
       {"/take/info", "/sensor/k0/calibration", "/sensor/k0/depth", "/ground_truth/joints"}) {
    ASSERT_TRUE(cut_counts.count(topic)) << topic;
    EXPECT_GT(cut_counts.at(topic), 0) << topic;
  }
  EXPECT_LT(cut_counts.at("/sensor/k0/depth"), full_counts.at("/sensor/k0/depth"));
}

TEST(RunTakeInfo, CorruptOrMissingFileFails) {
  const std::string dir = testing::MakeTempDir("take_corrupt");
  const std::string noise = dir + "/noise.mcap";
  {
    std::ofstream out(noise, std::ios::binary);
    std::mt19937 rng(3);
    for (int i = 0; i < 4096; ++i) out.put(static_cast<char>(rng() & 0xff));
  }
  const std::string text = dir + "/notes.mcap";
  std::ofstream(text) << "this is a text file, not a take\n";
  for (const std::string& path : {noise, text}) {
    std::ostringstream out, err;
    EXPECT_EQ(RunTakeInfo({path}, out, err), kExitFailure) << err.str();
    EXPECT_NE(err.str().find(path), std::string::npos) << err.str();
  }
  std::ostringstream out, err;
  EXPECT_EQ(RunTakeInfo({dir + "/missing.mcap"}, out, err), kExitFailure) << err.str();
  EXPECT_NE(err.str().find("missing.mcap"), std::string::npos) << err.str();
}

TEST(RunTakeSheet, WritesOneRowPerSensorAndFrame) {
  const std::string dir = testing::MakeTempDir("take_sheet");
  const std::string take = dir + "/take.mcap";
  const std::string png = dir + "/sheet.png";
  SynthesizeSmallTake(take, 0.3);
  std::ostringstream out, err;
  ASSERT_EQ(RunTakeSheet({take, "--out", png, "--frames", "2"}, out, err), kExitOk) << err.str();
  ASSERT_TRUE(std::filesystem::exists(png));
  const std::string bytes = ReadBytes(png);
  ASSERT_GT(bytes.size(), 10000u);
  ASSERT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  ASSERT_EQ(bytes.substr(12, 4), "IHDR");
  const uint32_t width_px = ReadU32(bytes, 16);
  const uint32_t height_px = ReadU32(bytes, 20);
  std::cout << "sheet " << width_px << "x" << height_px << " px, " << bytes.size() << " bytes\n";
  EXPECT_EQ(height_px, 270u * 2 * 2);  // Cell height x sensors x frames.
  EXPECT_GT(width_px, 270u);
}

TEST(RunSynth, MissingOutIsUsageError) {
  std::ostringstream out, err;
  EXPECT_EQ(RunSynth({"--motion", "builtin:squat", "--seconds", "0.1"}, out, err), kExitUsage);
  EXPECT_NE(err.str().find("out"), std::string::npos) << err.str();
}

}  // namespace
}  // namespace reenact::cli
