#include "clients/cli/progress_bar.h"

#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "absl/strings/str_split.h"

namespace reenact::cli {
namespace {

Progress At(const std::string& stage, double fraction, int64_t done) {
  Progress p;
  p.stage = stage;
  p.fraction = fraction;
  p.items_done = done;
  p.items_total = 100;
  return p;
}

TEST(ProgressBar, PipedOutputIsPlainLinesPerStageAndTenPercent) {
  std::ostringstream err;  // Not a terminal.
  ProgressBar bar(err, /*enabled=*/true);
  for (int i = 0; i <= 100; ++i) bar.Update(At(i < 50 ? "load" : "fit", i / 100.0, i));
  bar.Finish();
  const std::string text = err.str();
  EXPECT_EQ(text.find('\r'), std::string::npos) << text;
  const std::vector<std::string> lines = absl::StrSplit(text, '\n', absl::SkipEmpty());
  // load at 0, 10, ..., 40 %; fit at 50, 60, ..., 100 %: 11 lines.
  ASSERT_EQ(lines.size(), 11u) << text;
  EXPECT_NE(lines.front().find("load"), std::string::npos);
  EXPECT_NE(lines[5].find("fit"), std::string::npos);
  EXPECT_NE(lines.back().find("100.0%"), std::string::npos);
  EXPECT_NE(lines.back().find("100/100"), std::string::npos);
}

TEST(ProgressLine, OnATerminalOneLineIsRedrawnInPlace) {
  std::ostringstream err;
  ProgressLine line(err, /*enabled=*/true, /*terminal=*/true);
  line.Show("load", 0.1, "load 10%");
  line.Show("load", 0.2, "load 20% and more");
  line.Show("load", 0.3, "load 30%");
  line.EndLine();
  EXPECT_EQ(err.str(), "\rload 10%\rload 20% and more\rload 30%         \n");
}

TEST(ProgressLine, DisabledPrintsNothing) {
  std::ostringstream err;
  ProgressLine line(err, /*enabled=*/false, /*terminal=*/false);
  line.Show("load", 1.0, "done");
  line.EndLine();
  EXPECT_TRUE(err.str().empty());
}

}  // namespace
}  // namespace reenact::cli
