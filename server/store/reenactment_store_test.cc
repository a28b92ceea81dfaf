#include "server/store/reenactment_store.h"

#include <filesystem>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using reenact::testing::MakeTestReenactment;
using reenact::testing::TestReenactmentOptions;

// Writes a test reenactment with `id` where the store expects it.
void WriteFor(ReenactmentStore& store, const std::string& id, const std::string& take_id,
              int64_t created_unix_ns, int keyframes = 2) {
  TestReenactmentOptions options;
  options.id = id;
  options.keyframes = keyframes;
  ReenactmentData data = MakeTestReenactment(options);
  data.info.set_take_id(take_id);
  data.info.set_created_unix_ns(created_unix_ns);
  ASSERT_TRUE(WriteReenactmentFile(data, store.PathFor(id)).ok());
}

TEST(ReenactmentStore, NewIdsFollowThePatternAndDiffer) {
  auto store = ReenactmentStore::Open(reenact::testing::MakeTempDir("rstore_id") + "/r");
  ASSERT_TRUE(store.ok()) << store.status();
  const std::regex pattern("r-[0-9]{8}-[0-9]{6}-[0-9a-f]{4}");
  const std::string a = (*store)->NewId(), b = (*store)->NewId();
  EXPECT_TRUE(std::regex_match(a, pattern)) << a;
  EXPECT_NE(a, b);
  EXPECT_EQ((*store)->PathFor(a), (*store)->dir() + "/" + a + ".reen");
}

TEST(ReenactmentStore, AddsListsGetsAndDeletes) {
  const std::string dir = reenact::testing::MakeTempDir("rstore_add") + "/reenactments";
  auto opened = ReenactmentStore::Open(dir);
  ASSERT_TRUE(opened.ok()) << opened.status();
  ReenactmentStore& store = **opened;
  EXPECT_TRUE(store.List().empty());

  WriteFor(store, "r-old", "take-a", 1000, 3);
  WriteFor(store, "r-new", "take-b", 3000);
  WriteFor(store, "r-mid", "take-a", 2000);
  for (const std::string id : {"r-old", "r-new", "r-mid"}) {
    auto added = store.Add(id);
    ASSERT_TRUE(added.ok()) << added.status();
  }
  auto old = store.Get("r-old");
  ASSERT_TRUE(old.ok());
  EXPECT_EQ(old->info().reenactment_id(), "r-old");
  EXPECT_EQ(old->part_count(), 3);
  EXPECT_EQ(old->keyframe_count(), 3);
  EXPECT_EQ(old->file_bytes(), static_cast<int64_t>(fs::file_size(store.PathFor("r-old"))));
  EXPECT_EQ(store.Add("r-old").status().code(), absl::StatusCode::kAlreadyExists);

  const auto all = store.List();
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].info().reenactment_id(), "r-new");
  EXPECT_EQ(all[1].info().reenactment_id(), "r-mid");
  EXPECT_EQ(all[2].info().reenactment_id(), "r-old");
  const auto of_a = store.List("take-a");
  ASSERT_EQ(of_a.size(), 2u);
  EXPECT_EQ(of_a[0].info().reenactment_id(), "r-mid");
  EXPECT_TRUE(store.List("take-z").empty());

  EXPECT_EQ(store.Get("r-none").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store.Delete("r-none").code(), absl::StatusCode::kNotFound);
  ASSERT_TRUE(store.Delete("r-mid").ok());
  EXPECT_FALSE(fs::exists(store.PathFor("r-mid")));
  EXPECT_EQ(store.Get("r-mid").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store.List().size(), 2u);
}

TEST(ReenactmentStore, AddRefusesBadFilesAndLeavesThem) {
  auto opened = ReenactmentStore::Open(reenact::testing::MakeTempDir("rstore_bad"));
  ASSERT_TRUE(opened.ok());
  ReenactmentStore& store = **opened;
  EXPECT_EQ(store.Add("r-missing").status().code(), absl::StatusCode::kNotFound);
  ASSERT_TRUE(WriteFileAtomically(store.PathFor("r-junk"), "not a reenactment").ok());
  EXPECT_EQ(store.Add("r-junk").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(fs::exists(store.PathFor("r-junk")));
  // A valid file whose info names another reenactment.
  WriteFor(store, "r-other", "t", 1);
  fs::rename(store.PathFor("r-other"), store.PathFor("r-renamed"));
  EXPECT_EQ(store.Add("r-renamed").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(store.Add("../escape").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(store.List().empty());
}

TEST(ReenactmentStore, OpenIndexesFilesSkipsBadOnesAndRemovesTemporaries) {
  const std::string dir = reenact::testing::MakeTempDir("rstore_reopen");
  {
    auto store = ReenactmentStore::Open(dir);
    ASSERT_TRUE(store.ok());
    WriteFor(**store, "r-a", "t1", 10, 4);
    WriteFor(**store, "r-b", "t2", 20);
    ASSERT_TRUE((*store)->Add("r-a").ok());
  }
  ASSERT_TRUE(WriteFileAtomically(dir + "/r-broken.reen", "garbage").ok());
  ASSERT_TRUE(WriteFileAtomically(dir + "/r-dead.reen.tmp", "half written").ok());
  ASSERT_TRUE(WriteFileAtomically(dir + "/notes.txt", "kept").ok());

  auto store = ReenactmentStore::Open(dir);
  ASSERT_TRUE(store.ok()) << store.status();
  const auto all = (*store)->List();
  ASSERT_EQ(all.size(), 2u);  // r-b was never added but its file is whole.
  EXPECT_EQ(all[0].info().reenactment_id(), "r-b");
  auto a = (*store)->Get("r-a");
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->keyframe_count(), 4);
  EXPECT_EQ(a->info().take_id(), "t1");
  EXPECT_TRUE(fs::exists(dir + "/r-broken.reen"));  // Left for inspection.
  EXPECT_FALSE(fs::exists(dir + "/r-dead.reen.tmp"));
  EXPECT_TRUE(fs::exists(dir + "/notes.txt"));
}

// A body-model reenactment (no parts, no keyframes, a body mesh) is
// summarised on Add and when Open indexes it again.
TEST(ReenactmentStore, SummarisesBodyReenactments) {
  const std::string dir = reenact::testing::MakeTempDir("rstore_body");
  const ReenactmentData data = reenact::testing::MakeTestBodyReenactment(7, "r-body");
  {
    auto store = ReenactmentStore::Open(dir);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE(WriteReenactmentFile(data, (*store)->PathFor("r-body")).ok());
    auto added = (*store)->Add("r-body");
    ASSERT_TRUE(added.ok()) << added.status();
    EXPECT_EQ(added->part_count(), 0);
    EXPECT_EQ(added->keyframe_count(), 0);
    EXPECT_EQ(added->info().SerializeAsString(), data.info.SerializeAsString());
  }
  auto store = ReenactmentStore::Open(dir);
  ASSERT_TRUE(store.ok()) << store.status();
  auto got = (*store)->Get("r-body");
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_EQ(got->info().method(), "body");
  EXPECT_EQ(got->info().frame_count(), 7);
  EXPECT_EQ(got->part_count(), 0);
  EXPECT_EQ(got->keyframe_count(), 0);
  EXPECT_EQ(got->file_bytes(), static_cast<int64_t>(fs::file_size((*store)->PathFor("r-body"))));
}

}  // namespace
}  // namespace reenact::server
