#include "server/rpc/ingest_service.h"

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/take.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::ExpectStoredFrameSets;
using testing::IngestClient;
using testing::MakeFrameSet;
using testing::MakeOpenTake;
using testing::SensorIds;
using testing::TestServer;

constexpr int kSensors = 2;

std::unique_ptr<TestServer> StartServer(const std::string& name, ServerOptions options = {}) {
  options.max_message_mb = 1;  // Test sets are ~10 KB; a 2 MB message is "oversized".
  return TestServer::Start(reenact::testing::MakeTempDir(name), options);
}

// Waits until the take leaves RECORDING (its stream's end is asynchronous).
v1::Take WaitNotRecording(TestServer& t, const std::string& take_id) {
  v1::Take take;
  for (int i = 0; i < 500; ++i) {
    EXPECT_TRUE(t.GetTake(take_id, &take).ok());
    if (take.state() != v1::TAKE_STATE_RECORDING) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return take;
}

TEST(Ingest, StreamsFrameSetsAcksAndCloses) {
  auto t = StartServer("ingest_stream");
  ASSERT_NE(t, nullptr);
  IngestClient client(*t->ingest);
  ASSERT_TRUE(client.Open(MakeOpenTake("take-1", "daemon-a", kSensors)));
  const auto opened = client.ReadOpened();
  ASSERT_TRUE(opened.has_value());
  EXPECT_EQ(opened->take_id(), "take-1");
  EXPECT_EQ(opened->durable_sequence(), 0u);
  EXPECT_FALSE(opened->resumed());
  constexpr uint64_t kSets = 30;
  ASSERT_TRUE(client.SendSets(1, kSets, kSensors));
  ASSERT_TRUE(client.WaitAck(kSets));
  ASSERT_TRUE(client.Close(kSets));
  ASSERT_TRUE(client.Finish().ok());
  // Acks rise strictly and reach the last set.
  ASSERT_FALSE(client.acks().empty());
  for (size_t i = 1; i < client.acks().size(); ++i) {
    EXPECT_GT(client.acks()[i], client.acks()[i - 1]);
  }
  EXPECT_EQ(client.acks().back(), kSets);
  ASSERT_TRUE(client.closed().has_value());
  const v1::TakeClosed& closed = *client.closed();
  EXPECT_EQ(closed.take_id(), "take-1");
  EXPECT_EQ(closed.durable_sequence(), kSets);
  EXPECT_EQ(closed.frame_set_count(), static_cast<int64_t>(kSets));
  EXPECT_EQ(closed.frame_count(), static_cast<int64_t>(kSets * kSensors));
  EXPECT_EQ(closed.size_bytes(), static_cast<int64_t>(fs::file_size(t->TakePath("take-1"))));
  v1::Take take;
  ASSERT_TRUE(t->GetTake("take-1", &take).ok());
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(take.daemon_id(), "daemon-a");
  ExpectStoredFrameSets(t->TakePath("take-1"), SensorIds(kSensors), kSets);
}

TEST(Ingest, ClosesRightAfterSendingWithoutWaitingForAcks) {
  auto t = StartServer("ingest_pipelined");
  ASSERT_NE(t, nullptr);
  IngestClient client(*t->ingest);
  ASSERT_TRUE(client.Open(MakeOpenTake("t", "d", 1)));
  ASSERT_TRUE(client.SendSets(1, 12, 1));
  ASSERT_TRUE(client.Close(12));
  ASSERT_TRUE(client.Finish().ok());
  ASSERT_TRUE(client.closed().has_value());
  EXPECT_EQ(client.closed()->durable_sequence(), 12u);
  ExpectStoredFrameSets(t->TakePath("t"), SensorIds(1), 12);
}

TEST(Ingest, FlowControlPausesReadingUntilTheDiskCatchesUp) {
  ServerOptions options;
  options.ingest_queue_limit_bytes = 1;  // Pause after every set.
  auto t = StartServer("ingest_flow", options);
  ASSERT_NE(t, nullptr);
  IngestClient client(*t->ingest);
  ASSERT_TRUE(client.Open(MakeOpenTake("t", "d", kSensors)));
  ASSERT_TRUE(client.SendSets(1, 20, kSensors));
  ASSERT_TRUE(client.Close(20));
  ASSERT_TRUE(client.Finish().ok());
  EXPECT_EQ(client.closed()->durable_sequence(), 20u);
  ExpectStoredFrameSets(t->TakePath("t"), SensorIds(kSensors), 20);
}

// A refused message after three good sets: the stream ends with `code`, the
// take keeps sets 1..3, is INTERRUPTED, and resumes at 4.
struct BadMessage {
  std::string name;
  std::function<v1::IngestRequest()> make;
  grpc::StatusCode code;
  std::string message;  // Expected in the status message.
};

v1::IngestRequest SetRequest(const v1::FrameSet& set) {
  v1::IngestRequest r;
  *r.mutable_frame_set() = set;
  return r;
}

v1::IngestRequest MutatedSet(uint64_t sequence, const std::function<void(v1::FrameSet&)>& mutate) {
  v1::FrameSet set = MakeFrameSet(sequence, SensorIds(kSensors));
  mutate(set);
  return SetRequest(set);
}

std::vector<BadMessage> BadMessages() {
  return {
      {"unknown sensor",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) { s.mutable_frames(0)->set_sensor_id("k9"); });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "k9"},
      {"nested sensor id",
       [] {
         return MutatedSet(
             4, [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_sensor_id("k1"); });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "differ"},
      {"nested stamps",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) {
           s.mutable_frames(1)->mutable_color()->set_device_stamp_ns(3);
         });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "differ"},
      {"missing depth",
       [] { return MutatedSet(4, [](v1::FrameSet& s) { s.mutable_frames(0)->clear_depth(); }); },
       grpc::StatusCode::INVALID_ARGUMENT, "no depth"},
      {"unknown encoding",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) {
           s.mutable_frames(0)->mutable_depth()->set_encoding("raw16");
         });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "raw16"},
      {"zero size",
       [] {
         return MutatedSet(
             4, [](v1::FrameSet& s) { s.mutable_frames(0)->mutable_depth()->set_height_px(0); });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "size"},
      {"absurd size",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) {
           s.mutable_frames(0)->mutable_mask()->set_width_px(1 << 24);
         });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "size"},
      {"depth does not decode",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) {
           std::string* d = s.mutable_frames(1)->mutable_depth()->mutable_data();
           (*d)[40] ^= 0x04;
         });
       },
       grpc::StatusCode::INVALID_ARGUMENT, "depth"},
      {"sequence gap", [] { return SetRequest(MakeFrameSet(6, SensorIds(kSensors))); },
       grpc::StatusCode::INVALID_ARGUMENT, "expected 4"},
      {"sequence duplicate", [] { return SetRequest(MakeFrameSet(3, SensorIds(kSensors))); },
       grpc::StatusCode::INVALID_ARGUMENT, "duplicate: expected 4"},
      {"sequence step back", [] { return SetRequest(MakeFrameSet(1, SensorIds(kSensors))); },
       grpc::StatusCode::INVALID_ARGUMENT, "step back: expected 4"},
      {"second OpenTake",
       [] {
         v1::IngestRequest r;
         *r.mutable_open() = MakeOpenTake("take-bad", "daemon-a", kSensors);
         return r;
       },
       grpc::StatusCode::FAILED_PRECONDITION, "twice"},
      {"empty request", [] { return v1::IngestRequest(); }, grpc::StatusCode::INVALID_ARGUMENT,
       "none of"},
      {"CloseTake with a wrong last_sequence",
       [] {
         v1::IngestRequest r;
         r.mutable_close()->set_last_sequence(7);
         return r;
       },
       grpc::StatusCode::INVALID_ARGUMENT, "last FrameSet sent was 3"},
      {"SensorLost of an unknown sensor",
       [] {
         v1::IngestRequest r;
         r.mutable_sensor_lost()->set_sensor_id("k5");
         return r;
       },
       grpc::StatusCode::INVALID_ARGUMENT, "k5"},
      {"oversized message",
       [] {
         return MutatedSet(4, [](v1::FrameSet& s) {
           s.mutable_frames(0)->mutable_color()->set_data(std::string(2 << 20, 'x'));
         });
       },
       grpc::StatusCode::RESOURCE_EXHAUSTED, ""},
  };
}

