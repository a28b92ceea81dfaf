// The client SDK's ReenactmentSource: reenactment files in a folder (local)
// and the server's Reenactments service over loopback with a cache folder
// (remote), behind one interface.
#include "clients/sdk/reenactment_source.h"

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"
#include "tests/testing/reenactments_server.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;
using testing::MakeTestBodyReenactment;
using testing::MakeTestReenactment;
using testing::TestReenactmentOptions;

// `loaded` holds what `stored` holds (both written as messages the way a
// reader converts them).
void ExpectSame(const Reenactment& loaded, const ReenactmentData& stored) {
  const ReenactmentData a = ReenactmentToProto(loaded);
  const ReenactmentData b = ReenactmentToProto(testing::ToPlain(stored));
  EXPECT_EQ(a.info.SerializeAsString(), b.info.SerializeAsString());
  ASSERT_EQ(a.parts.size(), b.parts.size());
  ASSERT_EQ(a.frames.size(), b.frames.size());
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  ASSERT_EQ(a.body.size(), b.body.size());
  for (size_t i = 0; i < a.frames.size(); ++i) {
    EXPECT_EQ(a.frames[i].SerializeAsString(), b.frames[i].SerializeAsString());
  }
  for (size_t i = 0; i < a.body.size(); ++i) {
    EXPECT_EQ(a.body[i].SerializeAsString(), b.body[i].SerializeAsString());
  }
}

ReenactmentData Rigid(const std::string& id, int64_t created) {
  TestReenactmentOptions options;
  options.id = id;
  options.frames = 12;
  options.keyframes = 3;
  ReenactmentData data = MakeTestReenactment(options);
  data.info.set_created_unix_ns(created);
  return data;
}

TEST(LocalReenactmentSource, ListsAndLoadsTheFilesOfAFolder) {
  const std::string dir = testing::MakeTempDir("source_local");
  const ReenactmentData rigid = Rigid("r-old", 1000);
  ReenactmentData body = MakeTestBodyReenactment(4, "r-new");
  body.info.set_created_unix_ns(2000);
  ASSERT_TRUE(WriteReenactmentFile(rigid, dir + "/r-old.reen").ok());
  // A file named otherwise is found by the id inside it.
  ASSERT_TRUE(WriteReenactmentFile(body, dir + "/teacher.reen").ok());
  std::ofstream(dir + "/broken.reen") << "not a reenactment";
  std::ofstream(dir + "/notes.txt") << "ignored";

  auto source = client::OpenReenactmentSource(dir);
  ASSERT_TRUE(source.ok()) << source.status();
  auto list = (*source)->List();
  ASSERT_TRUE(list.ok()) << list.status();
  ASSERT_EQ(list->size(), 2u) << "the damaged file is left out";
  EXPECT_EQ((*list)[0].info().reenactment_id(), "r-new");
  EXPECT_EQ((*list)[1].info().reenactment_id(), "r-old");
  EXPECT_EQ((*list)[1].part_count(), 3);
  EXPECT_GT((*list)[1].file_bytes(), 0);

  auto loaded = (*source)->Load("r-new");
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ExpectSame(*loaded, body);
  auto old = (*source)->Load("r-old");
  ASSERT_TRUE(old.ok());
  ExpectSame(*old, rigid);
  EXPECT_EQ((*source)->Load("r-missing").status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE((*source)->Describe().find(dir), std::string::npos);

  // One file is a source too.
  auto single = client::OpenReenactmentSource(dir + "/teacher.reen");
  ASSERT_TRUE(single.ok());
  ASSERT_TRUE((*single)->Load("r-new").ok());
  EXPECT_EQ(client::OpenReenactmentSource(dir + "/nothing").status().code(),
            absl::StatusCode::kNotFound);
}

using Server = testing::ReenactmentsTestServer;

TEST(RemoteReenactmentSource, FetchesOnceAndServesTheCacheAfter) {
  Server server("source_remote");
  const ReenactmentData rigid = Rigid("r-rigid", 1000);
  ReenactmentData body = MakeTestBodyReenactment(5, "r-body");
  body.info.set_created_unix_ns(2000);
  server.Store(rigid);
  server.Store(body);
  const std::string cache = testing::MakeTempDir("source_cache") + "/cache";

  auto source = client::OpenReenactmentSource("grpc:" + server.address, cache);
  ASSERT_TRUE(source.ok()) << source.status();
  auto list = (*source)->List();
  ASSERT_TRUE(list.ok()) << list.status();
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ((*list)[0].info().reenactment_id(), "r-body");

  auto first = (*source)->Load("r-body");
  ASSERT_TRUE(first.ok()) << first.status();
  ExpectSame(*first, body);
  ASSERT_TRUE(fs::exists(cache + "/r-body.reen")) << "a fetched reenactment is cached";

  // The cached copy serves the next load: mark it, and the mark comes back.
  Reenactment marked = *first;
  marked.info.figures["cached"] = 1.0;
  ASSERT_TRUE(WriteReenactment(marked, cache + "/r-body.reen").ok());
  auto second = (*source)->Load("r-body");
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(second->info.figures.count("cached"), 1u);

  // A cached copy of another version (other creation time) is fetched again.
  marked.info.figures["cached"] = 2.0;
  marked.info.created_unix_ns = 1;
  ASSERT_TRUE(WriteReenactment(marked, cache + "/r-body.reen").ok());
  auto third = (*source)->Load("r-body");
  ASSERT_TRUE(third.ok());
  EXPECT_EQ(third->info.figures.count("cached"), 0u);
  ExpectSame(*third, body);

  // Rigid, with and without keyframes; unknown ids.
  auto no_keyframes = (*source)->Load("r-rigid", /*skip_keyframes=*/true);
  ASSERT_TRUE(no_keyframes.ok());
  EXPECT_TRUE(no_keyframes->keyframes.empty());
  EXPECT_FALSE(fs::exists(cache + "/r-rigid.reen")) << "only whole reenactments are cached";
  auto whole = (*source)->Load("r-rigid");
  ASSERT_TRUE(whole.ok());
  ExpectSame(*whole, rigid);
  EXPECT_TRUE(fs::exists(cache + "/r-rigid.reen"));
  EXPECT_EQ((*source)->Load("r-missing").status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE((*source)->Describe().find(server.address), std::string::npos);
}

TEST(OpenReenactmentSource, RejectsAnEmptyAddress) {
  EXPECT_EQ(client::OpenReenactmentSource("grpc:").status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(client::DefaultReenactmentCacheDir().empty());
}

}  // namespace
}  // namespace reenact
