#include "server/rpc/reenactments_service.h"

#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"
#include "server/store/reenactment_store.h"

namespace reenact::server {
namespace {

using reenact::testing::MakeTestReenactment;
using reenact::testing::TestReenactmentOptions;

// gRPC's default limit on received messages; Fetch must stay well below it.
constexpr size_t kDefaultMaxMessageBytes = 4 << 20;

// The Reenactments service alone on 127.0.0.1:0 over a fresh store.
struct ServiceFixture {
  std::unique_ptr<ReenactmentStore> store;
  ServerContext context;
  std::unique_ptr<ReenactmentsService> service;
  std::unique_ptr<grpc::Server> server;
  std::unique_ptr<v1::Reenactments::Stub> stub;

  explicit ServiceFixture(const std::string& name, bool with_store = true) {
    auto opened = ReenactmentStore::Open(reenact::testing::MakeTempDir(name));
    EXPECT_TRUE(opened.ok()) << opened.status();
    store = std::move(*opened);
    if (with_store) context.reenactments = store.get();
    service = std::make_unique<ReenactmentsService>(context);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(service.get());
    server = builder.BuildAndStart();
    EXPECT_GT(port, 0);
    // Default channel limits: every message must fit the stock 4 MiB.
    stub = v1::Reenactments::NewStub(grpc::CreateChannel("127.0.0.1:" + std::to_string(port),
                                                         grpc::InsecureChannelCredentials()));
  }
  ~ServiceFixture() { server->Shutdown(); }

  ReenactmentData AddReenactment(const TestReenactmentOptions& options) {
    return Store(MakeTestReenactment(options));
  }

  // Writes `data` into the store and adds it.
  ReenactmentData Store(ReenactmentData data) {
    const std::string& id = data.info.reenactment_id();
    EXPECT_TRUE(WriteReenactmentFile(data, store->PathFor(id)).ok());
    EXPECT_TRUE(store->Add(id).ok());
    return data;
  }