TEST(Ingest, RefusedMessagesEndTheStreamAndKeepTheDurableSets) {
  auto t = StartServer("ingest_refused");
  ASSERT_NE(t, nullptr);
  for (const BadMessage& bad : BadMessages()) {
    SCOPED_TRACE(bad.name);
    {
      IngestClient client(*t->ingest);
      ASSERT_TRUE(client.Open(MakeOpenTake("take-bad", "daemon-a", kSensors)));
      ASSERT_TRUE(client.ReadOpened().has_value());
      ASSERT_TRUE(client.SendSets(1, 3, kSensors));
      client.Send(bad.make());
      const grpc::Status status = client.Finish();
      EXPECT_EQ(status.error_code(), bad.code) << status.error_message();
      EXPECT_NE(status.error_message().find(bad.message), std::string::npos)
          << status.error_message();
    }
    const v1::Take take = WaitNotRecording(*t, "take-bad");
    EXPECT_EQ(take.state(), v1::TAKE_STATE_INTERRUPTED);
    EXPECT_EQ(take.durable_sequence(), 3u);
    ExpectStoredFrameSets(t->TakePath("take-bad"), SensorIds(kSensors), 3);
    // Resumable: the daemon reconnects, finds 3 sets stored, and closes.
    IngestClient resume(*t->ingest);
    ASSERT_TRUE(resume.Open(MakeOpenTake("take-bad", "daemon-a", kSensors)));
    const auto opened = resume.ReadOpened();
    ASSERT_TRUE(opened.has_value());
    EXPECT_TRUE(opened->resumed());
    EXPECT_EQ(opened->durable_sequence(), 3u);
    ASSERT_TRUE(resume.Close(3));
    EXPECT_TRUE(resume.Finish().ok());
    // Start the next case from a fresh take.
    grpc::ClientContext context;
    v1::DeleteTakeRequest request;
    request.set_take_id("take-bad");
    v1::DeleteTakeResponse response;
    ASSERT_TRUE(t->takes->Delete(&context, request, &response).ok());
  }
}

