#include "common/ingest/uplink.h"

#include <thread>

#include <gtest/gtest.h>

#include "capture_daemon/testing/fake_ingest.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

v1::FrameSet MakeSet(uint64_t sequence) {
  v1::FrameSet set;
  set.set_sequence(sequence);
  set.set_stamp_ns(static_cast<int64_t>(sequence) * 33'333'333);
  v1::Frame* frame = set.add_frames();
  frame->set_sensor_id("k0");
  frame->mutable_depth()->set_data(std::string(2000, static_cast<char>(sequence)));
  return set;
}

v1::OpenTake MakeOpen(const std::string& take_id) {
  v1::OpenTake open;
  open.set_take_id(take_id);
  open.set_daemon_id("test-daemon");
  open.add_sensors()->set_sensor_id("k0");
  return open;
}

std::unique_ptr<ingest::Spool> MakeSpool(const std::string& name) {
  ingest::SpoolOptions options;
  options.dir = reenact::testing::MakeTempDir(name);
  auto spool = ingest::Spool::Open(options);
  EXPECT_TRUE(spool.ok()) << spool.status();
  return spool.ok() ? std::move(*spool) : nullptr;
}

TEST(TakeUplink, ResumesAfterStreamKilledAndDeliversEachSetOnceInOrder) {
  testing::FakeIngestServer server;
  ASSERT_TRUE(server.ok());
  server.service().set_kill_after_sets(37);
  server.service().set_ack_every(5);
  auto spool = MakeSpool("uplink_resume");
  ASSERT_NE(spool, nullptr);
  ingest::UplinkOptions options;
  std::atomic<uint64_t> acked{0};
  ingest::TakeUplink uplink(ingest::MakeIngestChannel(server.address(), options), options,
                            spool.get(), [&acked](uint64_t durable, int64_t) { acked = durable; });
  uplink.SetOpen(MakeOpen("take-resume"));
  // Sets arrive while the uplink streams.
  for (uint64_t s = 1; s <= 100; ++s) {
    ASSERT_TRUE(spool->Append(MakeSet(s)).ok());
    uplink.Notify();
    if (s % 10 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  v1::SensorLost lost;
  lost.set_sensor_id("k0");
  lost.set_reason("end of recording");
  uplink.SensorLost(lost);
  v1::CloseTake close;
  close.set_last_sequence(100);
  uplink.Close(close);
  ASSERT_TRUE(uplink.WaitDone(20.0));
  ASSERT_TRUE(uplink.result().ok()) << uplink.result();
  const auto takes = server.service().takes();
  ASSERT_EQ(takes.count("take-resume"), 1u);
  const testing::FakeTake& take = takes.at("take-resume");
  EXPECT_TRUE(take.closed);
  EXPECT_EQ(take.streams, 2) << "one reconnect";
  ASSERT_EQ(take.sets.size(), 100u);
  for (size_t i = 0; i < take.sets.size(); ++i) {
    EXPECT_EQ(take.sets[i].sequence(), i + 1);
    EXPECT_EQ(take.sets[i].SerializeAsString(), MakeSet(i + 1).SerializeAsString());
  }
  EXPECT_EQ(take.lost.size(), 1u);
  const ingest::UplinkStats stats = uplink.stats();
  EXPECT_EQ(stats.reconnects, 1);
  EXPECT_EQ(stats.durable_sequence, 100u);
  // The sets after the last Ack before the kill (35) went out again: the
  // service received 36 and 37 twice. The uplink counts a set as sent when its
  // write completed, and the write the kill interrupted may not have, so its
  // own count can be one lower.
  EXPECT_GE(server.service().sets_received(), 102u);
  EXPECT_GE(stats.frame_sets_sent, 101);
  EXPECT_EQ(acked.load(), 100u);
  EXPECT_EQ(spool->frame_sets(), 0) << "acknowledged sets are released";
  ASSERT_TRUE(uplink.closed().has_value());
  EXPECT_EQ(uplink.closed()->frame_set_count(), 100);
}

TEST(TakeUplink, NonRetryableStatusStopsTheTake) {
  testing::FakeIngestServer server;
  ASSERT_TRUE(server.ok());
  server.service().set_refuse_open(grpc::Status(grpc::StatusCode::PERMISSION_DENIED, "not yours"));
  auto spool = MakeSpool("uplink_refused");
  ASSERT_TRUE(spool->Append(MakeSet(1)).ok());
  ingest::UplinkOptions options;
  ingest::TakeUplink uplink(ingest::MakeIngestChannel(server.address(), options), options,
                            spool.get());
  uplink.SetOpen(MakeOpen("take-refused"));
  ASSERT_TRUE(uplink.WaitDone(10.0));
  EXPECT_TRUE(absl::IsPermissionDenied(uplink.result())) << uplink.result();
  EXPECT_NE(uplink.result().message().find("not yours"), std::string::npos);
  EXPECT_EQ(uplink.stats().reconnects, 0);
  EXPECT_EQ(spool->frame_sets(), 1) << "the spool keeps what was not acknowledged";
}

TEST(TakeUplink, RetriesWhileServerIsAwayThenDelivers) {
  // Find a free port, then leave it closed for a while.
  int port = 0;
  {
    testing::FakeIngestServer probe;
    ASSERT_TRUE(probe.ok());
    port = probe.port();
  }
  auto spool = MakeSpool("uplink_away");
  for (uint64_t s = 1; s <= 5; ++s) ASSERT_TRUE(spool->Append(MakeSet(s)).ok());
  ingest::UplinkOptions options;
  options.max_backoff_ms = 200;
  ingest::TakeUplink uplink(ingest::MakeIngestChannel("127.0.0.1:" + std::to_string(port), options),
                            options, spool.get());
  uplink.SetOpen(MakeOpen("take-away"));
  v1::CloseTake close;
  close.set_last_sequence(5);
  uplink.Close(close);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_FALSE(uplink.stats().done);
  EXPECT_GE(uplink.stats().reconnects, 2);
  EXPECT_FALSE(uplink.stats().connected);
  testing::FakeIngestServer server(port);
  ASSERT_TRUE(server.ok());
  ASSERT_TRUE(uplink.WaitDone(20.0));
  EXPECT_TRUE(uplink.result().ok()) << uplink.result();
  EXPECT_EQ(server.service().takes().at("take-away").sets.size(), 5u);
}

TEST(TakeUplink, AbortLeavesTheSpool) {
  auto spool = MakeSpool("uplink_abort");
  ASSERT_TRUE(spool->Append(MakeSet(1)).ok());
  ingest::UplinkOptions options;
  ingest::TakeUplink uplink(ingest::MakeIngestChannel("127.0.0.1:1", options), options,
                            spool.get());
  uplink.SetOpen(MakeOpen("take-abort"));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  uplink.Abort();
  ASSERT_TRUE(uplink.WaitDone(5.0));
  EXPECT_TRUE(absl::IsAborted(uplink.result())) << uplink.result();
  EXPECT_EQ(spool->frame_sets(), 1);
}

}  // namespace
}  // namespace reenact::capture