  // The Get RPC.
  grpc::Status Get(const std::string& id, v1::ReenactmentSummary* summary) {
    grpc::ClientContext context;
    v1::GetReenactmentRequest request;
    request.set_reenactment_id(id);
    return stub->Get(&context, request, summary);
  }
};

// What one Fetch delivered, in arrival order.
struct Fetched {
  std::vector<v1::FetchReenactmentChunk::ChunkCase> kinds;
  ReenactmentData data;
  size_t largest_message_bytes = 0;
  int frame_batches = 0;
  grpc::Status status;
};

Fetched Fetch(ServiceFixture& f, const std::string& id, bool skip_keyframes) {
  grpc::ClientContext context;
  v1::FetchReenactmentRequest request;
  request.set_reenactment_id(id);
  request.set_skip_keyframes(skip_keyframes);
  auto reader = f.stub->Fetch(&context, request);
  Fetched out;
  v1::FetchReenactmentChunk chunk;
  while (reader->Read(&chunk)) {
    out.largest_message_bytes = std::max(out.largest_message_bytes, chunk.ByteSizeLong());
    out.kinds.push_back(chunk.chunk_case());
    switch (chunk.chunk_case()) {
      case v1::FetchReenactmentChunk::kInfo:
        out.data.info = chunk.info();
        break;
      case v1::FetchReenactmentChunk::kPartMesh:
        out.data.parts.push_back(chunk.part_mesh());
        break;
      case v1::FetchReenactmentChunk::kFrames:
        ++out.frame_batches;
        for (const auto& frame : chunk.frames().frames()) out.data.frames.push_back(frame);
        break;
      case v1::FetchReenactmentChunk::kKeyframe:
        out.data.keyframes.push_back(chunk.keyframe());
        break;
      case v1::FetchReenactmentChunk::kBodyMesh:
        out.data.body.push_back(chunk.body_mesh());
        break;
      case v1::FetchReenactmentChunk::kAppearanceMp4Piece:
        if (out.data.body.empty()) {
          ADD_FAILURE() << "a piece of an appearance video before the body mesh";
          break;
        }
        out.data.body.back().mutable_appearance()->mutable_mp4()->append(
            chunk.appearance_mp4_piece());
        break;
      default:
        ADD_FAILURE() << "empty chunk";
    }
  }
  out.status = reader->Finish();
  return out;
}

TEST(Reenactments, ListGetAndDeleteOverTheWire) {
  ServiceFixture f("rsvc_list");
  TestReenactmentOptions a;
  a.id = "r-a";
  f.AddReenactment(a);
  TestReenactmentOptions b;
  b.id = "r-b";
  ReenactmentData data_b = MakeTestReenactment(b);
  data_b.info.set_take_id("other-take");
  data_b.info.set_created_unix_ns(data_b.info.created_unix_ns() + 1);
  ASSERT_TRUE(WriteReenactmentFile(data_b, f.store->PathFor("r-b")).ok());
  ASSERT_TRUE(f.store->Add("r-b").ok());

  grpc::ClientContext list_context;
  v1::ListReenactmentsResponse listed;
  ASSERT_TRUE(f.stub->List(&list_context, {}, &listed).ok());
  ASSERT_EQ(listed.reenactments_size(), 2);
  EXPECT_EQ(listed.reenactments(0).info().reenactment_id(), "r-b");
  grpc::ClientContext filter_context;
  v1::ListReenactmentsRequest filter;
  filter.set_take_id("other-take");
  ASSERT_TRUE(f.stub->List(&filter_context, filter, &listed).ok());
  ASSERT_EQ(listed.reenactments_size(), 1);

  v1::ReenactmentSummary summary;
  ASSERT_TRUE(f.Get("r-a", &summary).ok());
  EXPECT_EQ(summary.part_count(), 3);
  EXPECT_EQ(summary.keyframe_count(), 2);
  EXPECT_EQ(summary.info().frame_count(), 5);
  EXPECT_EQ(f.Get("r-zzz", &summary).error_code(), grpc::StatusCode::NOT_FOUND);

  v1::DeleteReenactmentRequest del;
  del.set_reenactment_id("r-a");
  v1::DeleteReenactmentResponse deleted;
  grpc::ClientContext delete_context;
  ASSERT_TRUE(f.stub->Delete(&delete_context, del, &deleted).ok());
  EXPECT_FALSE(std::filesystem::exists(f.store->PathFor("r-a")));
  grpc::ClientContext again_context;
  EXPECT_EQ(f.stub->Delete(&again_context, del, &deleted).error_code(),
            grpc::StatusCode::NOT_FOUND);
}

TEST(Reenactments, FetchStreamsEverythingInOrderInSmallMessages) {
  ServiceFixture f("rsvc_fetch");
  TestReenactmentOptions options;
  options.id = "r-long";
  options.parts = 15;
  options.frames = 3000;  // About 4 MB of frames: several batches.
  options.keyframes = 12;
  options.texture_px = 256;
  const ReenactmentData written = f.AddReenactment(options);

  const Fetched got = Fetch(f, "r-long", /*skip_keyframes=*/false);
  ASSERT_TRUE(got.status.ok()) << got.status.error_message();
  ASSERT_TRUE(ValidateReenactment(got.data).ok());
  EXPECT_EQ(got.data.info.SerializeAsString(), written.info.SerializeAsString());
  ASSERT_EQ(got.data.frames.size(), 3000u);
  EXPECT_EQ(got.data.frames[1234].SerializeAsString(), written.frames[1234].SerializeAsString());
  ASSERT_EQ(got.data.keyframes.size(), 12u);
  EXPECT_EQ(got.data.keyframes[11].SerializeAsString(), written.keyframes[11].SerializeAsString());
  size_t frame_bytes = 0;
  for (const auto& frame : written.frames) frame_bytes += frame.ByteSizeLong();
  EXPECT_GT(frame_bytes, size_t{3} << 20);
  EXPECT_GE(got.frame_batches, static_cast<int>(frame_bytes / kFetchFrameBatchBytes) + 1);
  EXPECT_LT(got.largest_message_bytes, kDefaultMaxMessageBytes / 2);
  // Order: info, the parts, frame batches, keyframes one per message.
  ASSERT_EQ(got.kinds.size(), 1u + 15u + got.frame_batches + 12u);
  EXPECT_EQ(got.kinds[0], v1::FetchReenactmentChunk::kInfo);
  for (int i = 1; i <= 15; ++i) EXPECT_EQ(got.kinds[i], v1::FetchReenactmentChunk::kPartMesh);
  EXPECT_EQ(got.kinds.back(), v1::FetchReenactmentChunk::kKeyframe);
  EXPECT_TRUE(std::is_sorted(got.kinds.begin(), got.kinds.end()));

  const Fetched skipped = Fetch(f, "r-long", /*skip_keyframes=*/true);
  ASSERT_TRUE(skipped.status.ok());
  EXPECT_TRUE(skipped.data.keyframes.empty());
  EXPECT_EQ(skipped.data.frames.size(), 3000u);

  EXPECT_EQ(Fetch(f, "r-unknown", false).status.error_code(), grpc::StatusCode::NOT_FOUND);
}

// A body-model reenactment streams as info, its body mesh, then the frame
// batches, and arrives equal to the file.
TEST(Reenactments, FetchOfABodyReenactmentStreamsTheBodyMeshAfterTheInfo) {
  ServiceFixture f("rsvc_body");
  const ReenactmentData written = f.Store(reenact::testing::MakeTestBodyReenactment(300, "r-body"));
  v1::ReenactmentSummary summary;
  ASSERT_TRUE(f.Get("r-body", &summary).ok());
  EXPECT_EQ(summary.part_count(), 0);
  EXPECT_EQ(summary.info().frame_count(), 300);

  const Fetched got = Fetch(f, "r-body", /*skip_keyframes=*/false);
  ASSERT_TRUE(got.status.ok()) << got.status.error_message();
  ASSERT_TRUE(ValidateReenactment(got.data).ok());
  ASSERT_GE(got.kinds.size(), 3u);
  EXPECT_EQ(got.kinds[0], v1::FetchReenactmentChunk::kInfo);
  EXPECT_EQ(got.kinds[1], v1::FetchReenactmentChunk::kBodyMesh);
  for (size_t i = 2; i < got.kinds.size(); ++i) {
    EXPECT_EQ(got.kinds[i], v1::FetchReenactmentChunk::kFrames) << i;
  }
  EXPECT_EQ(static_cast<int>(got.kinds.size()), 2 + got.frame_batches);
  EXPECT_EQ(got.data.info.SerializeAsString(), written.info.SerializeAsString());
  ASSERT_EQ(got.data.body.size(), 1u);
  EXPECT_EQ(got.data.body[0].SerializeAsString(), written.body[0].SerializeAsString());
  ASSERT_EQ(got.data.frames.size(), 300u);
  for (int frame : {0, 1, 299}) {  // Frame 1 carries vertex offsets.
    EXPECT_EQ(got.data.frames[frame].SerializeAsString(),
              written.frames[frame].SerializeAsString());
  }
  EXPECT_LT(got.largest_message_bytes, kDefaultMaxMessageBytes / 2);
}

// A body's appearance video larger than any message may be streams after
// the body mesh in pieces of at most 1 MiB, and arrives whole.
TEST(Reenactments, FetchStreamsALargeAppearanceVideoInPiecesAfterTheBodyMesh) {
  ServiceFixture f("rsvc_appearance");
  ReenactmentData data = reenact::testing::MakeTestBodyReenactment(30, "r-video");
  v1::AppearanceVideo& video = *data.body[0].mutable_appearance();
  std::string bytes(6 * (size_t{1} << 20) + 12345, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 2654435761u) >> 13);
  video.set_mp4(bytes);
  video.set_size_px(512);
  video.set_frame_count(30);
  video.set_codec("libx264");
  const ReenactmentData written = f.Store(data);

