#include "common/base/nearest_name.h"

#include <gtest/gtest.h>

#include "common/base/flags.h"

namespace reenact {
namespace {

TEST(EditDistance, CountsInsertionsDeletionsAndSubstitutions) {
  EXPECT_EQ(EditDistance("", ""), 0);
  EXPECT_EQ(EditDistance("abc", ""), 3);
  EXPECT_EQ(EditDistance("kitten", "sitting"), 3);
  EXPECT_EQ(EditDistance("submit", "sumbit"), 2);
  EXPECT_EQ(EditDistance("jobs", "job"), 1);
}

TEST(NearestName, SuggestsTyposAndPrefixesButNotStrangers) {
  const std::vector<std::string> names = {"reenactment", "server", "format", "out", "json"};
  EXPECT_EQ(NearestName("sever", names), "server");
  EXPECT_EQ(NearestName("fromat", names), "format");
  EXPECT_EQ(NearestName("reen", names), "reenactment");
  EXPECT_EQ(NearestName("jsn", names), "json");
  EXPECT_EQ(NearestName("colour", names), std::nullopt);
  EXPECT_EQ(NearestName("server", names), std::nullopt) << "a known name needs no suggestion";
  EXPECT_EQ(NearestName("", names), std::nullopt);
}

TEST(Flags, AnUnknownFlagNamesTheNearestKnownOne) {
  const auto typo = Flags::Parse({"--sever", "x:1"}, {"server", "out"}, {"json"});
  ASSERT_FALSE(typo.ok());
  EXPECT_EQ(typo.status().message(), "unknown flag --sever (did you mean --server?)");
  const auto stranger = Flags::Parse({"--colour"}, {"server", "out"}, {"json"});
  ASSERT_FALSE(stranger.ok());
  EXPECT_EQ(stranger.status().message(), "unknown flag --colour");
}

}  // namespace
}  // namespace reenact
