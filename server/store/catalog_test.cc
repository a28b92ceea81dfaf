#include "server/store/catalog.h"

#include <string>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "common/base/files.h"
#include "common/testing/test_data.h"

namespace reenact::server {
namespace {

TakeRow MakeRow(const std::string& id, int64_t created_ns, v1::TakeState state) {
  TakeRow row;
  row.path = "takes/" + id + ".mcap";
  row.first_stamp_ns = 1000;
  row.last_stamp_ns = 1000 + 33'000'000 * 9;
  v1::Take& t = row.take;
  t.set_take_id(id);
  t.set_name("name " + id);
  t.set_state(state);
  t.set_daemon_id("daemon-a");
  t.set_created_unix_ns(created_ns);
  t.set_updated_unix_ns(created_ns + 5);
  t.set_durable_sequence(10);
  t.set_frame_set_count(10);
  t.set_duration_ns(row.last_stamp_ns - row.first_stamp_ns);
  t.set_size_bytes(123456789012);
  t.set_generator("reenactd 0.1.0");
  t.set_synthetic(true);
  t.set_fps(29.97);
  for (const char* sensor : {"k0", "k1"}) {
    v1::TakeSensor* s = t.add_sensors();
    s->set_sensor_id(sensor);
    s->set_model("kinect_v2");
    s->set_frame_count(10);
  }
  t.mutable_sensors(1)->set_lost_stamp_ns(777);
  t.mutable_sensors(1)->set_lost_reason("unplugged");
  return row;
}

void ExpectSameRow(const TakeRow& a, const TakeRow& b) {
  EXPECT_EQ(a.take.SerializeAsString(), b.take.SerializeAsString())
      << a.take.DebugString() << "\nvs\n"
      << b.take.DebugString();
  EXPECT_EQ(a.path, b.path);
  EXPECT_EQ(a.first_stamp_ns, b.first_stamp_ns);
  EXPECT_EQ(a.last_stamp_ns, b.last_stamp_ns);
}

TEST(Catalog, UsesWalAndVersionedSchema) {
  const std::string path = testing::MakeTempDir("catalog_wal") + "/catalog.sqlite";
  auto catalog = Catalog::Open(path);
  ASSERT_TRUE(catalog.ok()) << catalog.status();
  EXPECT_EQ(*(*catalog)->JournalMode(), "wal");
  EXPECT_EQ(*(*catalog)->SchemaVersion(), Catalog::kSchemaVersion);
}

TEST(Catalog, RowsSurviveReopen) {
  const std::string path = testing::MakeTempDir("catalog_reopen") + "/catalog.sqlite";
  const TakeRow row = MakeRow("take-1", 100, v1::TAKE_STATE_COMPLETE);
  {
    auto catalog = Catalog::Open(path);
    ASSERT_TRUE(catalog.ok());
    ASSERT_TRUE((*catalog)->Put(row).ok());
  }
  auto catalog = Catalog::Open(path);
  ASSERT_TRUE(catalog.ok()) << catalog.status();
  auto got = (*catalog)->Get("take-1");
  ASSERT_TRUE(got.ok()) << got.status();
  ExpectSameRow(row, *got);
  EXPECT_EQ(*(*catalog)->SchemaVersion(), Catalog::kSchemaVersion);
}

TEST(Catalog, PutReplacesRowAndSensors) {
  auto catalog = Catalog::Open(testing::MakeTempDir("catalog_replace") + "/c.sqlite");
  ASSERT_TRUE(catalog.ok());
  TakeRow row = MakeRow("t", 100, v1::TAKE_STATE_RECORDING);
  ASSERT_TRUE((*catalog)->Put(row).ok());
  row.take.set_state(v1::TAKE_STATE_INTERRUPTED);
  row.take.set_durable_sequence(42);
  row.take.mutable_sensors()->RemoveLast();
  ASSERT_TRUE((*catalog)->Put(row).ok());
  auto got = (*catalog)->Get("t");
  ASSERT_TRUE(got.ok());
  ExpectSameRow(row, *got);
  EXPECT_EQ(got->take.sensors_size(), 1);
}

TEST(Catalog, ListsNewestFirstAndFiltersByState) {
  auto catalog = Catalog::Open(testing::MakeTempDir("catalog_list") + "/c.sqlite");
  ASSERT_TRUE(catalog.ok());
  ASSERT_TRUE((*catalog)->Put(MakeRow("old", 100, v1::TAKE_STATE_COMPLETE)).ok());
  ASSERT_TRUE((*catalog)->Put(MakeRow("new", 300, v1::TAKE_STATE_INTERRUPTED)).ok());
  ASSERT_TRUE((*catalog)->Put(MakeRow("mid", 200, v1::TAKE_STATE_COMPLETE)).ok());
  auto all = (*catalog)->List(v1::TAKE_STATE_UNSPECIFIED);
  ASSERT_TRUE(all.ok());
  ASSERT_EQ(all->size(), 3u);
  EXPECT_EQ((*all)[0].take.take_id(), "new");
  EXPECT_EQ((*all)[1].take.take_id(), "mid");
  EXPECT_EQ((*all)[2].take.take_id(), "old");
  EXPECT_EQ((*all)[0].take.sensors_size(), 2);
  auto complete = (*catalog)->List(v1::TAKE_STATE_COMPLETE);
  ASSERT_TRUE(complete.ok());
  ASSERT_EQ(complete->size(), 2u);
  EXPECT_EQ((*complete)[0].take.take_id(), "mid");
  EXPECT_TRUE((*catalog)->List(v1::TAKE_STATE_RECORDING)->empty());
}

TEST(Catalog, DeleteRemovesTakeAndSensors) {
  auto catalog = Catalog::Open(testing::MakeTempDir("catalog_delete") + "/c.sqlite");
  ASSERT_TRUE(catalog.ok());
  ASSERT_TRUE((*catalog)->Put(MakeRow("t", 100, v1::TAKE_STATE_COMPLETE)).ok());
  ASSERT_TRUE((*catalog)->Delete("t").ok());
  EXPECT_EQ((*catalog)->Get("t").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ((*catalog)->Delete("t").code(), absl::StatusCode::kNotFound);
  // No orphaned sensors come back with a take of the same id.
  TakeRow bare = MakeRow("t", 100, v1::TAKE_STATE_COMPLETE);
  bare.take.clear_sensors();
  ASSERT_TRUE((*catalog)->Put(bare).ok());
  EXPECT_EQ((*catalog)->Get("t")->take.sensors_size(), 0);
}

TEST(Catalog, RefusesNewerSchemaAndForeignFiles) {
  const std::string dir = testing::MakeTempDir("catalog_bad");
  {
    auto catalog = Catalog::Open(dir + "/newer.sqlite");
    ASSERT_TRUE(catalog.ok());
  }
  {
    // A later build's catalog: bump the version behind the catalog's back.
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir + "/newer.sqlite").c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 99", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  auto newer = Catalog::Open(dir + "/newer.sqlite");
  EXPECT_EQ(newer.status().code(), absl::StatusCode::kFailedPrecondition) << newer.status();
  EXPECT_NE(newer.status().message().find("99"), std::string::npos);
  ASSERT_TRUE(WriteFileAtomically(dir + "/text.sqlite", std::string(4096, 'x')).ok());
  auto foreign = Catalog::Open(dir + "/text.sqlite");
  EXPECT_FALSE(foreign.ok());
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kDataLoss) << foreign.status();
}

}  // namespace
}  // namespace reenact::server
