// Text from elsewhere (a take's name, a job's error, a token's name) made
// safe to print on a terminal: a name holding ESC [ 2 J or a cursor move
// must not rewrite the user's screen or fake other output.
#pragma once

#include <string>

#include "absl/strings/string_view.h"

namespace reenact {

// `text` with every control character (C0 but none, DEL, and C1 as
// U+0080..U+009F) and every byte that is not part of well-formed UTF-8
// written as a visible escape ("\x1b"); a backslash stays itself. Printable
// UTF-8 (accents, CJK, emoji) is kept as it is.
std::string TerminalSafe(absl::string_view text);

}  // namespace reenact