TEST(Ingest, MessagesBeforeOpenTakeAreRefused) {
  auto t = StartServer("ingest_before_open");
  ASSERT_NE(t, nullptr);
  {
    IngestClient client(*t->ingest);
    client.SendSet(MakeFrameSet(1, SensorIds(1)));
    const grpc::Status status = client.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(status.error_message().find("before OpenTake"), std::string::npos);
  }
  {
    IngestClient client(*t->ingest);
    client.Close(0);
    EXPECT_EQ(client.Finish().error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  }
  for (const std::string& bad_id :
       std::vector<std::string>{"", "a/b", "../x", std::string(65, 'x')}) {
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake(bad_id, "daemon-a", 1));
    const grpc::Status status = client.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad_id;
    EXPECT_NE(status.error_message().find("take_id"), std::string::npos);
  }
  IngestClient no_sensors(*t->ingest);
  no_sensors.Open(MakeOpenTake("t", "daemon-a", 0));
  EXPECT_EQ(no_sensors.Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  // A stream that ends before anything was sent is just over.
  IngestClient empty(*t->ingest);
  EXPECT_TRUE(empty.Finish().ok());
  v1::Take take;
  EXPECT_EQ(t->GetTake("t", &take).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Ingest, CompleteTakeAnswersRepeatedCloseAndRefusesMore) {
  auto t = StartServer("ingest_complete");
  ASSERT_NE(t, nullptr);
  v1::TakeClosed first;
  {
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake("t", "daemon-a", 1));
    client.SendSets(1, 5, 1);
    client.Close(5);
    ASSERT_TRUE(client.Finish().ok());
    first = *client.closed();
  }
  {
    // The TakeClosed was lost: the daemon reconnects and closes again.
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake("t", "daemon-a", 1));
    const auto opened = client.ReadOpened();
    ASSERT_TRUE(opened.has_value());
    EXPECT_TRUE(opened->resumed());
    EXPECT_EQ(opened->durable_sequence(), 5u);
    client.Close(5);
    ASSERT_TRUE(client.Finish().ok());
    ASSERT_TRUE(client.closed().has_value());
    EXPECT_EQ(client.closed()->SerializeAsString(), first.SerializeAsString());
  }
  {
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake("t", "daemon-a", 1));
    client.SendSet(MakeFrameSet(6, SensorIds(1)));
    const grpc::Status status = client.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::ALREADY_EXISTS) << status.error_message();
  }
  {
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake("t", "daemon-a", 1));
    client.Close(9);
    EXPECT_EQ(client.Finish().error_code(), grpc::StatusCode::ALREADY_EXISTS);
  }
  ExpectStoredFrameSets(t->TakePath("t"), SensorIds(1), 5);
}

