#include "common/base/terminal_text.h"

#include <gtest/gtest.h>

namespace reenact {
namespace {

TEST(TerminalSafe, EscapesControlsAndBrokenUtf8AndKeepsPrintableText) {
  EXPECT_EQ(TerminalSafe("squat 3"), "squat 3");
  EXPECT_EQ(TerminalSafe("caf\xC3\xA9 \xE6\x97\xA5 \xF0\x9F\x92\x83"),
            "caf\xC3\xA9 \xE6\x97\xA5 \xF0\x9F\x92\x83");
  // A screen clear, a cursor move, a bell, a newline that would fake a row.
  EXPECT_EQ(TerminalSafe("a\x1b[2Jb"), "a\\x1b[2Jb");
  EXPECT_EQ(TerminalSafe("x\ry\x07\nz\x7f"), "x\\x0dy\\x07\\x0az\\x7f");
  // C1 CSI (U+009B) and bytes that are not UTF-8.
  EXPECT_EQ(TerminalSafe("\xC2\x9B"
                         "31m"),
            "\\xc2\\x9b31m");
  EXPECT_EQ(TerminalSafe("\xff\xfe\xC0\xAE"), "\\xff\\xfe\\xc0\\xae");
  EXPECT_EQ(TerminalSafe("\xE2\x82"), "\\xe2\\x82");  // Cut short.
  EXPECT_EQ(TerminalSafe(std::string("a\0b", 3)), "a\\x00b");
}

}  // namespace
}  // namespace reenact
