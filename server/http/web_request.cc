#include "server/http/web_request.h"

#include <algorithm>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "common/base/json_text.h"

namespace reenact::server::http {

bool PercentDecode(absl::string_view in, std::string* out) {
  out->clear();
  out->reserve(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] == '\0') return false;
    if (in[i] != '%') {
      out->push_back(in[i]);
      continue;
    }
    if (i + 2 >= in.size() || !absl::ascii_isxdigit(in[i + 1]) ||
        !absl::ascii_isxdigit(in[i + 2])) {
      return false;
    }
    const auto hex = [](char c) {
      return absl::ascii_isdigit(c) ? c - '0' : absl::ascii_tolower(c) - 'a' + 10;
    };
    const char c = static_cast<char>(hex(in[i + 1]) * 16 + hex(in[i + 2]));
    if (c == '\0') return false;
    out->push_back(c);
    i += 2;
  }
  return true;
}

bool ParseQuery(absl::string_view query, std::map<std::string, std::string>* out) {
  out->clear();
  for (absl::string_view pair : absl::StrSplit(query, '&', absl::SkipEmpty())) {
    const size_t equals = pair.find('=');
    std::string key, value;
    std::string raw_value(equals == absl::string_view::npos ? "" : pair.substr(equals + 1));
    std::replace(raw_value.begin(), raw_value.end(), '+', ' ');
    if (!PercentDecode(pair.substr(0, equals), &key) || !PercentDecode(raw_value, &value)) {
      return false;
    }
    (*out)[key] = value;
  }
  return true;
}

bool ParseTarget(absl::string_view target, std::string* path,
                 std::map<std::string, std::string>* query) {
  query->clear();
  const size_t question = target.find('?');
  if (!PercentDecode(target.substr(0, question), path) || path->empty() || path->front() != '/') {
    return false;
  }
  return question == absl::string_view::npos || ParseQuery(target.substr(question + 1), query);
}

bool ParseByteRange(absl::string_view header, int64_t size, int64_t* first, int64_t* last,
                    bool* ignore) {
  *ignore = false;
  constexpr absl::string_view kUnit = "bytes=";
  if (!absl::StartsWith(header, kUnit) || absl::StrContains(header, ',')) {
    *ignore = true;
    return false;
  }
  const absl::string_view spec = absl::StripAsciiWhitespace(header.substr(kUnit.size()));
  const size_t dash = spec.find('-');
  if (dash == absl::string_view::npos) {
    *ignore = true;
    return false;
  }
  const absl::string_view a = spec.substr(0, dash), b = spec.substr(dash + 1);
  int64_t x = 0, y = 0;
  if (a.empty()) {  // Suffix: the last N bytes.
    if (!absl::SimpleAtoi(b, &y) || y < 0) {
      *ignore = true;
      return false;
    }
    if (y == 0 || size == 0) return false;
    *first = std::max<int64_t>(0, size - y);
    *last = size - 1;
    return true;
  }
  if (!absl::SimpleAtoi(a, &x) || x < 0 || (!b.empty() && (!absl::SimpleAtoi(b, &y) || y < x))) {
    *ignore = true;
    return false;
  }
  if (x >= size) return false;
  *first = x;
  *last = b.empty() ? size - 1 : std::min(y, size - 1);
  return true;
}

bool IsUtf8(absl::string_view text) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  size_t i = 0;
  while (i < n) {
    const unsigned char lead = bytes[i];
    if (lead < 0x80) {
      ++i;
      continue;
    }
    size_t length = 0;
    unsigned char low = 0x80, high = 0xBF;  // The second byte's range.
    if (lead >= 0xC2 && lead <= 0xDF) {
      length = 2;
    } else if (lead >= 0xE0 && lead <= 0xEF) {
      length = 3;
      if (lead == 0xE0) low = 0xA0;   // No overlong forms.
      if (lead == 0xED) high = 0x9F;  // No surrogates.
    } else if (lead >= 0xF0 && lead <= 0xF4) {
      length = 4;
      if (lead == 0xF0) low = 0x90;   // No overlong forms.
      if (lead == 0xF4) high = 0x8F;  // Nothing above U+10FFFF.
    } else {
      return false;
    }
    if (n - i < length) return false;
    if (bytes[i + 1] < low || bytes[i + 1] > high) return false;
    for (size_t k = 2; k < length; ++k) {
      if (bytes[i + k] < 0x80 || bytes[i + k] > 0xBF) return false;
    }
    i += length;
  }
  return true;
}

std::string ErrorBody(absl::string_view code, absl::string_view message) {
  return JsonText(
      nlohmann::json{{"error", {{"code", std::string(code)}, {"message", std::string(message)}}}});
}

}  // namespace reenact::server::http