TEST(Ingest, OtherDaemonAndSecondStreamAreRefused) {
  auto t = StartServer("ingest_owners");
  ASSERT_NE(t, nullptr);
  IngestClient recording(*t->ingest);
  recording.Open(MakeOpenTake("t", "daemon-a", 1));
  ASSERT_TRUE(recording.ReadOpened().has_value());
  recording.SendSets(1, 2, 1);
  ASSERT_TRUE(recording.WaitAck(2));
  {
    IngestClient second(*t->ingest);
    second.Open(MakeOpenTake("t", "daemon-a", 1));
    const grpc::Status status = second.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();
  }
  {
    IngestClient other(*t->ingest);
    other.Open(MakeOpenTake("t", "daemon-b", 1));
    const grpc::Status status = other.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED) << status.error_message();
    EXPECT_NE(status.error_message().find("daemon-a"), std::string::npos);
  }
  // The refusals did not disturb the recording stream.
  recording.SendSets(3, 4, 1);
  recording.Close(4);
  ASSERT_TRUE(recording.Finish().ok());
  ExpectStoredFrameSets(t->TakePath("t"), SensorIds(1), 4);
}

TEST(Ingest, StreamEndingWithoutCloseLeavesTakeResumable) {
  auto t = StartServer("ingest_cut");
  ASSERT_NE(t, nullptr);
  {
    IngestClient client(*t->ingest);
    client.Open(MakeOpenTake("t", "daemon-a", kSensors));
    client.SendSets(1, 6, kSensors);
    ASSERT_TRUE(client.WaitAck(6));
    client.Cancel();  // The network went away.
    EXPECT_EQ(client.Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  v1::Take take = WaitNotRecording(*t, "t");
  EXPECT_EQ(take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(take.durable_sequence(), 6u);
  {
    IngestClient client(*t->ingest);  // Half-closes without CloseTake.
    client.Open(MakeOpenTake("t", "daemon-a", kSensors));
    EXPECT_EQ(client.ReadOpened()->durable_sequence(), 6u);
    client.SendSets(7, 9, kSensors);
    const grpc::Status status = client.Finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();
  }
  take = WaitNotRecording(*t, "t");
  EXPECT_EQ(take.durable_sequence(), 9u);
  IngestClient client(*t->ingest);
  client.Open(MakeOpenTake("t", "daemon-a", kSensors));
  const auto opened = client.ReadOpened();
  ASSERT_TRUE(opened.has_value());
  EXPECT_TRUE(opened->resumed());
  EXPECT_EQ(opened->durable_sequence(), 9u);
  client.SendSets(10, 14, kSensors);
  v1::IngestRequest lost;
  lost.mutable_sensor_lost()->set_sensor_id("k1");
  lost.mutable_sensor_lost()->set_stamp_ns(testing::kStartNs + 14 * testing::kPeriodNs);
  lost.mutable_sensor_lost()->set_reason("end of recording");
  client.Send(lost);
  client.Close(14);
  ASSERT_TRUE(client.Finish().ok());
  EXPECT_EQ(client.closed()->frame_set_count(), 14);
  ExpectStoredFrameSets(t->TakePath("t"), SensorIds(kSensors), 14);
  ASSERT_TRUE(t->GetTake("t", &take).ok());
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  EXPECT_EQ(take.sensors(1).lost_reason(), "end of recording");
}

TEST(Ingest, ShutdownStoresWhatArrivedAndSaysUnavailable) {
  auto t = StartServer("ingest_shutdown");
  ASSERT_NE(t, nullptr);
  IngestClient client(*t->ingest);
  client.Open(MakeOpenTake("t", "daemon-a", 1));
  client.SendSets(1, 8, 1);
  ASSERT_TRUE(client.WaitAck(8));
  t->server->Shutdown();
  const grpc::Status status = client.Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
  EXPECT_EQ(client.acks().back(), 8u);
  const std::string dir = t->data_dir;
  t.reset();
  // The next server finds the take INTERRUPTED (nothing to recover).
  auto again = TestServer::Start(dir);
  ASSERT_NE(again, nullptr);
  EXPECT_TRUE(again->server->recovered().empty());
  v1::Take take;
  ASSERT_TRUE(again->GetTake("t", &take).ok());
  EXPECT_EQ(take.state(), v1::TAKE_STATE_INTERRUPTED);
  EXPECT_EQ(take.durable_sequence(), 8u);
  ExpectStoredFrameSets(again->TakePath("t"), SensorIds(1), 8);
}

TEST(ClientLimits, AClientGetsNoMoreStreamsThanAllowedAndTheNextAfterOneEnds) {
  ServerOptions options;
  options.client_limits.max_streams = 2;
  auto t = TestServer::Start(reenact::testing::MakeTempDir("client_limits"), options);
  ASSERT_NE(t, nullptr);
  auto first = std::make_unique<IngestClient>(*t->ingest);
  first->Open(MakeOpenTake("s1", "daemon-a", 1));
  ASSERT_TRUE(first->ReadOpened().has_value());
  IngestClient second(*t->ingest);
  second.Open(MakeOpenTake("s2", "daemon-a", 1));
  ASSERT_TRUE(second.ReadOpened().has_value());
  // The third stream of the same client is refused, saying which limit.
  IngestClient third(*t->ingest);
  third.Open(MakeOpenTake("s3", "daemon-a", 1));
  const grpc::Status refused = third.Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << refused.error_message();
  EXPECT_NE(refused.error_message().find("--max-streams-per-client"), std::string::npos)
      << refused.error_message();
  // Unary calls are not streams: listing still works.
  v1::Take take;
  EXPECT_TRUE(t->GetTake("s1", &take).ok());
  // One ends; the next stream is let in.
  first->Close(0);
  EXPECT_TRUE(first->Finish().ok());
  first.reset();
  bool admitted = false;
  for (int attempt = 0; attempt < 50 && !admitted; ++attempt) {
    IngestClient fourth(*t->ingest);
    fourth.Open(MakeOpenTake("s4", "daemon-a", 1));
    admitted = fourth.ReadOpened().has_value();
    if (admitted) {
      fourth.Close(0);
      EXPECT_TRUE(fourth.Finish().ok());
    } else {
      (void)fourth.Finish();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  EXPECT_TRUE(admitted);
  second.Close(0);
  EXPECT_TRUE(second.Finish().ok());
}

// The HTTP front calls in process for its web clients, naming each
// (rpc::kForwardedClientKey): every web client counts on its own under the
// caps, and a network caller cannot pose as several clients with that key.
TEST(ClientLimits, TheFrontsCallsCountForEachOfItsClientsAndTheKeyMeansNothingFromTheNetwork) {
  ServerOptions options;
  options.client_limits.max_streams = 1;
  auto t = TestServer::Start(reenact::testing::MakeTempDir("forwarded_clients"), options);
  ASSERT_NE(t, nullptr);
  const auto opened = [](v1::Ingest::Stub& stub, const std::string& take_id) {
    auto client = std::make_unique<IngestClient>(stub);
    client->Open(MakeOpenTake(take_id, "daemon-a", 1));
    const bool ok = client->ReadOpened().has_value();
    return std::make_pair(ok, std::move(client));
  };
  const auto close = [](IngestClient& client) {
    client.Close(0);
    return client.Finish();
  };
  const auto expect_refused = [](IngestClient& client) {
    const grpc::Status refused = client.Finish();
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
        << refused.error_message();
    EXPECT_NE(refused.error_message().find("--max-streams-per-client"), std::string::npos)
        << refused.error_message();
  };

  // In process: web client 10.0.0.1 holds its one stream; its second is
  // refused, while 10.0.0.2 (same token: none) is served.
  auto web_a = v1::Ingest::NewStub(t->server->InProcessChannel("", "10.0.0.1"));
  auto web_a_again = v1::Ingest::NewStub(t->server->InProcessChannel("", "10.0.0.1"));
  auto web_b = v1::Ingest::NewStub(t->server->InProcessChannel("", "10.0.0.2"));
  auto [a_ok, a] = opened(*web_a, "fa");
  ASSERT_TRUE(a_ok);
  auto [a2_ok, a2] = opened(*web_a_again, "fa2");
  EXPECT_FALSE(a2_ok);
  expect_refused(*a2);
  auto [b_ok, b] = opened(*web_b, "fb");
  EXPECT_TRUE(b_ok);

  // From the network the key is ignored: two callers that name two
  // different clients are one client (127.0.0.1), so the second is refused.
  grpc::ClientContext first_context, second_context;
  first_context.AddMetadata(rpc::kForwardedClientKey, "10.0.0.3");
  second_context.AddMetadata(rpc::kForwardedClientKey, "10.0.0.4");
  auto first_stream = t->ingest->Ingest(&first_context);
  v1::IngestRequest open;
  *open.mutable_open() = MakeOpenTake("n1", "daemon-a", 1);
  ASSERT_TRUE(first_stream->Write(open));
  v1::IngestResponse first_answer;
  ASSERT_TRUE(first_stream->Read(&first_answer));
  auto second_stream = t->ingest->Ingest(&second_context);
  *open.mutable_open() = MakeOpenTake("n2", "daemon-a", 1);
  second_stream->Write(open);
  second_stream->WritesDone();
  v1::IngestResponse second_answer;
  while (second_stream->Read(&second_answer)) {
  }
  const grpc::Status second_status = second_stream->Finish();
  EXPECT_EQ(second_status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
      << second_status.error_message();

  // Cleanly closed: the first network stream, then the web ones.
  first_stream->WritesDone();
  while (first_stream->Read(&first_answer)) {
  }
  (void)first_stream->Finish();
  EXPECT_TRUE(close(*a).ok());
  EXPECT_TRUE(close(*b).ok());
}

TEST(Ingest, ASensorLostFloodIsStoredWithinTheQueueBoundAndLongReasonsAreRefused) {
  ServerOptions options;
  options.ingest_queue_limit_bytes = 64 << 10;  // About 64 SensorLost records.
  auto t = TestServer::Start(reenact::testing::MakeTempDir("sensor_lost_flood"), options);
  ASSERT_NE(t, nullptr);
  IngestClient client(*t->ingest);
  client.Open(MakeOpenTake("flood", "daemon-a", 1));
  ASSERT_TRUE(client.SendSets(1, 1, 1));
  constexpr int kLost = 20000;
  for (int i = 0; i < kLost; ++i) {
    v1::IngestRequest request;
    v1::SensorLost* lost = request.mutable_sensor_lost();
    lost->set_sensor_id("k0");
    lost->set_stamp_ns(1000 + i);
    lost->set_reason(std::string(1000, static_cast<char>('a' + i % 26)));
    ASSERT_TRUE(client.Send(request)) << i;
  }
  ASSERT_TRUE(client.SendSets(2, 2, 1));
  client.Close(2);
  ASSERT_TRUE(client.Finish().ok());
  v1::Take take;
  ASSERT_TRUE(t->GetTake("flood", &take).ok());
  EXPECT_EQ(take.state(), v1::TAKE_STATE_COMPLETE);
  auto reader = TakeReader::Open(t->TakePath("flood"));
  ASSERT_TRUE(reader.ok()) << reader.status();
  int stored = 0;
  ASSERT_TRUE((*reader)
                  ->ForEach<v1::SensorLostRecord>(kIngestSensorLostTopic,
                                                  [&](const v1::SensorLostRecord&) {
                                                    ++stored;
                                                    return absl::OkStatus();
                                                  })
                  .ok());
  EXPECT_EQ(stored, kLost);

  // A reason over 1 KiB ends the stream, saying so; the take is kept.
  IngestClient verbose(*t->ingest);
  verbose.Open(MakeOpenTake("verbose", "daemon-a", 1));
  ASSERT_TRUE(verbose.SendSets(1, 1, 1));
  v1::IngestRequest request;
  request.mutable_sensor_lost()->set_sensor_id("k0");
  request.mutable_sensor_lost()->set_reason(std::string(1 << 20, 'x'));
  verbose.Send(request);
  const grpc::Status refused = verbose.Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << refused.error_message();
  EXPECT_NE(refused.error_message().find("at most 1024"), std::string::npos)
      << refused.error_message();
}

}  // namespace
}  // namespace reenact::server
