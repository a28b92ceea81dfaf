#include "common/base/terminal_text.h"

#include <cstdio>

namespace reenact {
namespace {

// The length of the well-formed UTF-8 sequence at `s[i]` (RFC 3629), 0 when
// there is none.
size_t Utf8Length(const unsigned char* s, size_t n, size_t i) {
  const unsigned char lead = s[i];
  size_t length = 0;
  unsigned char low = 0x80, high = 0xBF;
  if (lead < 0x80) return 1;
  if (lead >= 0xC2 && lead <= 0xDF) {
    length = 2;
  } else if (lead >= 0xE0 && lead <= 0xEF) {
    length = 3;
    if (lead == 0xE0) low = 0xA0;
    if (lead == 0xED) high = 0x9F;
  } else if (lead >= 0xF0 && lead <= 0xF4) {
    length = 4;
    if (lead == 0xF0) low = 0x90;
    if (lead == 0xF4) high = 0x8F;
  } else {
    return 0;
  }
  if (n - i < length || s[i + 1] < low || s[i + 1] > high) return 0;
  for (size_t k = 2; k < length; ++k) {
    if (s[i + k] < 0x80 || s[i + k] > 0xBF) return 0;
  }
  return length;
}

void AppendEscape(unsigned char byte, std::string* out) {
  char escape[5];
  std::snprintf(escape, sizeof(escape), "\\x%02x", byte);
  out->append(escape);
}

}  // namespace

std::string TerminalSafe(absl::string_view text) {
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  std::string out;
  out.reserve(n);
  for (size_t i = 0; i < n;) {
    const size_t length = Utf8Length(s, n, i);
    if (length == 0) {
      AppendEscape(s[i], &out);
      ++i;
      continue;
    }
    if (length == 1) {
      if (s[i] < 0x20 || s[i] == 0x7F) {
        AppendEscape(s[i], &out);
      } else {
        out.push_back(static_cast<char>(s[i]));
      }
    } else if (length == 2 && s[i] == 0xC2 && s[i + 1] < 0xA0) {
      // U+0080..U+009F: C1 controls (CSI among them).
      AppendEscape(s[i], &out);
      AppendEscape(s[i + 1], &out);
    } else {
      out.append(text.data() + i, length);
    }
    i += length;
  }
  return out;
}

}  // namespace reenact
