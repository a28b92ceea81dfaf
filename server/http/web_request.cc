#include "server/http/web_request.h"

#include <algorithm>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"

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

}  // namespace reenact::server::http
