#include "common/ingest/spool.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::ingest {
namespace {

namespace fs = std::filesystem;

// A set whose depth payload is `bytes` long and depends on the sequence.
v1::FrameSet MakeSet(uint64_t sequence, size_t bytes) {
  v1::FrameSet set;
  set.set_sequence(sequence);
  set.set_stamp_ns(static_cast<int64_t>(sequence) * 33'333'333);
  v1::Frame* frame = set.add_frames();
  frame->set_sensor_id("k0");
  frame->set_frame_index(static_cast<int64_t>(sequence));
  std::string data(bytes, '\0');
  for (size_t i = 0; i < bytes; ++i) data[i] = static_cast<char>((i * 7 + sequence) & 0xff);
  frame->mutable_depth()->set_data(data);
  return set;
}

int CountSegments(const std::string& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".spool";
  return n;
}

std::string LastSegment(const std::string& dir) {
  std::string last;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".spool") last = std::max(last, e.path().string());
  }
  return last;
}

SpoolOptions Options(const std::string& dir) {
  SpoolOptions options;
  options.dir = dir;
  options.max_bytes = 4 << 20;
  options.segment_bytes = 64 << 10;
  options.cache_bytes = 0;  // Read everything back from disk.
  return options;
}

TEST(Spool, AppendReadBackAckReleasesSegments) {
  const std::string dir = reenact::testing::MakeTempDir("spool_basic");
  auto spool = Spool::Open(Options(dir));
  ASSERT_TRUE(spool.ok()) << spool.status();
  for (uint64_t s = 1; s <= 50; ++s) {
    int64_t bytes = 0;
    ASSERT_TRUE((*spool)->Append(MakeSet(s, 10'000 + s), &bytes).ok());
    EXPECT_GT(bytes, 10'000);
  }
  EXPECT_EQ((*spool)->frame_sets(), 50);
  EXPECT_EQ((*spool)->last_sequence(), 50u);
  const int segments = CountSegments(dir);
  EXPECT_GE(segments, 7) << "10 kB sets in 64 KiB segments";
  for (uint64_t s = 1; s <= 50; ++s) {
    auto set = (*spool)->Take(s);
    ASSERT_TRUE(set.ok()) << set.status();
    EXPECT_EQ(set->SerializeAsString(), MakeSet(s, 10'000 + s).SerializeAsString());
  }
  const int64_t before = (*spool)->bytes();
  ASSERT_TRUE((*spool)->Ack(20).ok());
  EXPECT_EQ((*spool)->first_sequence(), 21u);
  EXPECT_LT((*spool)->bytes(), before);
  EXPECT_LT(CountSegments(dir), segments);
  EXPECT_TRUE(absl::IsNotFound((*spool)->Take(20).status()));
  EXPECT_TRUE((*spool)->Take(21).ok());
  ASSERT_TRUE((*spool)->Ack(50).ok());
  EXPECT_EQ((*spool)->bytes(), 0);
  EXPECT_EQ((*spool)->frame_sets(), 0);
  EXPECT_EQ(CountSegments(dir), 0);
  // Numbering goes on after everything was released.
  EXPECT_TRUE(absl::IsInvalidArgument((*spool)->Append(MakeSet(50, 10))));
  EXPECT_TRUE((*spool)->Append(MakeSet(51, 10)).ok());
  EXPECT_TRUE(absl::IsInvalidArgument((*spool)->Append(MakeSet(53, 10))));
}

TEST(Spool, CacheHandsOverWithoutChangingContent) {
  const std::string dir = reenact::testing::MakeTempDir("spool_cache");
  SpoolOptions options = Options(dir);
  options.cache_bytes = 1 << 20;
  auto spool = Spool::Open(options);
  ASSERT_TRUE(spool.ok());
  ASSERT_TRUE((*spool)->Append(MakeSet(1, 5000)).ok());
  auto first = (*spool)->Take(1);   // From the cache.
  auto second = (*spool)->Take(1);  // From disk (a resend).
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_EQ(first->SerializeAsString(), second->SerializeAsString());
  EXPECT_EQ(first->SerializeAsString(), MakeSet(1, 5000).SerializeAsString());
}

TEST(Spool, BoundRefusesNewSetsAndKeepsOldOnes) {
  const std::string dir = reenact::testing::MakeTempDir("spool_bound");
  SpoolOptions options = Options(dir);
  options.max_bytes = 1 << 20;
  auto spool = Spool::Open(options);
  ASSERT_TRUE(spool.ok());
  uint64_t next = 1;
  absl::Status status;
  while ((status = (*spool)->Append(MakeSet(next, 100'000))).ok()) ++next;
  EXPECT_TRUE(absl::IsResourceExhausted(status)) << status;
  const uint64_t accepted = next - 1;
  EXPECT_EQ(accepted, 10u) << "1 MiB holds ten 100 kB sets";
  EXPECT_LE((*spool)->bytes(), options.max_bytes);
  EXPECT_TRUE(absl::IsResourceExhausted((*spool)->Append(MakeSet(next, 100'000))));
  EXPECT_EQ((*spool)->refused(), 2);
  for (uint64_t s = 1; s <= accepted; ++s) EXPECT_TRUE((*spool)->Take(s).ok()) << s;
  // Acknowledging frees whole segments, and appending resumes.
  ASSERT_TRUE((*spool)->Ack(accepted).ok());
  EXPECT_TRUE((*spool)->Append(MakeSet(next, 100'000)).ok());
}

TEST(Spool, ReopenCutsTornTailAndFindsUnacknowledged) {
  const std::string dir = reenact::testing::MakeTempDir("spool_reopen");
  {
    auto spool = Spool::Open(Options(dir));
    ASSERT_TRUE(spool.ok());
    for (uint64_t s = 1; s <= 12; ++s) ASSERT_TRUE((*spool)->Append(MakeSet(s, 20'000)).ok());
    ASSERT_TRUE((*spool)->Ack(3).ok());
    ASSERT_TRUE((*spool)->WriteMeta("open.pb", "hello").ok());
  }
  // An unclean stop: the last record is only half written.
  const std::string last = LastSegment(dir);
  const auto size = fs::file_size(last);
  fs::resize_file(last, size - 7'000);
  auto spool = Spool::Open(Options(dir));
  ASSERT_TRUE(spool.ok()) << spool.status();
  const SpoolRecovery& recovery = (*spool)->recovery();
  std::cout << "recovery: " << recovery.detail << "\n";
  EXPECT_EQ((*spool)->first_sequence(), 4u) << "1..3 were acknowledged and released";
  EXPECT_EQ((*spool)->last_sequence(), 11u);
  EXPECT_GT(recovery.cut_bytes, 0);
  EXPECT_LT(recovery.cut_bytes, 20'100);
  EXPECT_TRUE((*spool)->Take(11).ok());
  EXPECT_TRUE(absl::IsNotFound((*spool)->Take(12).status()));
  auto meta = (*spool)->ReadMeta("open.pb");
  ASSERT_TRUE(meta.ok() && meta->has_value());
  EXPECT_EQ(**meta, "hello");
  // The cut record is appended again.
  EXPECT_TRUE((*spool)->Append(MakeSet(12, 20'000)).ok());
  EXPECT_EQ((*spool)->Take(12)->SerializeAsString(), MakeSet(12, 20'000).SerializeAsString());
}

TEST(Spool, ReopenCutsAtCorruptRecord) {
  const std::string dir = reenact::testing::MakeTempDir("spool_corrupt");
  {
    auto spool = Spool::Open(Options(dir));
    ASSERT_TRUE(spool.ok());
    for (uint64_t s = 1; s <= 2; ++s) ASSERT_TRUE((*spool)->Append(MakeSet(s, 20'000)).ok());
  }
  // Flip one payload byte of the second record.
  const std::string segment = LastSegment(dir);
  std::fstream file(segment, std::ios::in | std::ios::out | std::ios::binary);
  const auto at = static_cast<std::streamoff>(fs::file_size(segment) - 100);
  file.seekg(at);
  const char byte = static_cast<char>(file.get());
  file.seekp(at);
  file.put(static_cast<char>(byte ^ 0xff));
  file.close();
  auto spool = Spool::Open(Options(dir));
  ASSERT_TRUE(spool.ok());
  EXPECT_EQ((*spool)->last_sequence(), 1u);
  EXPECT_NE((*spool)->recovery().detail.find("CRC"), std::string::npos)
      << (*spool)->recovery().detail;
}

TEST(Spool, RejectsBadOptions) {
  SpoolOptions options;
  EXPECT_TRUE(absl::IsInvalidArgument(Spool::Open(options).status()));
  options.dir = "/proc/reenact-no-such/spool";
  EXPECT_FALSE(Spool::Open(options).ok());
}

}  // namespace
}  // namespace reenact::ingest
