#include "common/log/log.h"

#include <cstdint>
#include <limits>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace reenact::log {
namespace {

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST(Log, JsonLinesParseAndCarryEveryField) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kJson, Level::kInfo});
  const std::string take_id = "take-1";
  logger.Info("take_opened",
              {{"take_id", take_id},
               {"sensors", 2},
               {"bytes", uint64_t{1} << 40},
               {"ratio", 0.25},
               {"resumed", false},
               {"negative", int64_t{-7}}},
              "take take-1 opened");
  const std::vector<std::string> lines = Lines(out.str());
  ASSERT_EQ(lines.size(), 1u) << out.str();
  const nlohmann::json j = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(j["level"], "info");
  EXPECT_EQ(j["event"], "take_opened");
  EXPECT_EQ(j["msg"], "take take-1 opened");
  EXPECT_EQ(j["take_id"], "take-1");
  EXPECT_EQ(j["sensors"], 2);
  EXPECT_EQ(j["bytes"].get<uint64_t>(), uint64_t{1} << 40);
  EXPECT_DOUBLE_EQ(j["ratio"].get<double>(), 0.25);
  EXPECT_EQ(j["resumed"], false);
  EXPECT_EQ(j["negative"], -7);
  // RFC 3339 in UTC with microseconds.
  EXPECT_TRUE(std::regex_match(j["ts"].get<std::string>(),
                               std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z)")))
      << j["ts"];
}

TEST(Log, JsonEscapesQuotesControlCharactersAndBadUtf8) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kJson, Level::kDebug});
  const std::string nasty = "a \"quoted\" \\ name\nwith\ttabs \x01 and \xff\xfe bytes";
  logger.Warn("auth_refused", {{"peer", nasty}, {"msg", "a field named like a key"}}, nasty);
  const std::vector<std::string> lines = Lines(out.str());
  ASSERT_EQ(lines.size(), 1u) << out.str();  // The newline in the value stays escaped.
  const nlohmann::json j = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(j["level"], "warn");
  const std::string peer = j["peer"].get<std::string>();
  EXPECT_THAT(peer, ::testing::HasSubstr("a \"quoted\" \\ name\nwith\ttabs \x01 and "));
  EXPECT_THAT(peer, ::testing::HasSubstr("\xef\xbf\xbd"));  // U+FFFD for the bad bytes.
  EXPECT_EQ(j["msg"].get<std::string>(), peer);
  // A reserved key does not overwrite the message.
  EXPECT_EQ(j["field_msg"], "a field named like a key");
}

TEST(Log, NonFiniteNumbersStayValidJson) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kJson, Level::kInfo});
  logger.Info("figures", {{"nan", std::numeric_limits<double>::quiet_NaN()},
                          {"inf", std::numeric_limits<double>::infinity()}});
  const nlohmann::json j = nlohmann::json::parse(Lines(out.str()).at(0));
  EXPECT_TRUE(j["nan"].is_null());
  EXPECT_TRUE(j["inf"].is_null());
}

TEST(Log, LevelDropsLowerLines) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kJson, Level::kWarn});
  logger.Debug("a");
  logger.Info("b");
  logger.Warn("c");
  logger.Error("d");
  EXPECT_FALSE(logger.Enabled(Level::kInfo));
  EXPECT_TRUE(logger.Enabled(Level::kError));
  const std::vector<std::string> lines = Lines(out.str());
  ASSERT_EQ(lines.size(), 2u) << out.str();
  EXPECT_EQ(nlohmann::json::parse(lines[0])["event"], "c");
  EXPECT_EQ(nlohmann::json::parse(lines[1])["level"], "error");
}

TEST(Log, TextLinesKeepValuesReadable) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kText, Level::kInfo});
  logger.Info("job_failed", {{"job_id", "j-1"}, {"error", "worker said \"no\"\nthen left"}},
              "job j-1 failed");
  const std::vector<std::string> lines = Lines(out.str());
  ASSERT_EQ(lines.size(), 1u) << out.str();
  EXPECT_TRUE(std::regex_match(
      lines[0],
      std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z info job_failed: job j-1 failed )"
                 R"(job_id=j-1 error="worker said \\"no\\"\\nthen left")")))
      << lines[0];
}

TEST(Log, NullDestinationDropsEverything) {
  const Logger logger(nullptr, {Format::kJson, Level::kDebug});
  EXPECT_FALSE(logger.Enabled(Level::kError));
  logger.Error("nothing");  // Must not crash.
}

TEST(Log, ConcurrentLinesNeverInterleave) {
  std::ostringstream out;
  const Logger logger(&out, {Format::kJson, Level::kInfo});
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&logger, t] {
      for (int i = 0; i < 200; ++i) logger.Info("tick", {{"thread", t}, {"i", i}});
    });
  }
  for (std::thread& thread : threads) thread.join();
  const std::vector<std::string> lines = Lines(out.str());
  ASSERT_EQ(lines.size(), 800u);
  for (const std::string& line : lines) {
    EXPECT_TRUE(nlohmann::json::accept(line)) << line;
  }
}

TEST(Log, ParseOptionsNamesTheFlag) {
  auto ok = ParseOptions("json", "debug");
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_EQ(ok->format, Format::kJson);
  EXPECT_EQ(ok->level, Level::kDebug);
  EXPECT_THAT(std::string(ParseOptions("xml", "info").status().message()),
              ::testing::HasSubstr("--log-format"));
  EXPECT_THAT(std::string(ParseOptions("text", "loud").status().message()),
              ::testing::HasSubstr("--log-level"));
}

}  // namespace
}  // namespace reenact::log
