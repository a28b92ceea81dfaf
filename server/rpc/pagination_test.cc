#include "server/rpc/pagination.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "reenact/v1/takes_service.pb.h"

namespace reenact::server {
namespace {

std::vector<v1::Take> Takes(int n, size_t name_bytes) {
  std::vector<v1::Take> takes(n);
  for (int i = 0; i < n; ++i) {
    takes[i].set_take_id("t" + std::to_string(n - i));
    takes[i].set_created_unix_ns(1000 * (n - i));  // Newest first.
    takes[i].set_name(std::string(name_bytes, 'x'));
  }
  return takes;
}

std::vector<std::string> Page(const std::vector<v1::Take>& takes, int32_t size,
                              std::string* token) {
  std::vector<std::string> ids;
  absl::StatusOr<std::string> next = Paginate<v1::Take>(
      takes, size, *token,
      [](const v1::Take& t) {
        return PageKey{t.created_unix_ns(), t.take_id()};
      },
      [&ids](v1::Take&& t) { ids.push_back(t.take_id()); });
  EXPECT_TRUE(next.ok()) << next.status();
  *token = next.ok() ? *next : "";
  return ids;
}

TEST(Paginate, PagesEndAtTheByteBudgetWhateverTheSizeAsked) {
  // 3 MiB names (stored before names had a limit): one item a page, each
  // response well under the 64 MiB message limit.
  const std::vector<v1::Take> takes = Takes(5, 3 << 20);
  std::string token;
  std::vector<std::string> all;
  int pages = 0;
  do {
    const std::vector<std::string> ids = Page(takes, 1000, &token);
    EXPECT_EQ(ids.size(), 1u);
    all.insert(all.end(), ids.begin(), ids.end());
    ++pages;
  } while (!token.empty() && pages < 10);
  EXPECT_EQ(pages, 5);
  EXPECT_EQ(all, (std::vector<std::string>{"t5", "t4", "t3", "t2", "t1"}));
}

TEST(Paginate, SizesAndTokens) {
  const std::vector<v1::Take> takes = Takes(2500, 8);
  std::string token;
  EXPECT_EQ(Page(takes, 0, &token).size(), static_cast<size_t>(kDefaultPageSize));
  token.clear();
  EXPECT_EQ(Page(takes, 1 << 30, &token).size(), static_cast<size_t>(kMaxPageSize));
  EXPECT_EQ(Page(takes, 1 << 30, &token).size(), static_cast<size_t>(kMaxPageSize));
  EXPECT_EQ(Page(takes, 1 << 30, &token).size(), 500u);
  EXPECT_TRUE(token.empty());

  const absl::StatusOr<PageKey> key = DecodePageToken(EncodePageToken({-5, "a/b"}));
  ASSERT_TRUE(key.ok());
  EXPECT_EQ(key->time_ns, -5);
  EXPECT_EQ(key->id, "a/b");
  for (const std::string& bad : {std::string("x"), std::string(300, 'A'),
                                 EncodePageToken({1, "a"}).substr(2), std::string("djEvMQ")}) {
    EXPECT_EQ(DecodePageToken(bad).status().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

}  // namespace
}  // namespace reenact::server
