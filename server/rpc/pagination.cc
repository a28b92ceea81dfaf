#include "server/rpc/pagination.h"

#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace reenact::server {
namespace {

constexpr char kTokenVersion[] = "v1";
// Ids are at most 64 characters; a token is never much longer.
constexpr size_t kMaxTokenChars = 256;

bool Before(const PageKey& a, const PageKey& b) {
  if (a.time_ns != b.time_ns) return a.time_ns > b.time_ns;
  return a.id > b.id;
}

}  // namespace

std::string EncodePageToken(const PageKey& key) {
  return absl::WebSafeBase64Escape(absl::StrCat(kTokenVersion, "/", key.time_ns, "/", key.id));
}

absl::StatusOr<PageKey> DecodePageToken(std::string_view token_view) {
  const absl::string_view token(token_view.data(), token_view.size());
  const absl::Status bad = absl::InvalidArgumentError(
      "page_token is not one this server gave (pass next_page_token as it came)");
  if (token.size() > kMaxTokenChars) return bad;
  std::string text;
  if (!absl::WebSafeBase64Unescape(token, &text)) return bad;
  const std::vector<absl::string_view> fields = absl::StrSplit(text, absl::MaxSplits('/', 2));
  PageKey key;
  if (fields.size() != 3 || fields[0] != kTokenVersion ||
      !absl::SimpleAtoi(fields[1], &key.time_ns) || fields[2].empty()) {
    return bad;
  }
  key.id = std::string(fields[2]);
  return key;
}

size_t FirstAfter(const std::vector<PageKey>& keys, const PageKey& after) {
  // Sorted newest first: the items that come after `after` are a suffix.
  size_t i = 0;
  while (i < keys.size() && !Before(after, keys[i])) ++i;
  return i;
}

}  // namespace reenact::server
