// Pagination of the List RPCs (Takes, Jobs, Reenactments): page_size and
// page_token in, next_page_token out, over lists sorted newest first.
//
// Keyset, not offset: a token holds the sort key (time, id) of the last item
// sent, and the next page starts after it. Items created or deleted between
// two pages neither repeat nor shift the pages that follow, and a token stays
// valid for as long as the client likes. Tokens are opaque to clients (URL-
// safe base64 of "v1/<time>/<id>").
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"

namespace reenact::server {

// page_size 0 asks for this many.
inline constexpr int kDefaultPageSize = 100;
// A larger page_size is taken as this (AIP-158: coerce, don't refuse).
inline constexpr int kMaxPageSize = 1000;
// A page also ends once its items hold this many bytes (at least one item
// is always sent), so that no response nears the message size limit
// whatever the items hold.
inline constexpr size_t kMaxPageBytes = size_t{4} << 20;

// Where an item sorts: by time, newest first, then by id, descending.
struct PageKey {
  int64_t time_ns = 0;
  std::string id;
};

std::string EncodePageToken(const PageKey& key);
// InvalidArgument for a token EncodePageToken did not write.
absl::StatusOr<PageKey> DecodePageToken(std::string_view token);

// The first item of `keys` (sorted newest first) that comes after `after`.
size_t FirstAfter(const std::vector<PageKey>& keys, const PageKey& after);

// Hands the page of `items` (sorted newest first, as `key` says) that
// `page_size` and `page_token` ask for to `add`, in order, and returns the
// next page's token ("" after the last page). InvalidArgument for a
// negative page_size or a malformed token.
template <typename Item>
absl::StatusOr<std::string> Paginate(std::vector<Item> items, int32_t page_size,
                                     const std::string& page_token,
                                     const std::function<PageKey(const Item&)>& key,
                                     const std::function<void(Item&&)>& add) {
  if (page_size < 0) {
    return absl::InvalidArgumentError("page_size must not be negative");
  }
  const size_t limit = page_size == 0 ? kDefaultPageSize : std::min(page_size, kMaxPageSize);
  size_t first = 0;
  if (!page_token.empty()) {
    absl::StatusOr<PageKey> after = DecodePageToken(page_token);
    if (!after.ok()) return after.status();
    std::vector<PageKey> keys;
    keys.reserve(items.size());
    for (const Item& item : items) keys.push_back(key(item));
    first = FirstAfter(keys, *after);
  }
  size_t bytes = 0;
  size_t i = first;
  PageKey last;
  for (; i < items.size() && i - first < limit; ++i) {
    const size_t item_bytes = items[i].ByteSizeLong();
    if (i > first && bytes + item_bytes > kMaxPageBytes) break;
    bytes += item_bytes;
    last = key(items[i]);
    add(std::move(items[i]));
  }
  if (i >= items.size()) return std::string();
  return EncodePageToken(last);
}

}  // namespace reenact::server
