// Interoperability: takes written by TakeWriter must open in any MCAP reader.
// tests/js/check_take.mjs reads them with @mcap/core and prints JSON, which
// these tests compare with what was written.
//
// Setup (once per checkout): npm ci --prefix tests/js
//                        or: npm install --prefix tests/js
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/base/files.h"
#include "common/io/take.h"
#include "common/io/testing/small_take.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

const std::string kJsDir = std::string(REENACT_SOURCE_DIR) + "/tests/js";

// Skips the test (loudly) when node or the npm packages are missing.
#define REQUIRE_NODE_TOOLS()                                                               \
  do {                                                                                     \
    if (std::system("node --version > /dev/null 2>&1") != 0) {                             \
      GTEST_SKIP() << "\n*** SKIPPED: node is not installed; the independent MCAP reader " \
                      "check did not run. ***";                                            \
    }                                                                                      \
    if (!std::filesystem::exists(kJsDir + "/node_modules/@mcap/core")) {                   \
      GTEST_SKIP() << "\n*** SKIPPED: " << kJsDir                                          \
                   << "/node_modules is missing; run `npm ci --prefix tests/js` (or "      \
                      "`npm install --prefix tests/js`). ***";                             \
    }                                                                                      \
  } while (false)

// Runs check_take.mjs on `path` and parses its JSON output.
nlohmann::json RunCheck(const std::string& path, bool stream) {
  const std::string command =
      "node '" + kJsDir + "/check_take.mjs' " + (stream ? "--stream '" : "'") + path + "' 2>&1";
  std::FILE* pipe = ::popen(command.c_str(), "r");
  EXPECT_NE(pipe, nullptr) << command;
  if (pipe == nullptr) return {};
  std::string output;
  char buffer[4096];
  for (size_t n; (n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0;) output.append(buffer, n);
  ::pclose(pipe);
  const nlohmann::json result = nlohmann::json::parse(output, nullptr, false);
  EXPECT_FALSE(result.is_discarded()) << "check_take.mjs printed no JSON:\n" << output;
  return result;
}

std::map<std::string, uint64_t> Counts(const nlohmann::json& counts) {
  std::map<std::string, uint64_t> out;
  for (const auto& [topic, n] : counts.items()) out[topic] = n.get<uint64_t>();
  return out;
}

TEST(TakeInterop, IndexedReaderSeesEveryChannelAndMessage) {
  REQUIRE_NODE_TOOLS();
  const std::string path = testing::MakeTempDir("take_interop") + "/take.mcap";
  TakeWriterOptions options;
  options.mcap.chunk_size_bytes = 8192;
  const testing::WrittenTake written = testing::WriteTestTake(path, 2, 20, options);
  const nlohmann::json result = RunCheck(path, /*stream=*/false);
  ASSERT_TRUE(result.contains("channels")) << result.dump(2);
  EXPECT_TRUE(result["problems"].empty()) << result["problems"].dump(2);

  std::map<std::string, uint64_t> expected;
  uint64_t total = 0;
  for (const auto& [topic, messages] : written.messages_by_topic) {
    expected[topic] = messages.size();
    total += messages.size();
  }
  EXPECT_EQ(Counts(result["counts"]), expected);
  EXPECT_EQ(Counts(result["statistics_counts"]), expected);
  EXPECT_EQ(result["message_count"].get<uint64_t>(), total);
  EXPECT_GT(result["chunk_count"].get<int>(), 1);

  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  std::map<std::string, std::string> types;
  for (const TakeChannel& c : (*reader)->channels()) types[c.topic] = c.message_type;
  ASSERT_EQ(result["channels"].size(), expected.size());
  for (const auto& channel : result["channels"]) {
    const std::string topic = channel["topic"];
    EXPECT_EQ(channel["schema_name"], types[topic]) << topic;
    EXPECT_EQ(channel["schema_encoding"], "protobuf") << topic;
    EXPECT_EQ(channel["message_encoding"], "protobuf") << topic;
    EXPECT_GT(channel["schema_bytes"].get<int>(), 100) << topic;
  }
}

TEST(TakeInterop, StreamReaderAgreesOnTruncatedTake) {
  REQUIRE_NODE_TOOLS();
  const std::string path = testing::MakeTempDir("take_interop_cut") + "/take.mcap";
  TakeWriterOptions options;
  options.mcap.chunk_size_bytes = 4096;
  testing::WriteTestTake(path, 2, 30, options);
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  ASSERT_TRUE(WriteFileAtomically(path, bytes->substr(0, bytes->size() / 2)).ok());

  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  ASSERT_FALSE((*reader)->report().complete);
  std::map<std::string, uint64_t> ours;
  uint64_t total = 0;
  for (const TakeChannel& c : (*reader)->channels()) {
    ours[c.topic] = c.message_count;
    total += c.message_count;
  }
  EXPECT_GT(total, 0u);

  const nlohmann::json result = RunCheck(path, /*stream=*/true);
  ASSERT_TRUE(result.contains("counts")) << result.dump(2);
  // The independent reader must also notice the truncation.
  EXPECT_FALSE(result["problems"].empty());
  EXPECT_EQ(Counts(result["counts"]), ours);
  EXPECT_EQ(result["message_count"].get<uint64_t>(), total);
}

}  // namespace
}  // namespace reenact