  const Fetched got = Fetch(f, "r-video", /*skip_keyframes=*/true);
  ASSERT_TRUE(got.status.ok()) << got.status.error_message();
  ASSERT_GE(got.kinds.size(), 9u);
  EXPECT_EQ(got.kinds[1], v1::FetchReenactmentChunk::kBodyMesh);
  for (size_t i = 2; i < 9; ++i) {
    EXPECT_EQ(got.kinds[i], v1::FetchReenactmentChunk::kAppearanceMp4Piece) << i;
  }
  EXPECT_EQ(got.kinds[9], v1::FetchReenactmentChunk::kFrames);
  ASSERT_EQ(got.data.body.size(), 1u);
  EXPECT_EQ(got.data.body[0].appearance().mp4().size(), bytes.size());
  EXPECT_TRUE(got.data.body[0].appearance().mp4() == bytes);
  EXPECT_EQ(got.data.body[0].SerializeAsString(), written.body[0].SerializeAsString());
  EXPECT_LT(got.largest_message_bytes, kDefaultMaxMessageBytes / 2);
}

TEST(Reenactments, FetchOfADamagedFileFailsWithDataLoss) {
  ServiceFixture f("rsvc_damaged");
  TestReenactmentOptions options;
  options.id = "r-x";
  f.AddReenactment(options);
  // Damaged after it was indexed: the stream ends with the file's error.
  std::filesystem::resize_file(f.store->PathFor("r-x"), 200);
  const Fetched got = Fetch(f, "r-x", false);
  EXPECT_FALSE(got.status.ok());
  EXPECT_TRUE(got.kinds.empty());
}

TEST(Reenactments, ClientCancellingAFetchEndsIt) {
  ServiceFixture f("rsvc_cancel");
  TestReenactmentOptions options;
  options.id = "r-big";
  options.frames = 200;
  options.keyframes = 60;
  options.texture_px = 384;
  options.noisy_keyframes = true;  // ~20 MB of keyframes: more than the read-ahead queue.
  f.AddReenactment(options);
  for (int round = 0; round < 3; ++round) {
    grpc::ClientContext context;
    v1::FetchReenactmentRequest request;
    request.set_reenactment_id("r-big");
    auto reader = f.stub->Fetch(&context, request);
    v1::FetchReenactmentChunk chunk;
    for (int i = 0; i < 2 + round * 5; ++i) ASSERT_TRUE(reader->Read(&chunk));
    context.TryCancel();
    while (reader->Read(&chunk)) {
    }
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  // The service still answers.
  EXPECT_TRUE(Fetch(f, "r-big", true).status.ok());
}

TEST(Reenactments, WithoutAStoreEverythingIsUnavailable) {
  ServiceFixture f("rsvc_nostore", /*with_store=*/false);
  grpc::ClientContext context;
  v1::ListReenactmentsResponse listed;
  EXPECT_EQ(f.stub->List(&context, {}, &listed).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(Fetch(f, "r-a", false).status.error_code(), grpc::StatusCode::UNAVAILABLE);
}

}  // namespace
}  // namespace reenact::server
