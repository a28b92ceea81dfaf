#include "capture_daemon/live_frames.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "capture_daemon/daemon.h"
#include "capture_daemon/testing/fake_ingest.h"
#include "capture_daemon/testing/synthetic_take.h"
#include "common/base/files.h"
#include "common/testing/test_data.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {
namespace {

v1::FrameSet SetWithSkeleton(int64_t stamp_ns) {
  v1::FrameSet set;
  set.set_stamp_ns(stamp_ns);
  v1::Frame* frame = set.add_frames();
  frame->set_sensor_id("k0");
  frame->add_skeletons()->set_sensor_id("k0");
  return set;
}

TEST(LiveFrames, ASlowSubscriberGetsTheNewestSet) {
  LiveFrames live;
  std::mutex mutex;
  std::vector<uint64_t> indices;
  bool ended = false;
  live.Subscribe({}, [&](std::shared_ptr<const v1::LiveFrameSet> set) {
    std::lock_guard<std::mutex> lock(mutex);
    if (set == nullptr) {
      ended = true;
      return;
    }
    indices.push_back(set->set_index());
    EXPECT_EQ(set->skeletons_size(), 1);
  });
  for (int i = 1; i <= 200; ++i) live.Publish(SetWithSkeleton(i));  // Never waits.
  for (int i = 0; i < 200; ++i) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (!indices.empty() && indices.back() == 200u) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  live.Close();
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_FALSE(indices.empty());
  EXPECT_EQ(indices.back(), 200u) << "the newest set always arrives";
  EXPECT_TRUE(std::is_sorted(indices.begin(), indices.end()));
  EXPECT_TRUE(ended);
}

TEST(MakeLiveFrameSet, FiltersSkeletonsAndShrinksColour) {
  v1::FrameSet set = SetWithSkeleton(5);
  v1::Frame* other = set.add_frames();
  other->set_sensor_id("k1");
  other->add_skeletons()->set_sensor_id("k1");
  v1::StreamFramesRequest request;
  request.add_sensor_ids("k1");
  const v1::LiveFrameSet live = MakeLiveFrameSet(set, 7, request);
  EXPECT_EQ(live.set_index(), 7u);
  EXPECT_EQ(live.stamp_ns(), 5);
  ASSERT_EQ(live.skeletons_size(), 1);
  EXPECT_EQ(live.skeletons(0).sensor_id(), "k1");
  EXPECT_EQ(live.colors_size(), 0);
}

// A daemon streaming a synthetic take in a loop (no take recorded), and a
// stub on its control address.
class StreamFramesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(server_.ok());
    const std::string dir = reenact::testing::MakeTempDir("daemon_stream_frames");
    DaemonOptions options;
    options.server_address = server_.address();
    options.sources = {{"playback", testing::SyntheticTakePath()}};
    options.loop = true;
    options.control_address = "127.0.0.1:0";
    options.control_port_file = dir + "/control";
    options.spool_dir = dir + "/spool";
    options.daemon_id = "test-daemon";
    auto daemon = Daemon::Create(options);
    ASSERT_TRUE(daemon.ok()) << daemon.status();
    daemon_ = std::move(*daemon);
    runner_ = std::thread([this] { result_ = daemon_->Run(); });
    std::string address;
    for (int i = 0; i < 250 && address.empty(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      address = ReadFileToString(options.control_port_file).value_or("");
    }
    ASSERT_FALSE(address.empty());
    address.pop_back();  // Newline.
    stub_ = v1::CaptureControl::NewStub(
        grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));
  }
  void TearDown() override {
    if (daemon_ == nullptr) return;
    daemon_->RequestStop();
    runner_.join();
    EXPECT_TRUE(result_.ok()) << result_;
  }

  testing::FakeIngestServer server_;
  std::unique_ptr<Daemon> daemon_;
  std::thread runner_;
  absl::Status result_;
  std::unique_ptr<v1::CaptureControl::Stub> stub_;
};

TEST_F(StreamFramesTest, StreamsSkeletonsAndShrunkColourUntilTheClientStops) {
  ASSERT_NE(stub_, nullptr);
  v1::StreamFramesRequest request;
  request.add_color_sensor_ids("k0");
  request.set_color_max_width_px(160);
  grpc::ClientContext context;
  auto reader = stub_->StreamFrames(&context, request);
  v1::LiveFrameSet set;
  int sets = 0;
  int skeletons = 0;
  uint64_t last_index = 0;
  while (sets < 20 && reader->Read(&set)) {
    ++sets;
    skeletons += set.skeletons_size();
    EXPECT_GT(set.set_index(), last_index);
    last_index = set.set_index();
    ASSERT_EQ(set.colors_size(), 1);
    EXPECT_EQ(set.colors(0).sensor_id(), "k0");
    EXPECT_EQ(set.colors(0).width_px(), 160);  // 320 px shrunk 2x.
    EXPECT_EQ(set.colors(0).height_px(), 90);
  }
  std::cout << sets << " live sets, " << skeletons << " skeletons, last set " << last_index
            << ", dropped " << set.dropped_sets() << "\n";
  EXPECT_EQ(sets, 20);
  EXPECT_GE(skeletons, 2 * 20 - 2) << "both sensors' skeletons, nearly every set";
  context.TryCancel();  // The client stops early.
  while (reader->Read(&set)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);

  // The daemon goes on: another client streams, and the status answers.
  grpc::ClientContext again;
  auto second = stub_->StreamFrames(&again, v1::StreamFramesRequest());
  ASSERT_TRUE(second->Read(&set));
  EXPECT_EQ(set.colors_size(), 0);
  again.TryCancel();
  while (second->Read(&set)) {
  }
  (void)second->Finish();
  grpc::ClientContext status_context;
  v1::DaemonStatus status;
  EXPECT_TRUE(stub_->Status(&status_context, {}, &status).ok());
}

TEST_F(StreamFramesTest, UnknownSensorIsInvalidArgument) {
  ASSERT_NE(stub_, nullptr);
  for (const bool colour : {false, true}) {
    v1::StreamFramesRequest request;
    if (colour) {
      request.add_color_sensor_ids("k9");
    } else {
      request.add_sensor_ids("k9");
    }
    grpc::ClientContext context;
    auto reader = stub_->StreamFrames(&context, request);
    v1::LiveFrameSet set;
    EXPECT_FALSE(reader->Read(&set));
    const grpc::Status status = reader->Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(status.error_message().find("k9"), std::string::npos) << status.error_message();
  }
}

TEST_F(StreamFramesTest, AStreamEndsWhenTheDaemonStops) {
  ASSERT_NE(stub_, nullptr);
  grpc::ClientContext context;
  auto reader = stub_->StreamFrames(&context, v1::StreamFramesRequest());
  v1::LiveFrameSet set;
  ASSERT_TRUE(reader->Read(&set));
  daemon_->RequestStop();
  int more = 0;
  while (reader->Read(&set)) ++more;
  EXPECT_TRUE(reader->Finish().ok());
  runner_.join();
  EXPECT_TRUE(result_.ok()) << result_;
  daemon_.reset();
}

}  // namespace
}  // namespace reenact::capture
