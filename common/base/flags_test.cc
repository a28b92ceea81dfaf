#include "common/base/flags.h"

#include <gtest/gtest.h>

namespace reenact {
namespace {

TEST(Flags, ParsesValuesBooleansAndPositionals) {
  auto flags = Flags::Parse({"take.mcap", "--frame", "12", "--json", "--asf=a.asf"},
                            {"frame", "asf"}, {"json"});
  ASSERT_TRUE(flags.ok()) << flags.status();
  EXPECT_EQ(flags->positional(), std::vector<std::string>{"take.mcap"});
  EXPECT_EQ(*flags->GetInt("frame", 0), 12);
  EXPECT_TRUE(flags->Has("json"));
  EXPECT_EQ(flags->GetOr("asf", ""), "a.asf");
}

TEST(Flags, RejectsUnknownFlagAndMissingValue) {
  EXPECT_FALSE(Flags::Parse({"--bogus"}, {"frame"}, {}).ok());
  EXPECT_FALSE(Flags::Parse({"--frame"}, {"frame"}, {}).ok());
  auto flags = Flags::Parse({"--frame", "x"}, {"frame"}, {});
  ASSERT_TRUE(flags.ok());
  EXPECT_FALSE(flags->GetInt("frame", 0).ok());
}

}  // namespace
}  // namespace reenact
