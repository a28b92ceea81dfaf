#include "server/rpc/takes_service.h"

#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "server/testing/test_server.h"
#include "server/testing/test_takes.h"

namespace reenact::server {
namespace {

namespace fs = std::filesystem;
using testing::IngestClient;
using testing::MakeOpenTake;
using testing::TestServer;

// Records a complete take of `sets` frame sets.
void RecordTake(TestServer& t, const std::string& id, uint64_t sets) {
  IngestClient client(*t.ingest);
  client.Open(MakeOpenTake(id, "daemon-a", 1));
  client.SendSets(1, sets, 1);
  client.Close(sets);
  ASSERT_TRUE(client.Finish().ok()) << id;
}

grpc::Status List(TestServer& t, v1::TakeState state, v1::ListTakesResponse* response) {
  grpc::ClientContext context;
  v1::ListTakesRequest request;
  request.set_state(state);
  return t.takes->List(&context, request, response);
}

grpc::Status Delete(TestServer& t, const std::string& id, v1::DeleteTakeResponse* response) {
  grpc::ClientContext context;
  v1::DeleteTakeRequest request;
  request.set_take_id(id);
  return t.takes->Delete(&context, request, response);
}

grpc::Status Download(TestServer& t, const std::string& id, int32_t chunk_bytes, std::string* bytes,
                      int* chunks) {
  grpc::ClientContext context;
  v1::DownloadTakeRequest request;
  request.set_take_id(id);
  request.set_chunk_bytes(chunk_bytes);
  auto reader = t.takes->Download(&context, request);
  v1::TakeFileChunk chunk;
  *chunks = 0;
  bytes->clear();
  while (reader->Read(&chunk)) {
    EXPECT_EQ(chunk.offset(), static_cast<int64_t>(bytes->size()));
    EXPECT_GT(chunk.total_bytes(), 0);
    *bytes += chunk.data();
    ++*chunks;
  }
  return reader->Finish();
}

TEST(Takes, ListsNewestFirstAndFilters) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_list"));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "first", 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  RecordTake(*t, "second", 4);
  IngestClient recording(*t->ingest);
  recording.Open(MakeOpenTake("third", "daemon-a", 1));
  recording.SendSets(1, 2, 1);
  ASSERT_TRUE(recording.WaitAck(2));

  v1::ListTakesResponse all;
  ASSERT_TRUE(List(*t, v1::TAKE_STATE_UNSPECIFIED, &all).ok());
  ASSERT_EQ(all.takes_size(), 3);
  EXPECT_EQ(all.takes(0).take_id(), "third");
  EXPECT_EQ(all.takes(1).take_id(), "second");
  EXPECT_EQ(all.takes(2).take_id(), "first");
  EXPECT_EQ(all.takes(0).state(), v1::TAKE_STATE_RECORDING);
  EXPECT_EQ(all.takes(0).durable_sequence(), 2u);  // Live, not the last catalog write.
  EXPECT_EQ(all.takes(1).frame_set_count(), 4);
  EXPECT_EQ(all.takes(1).sensors(0).frame_count(), 4);
  EXPECT_EQ(all.takes(1).generator(), "server test");
  EXPECT_DOUBLE_EQ(all.takes(1).fps(), 30.0);
  v1::ListTakesResponse complete;
  ASSERT_TRUE(List(*t, v1::TAKE_STATE_COMPLETE, &complete).ok());
  ASSERT_EQ(complete.takes_size(), 2);
  EXPECT_EQ(complete.takes(0).take_id(), "second");
  v1::ListTakesResponse recording_only;
  ASSERT_TRUE(List(*t, v1::TAKE_STATE_RECORDING, &recording_only).ok());
  ASSERT_EQ(recording_only.takes_size(), 1);
  v1::ListTakesResponse bad;
  EXPECT_EQ(List(*t, static_cast<v1::TakeState>(42), &bad).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  recording.Close(2);
  ASSERT_TRUE(recording.Finish().ok());
}

TEST(Takes, ListPagesThroughEveryTakeOnceWhileTakesComeAndGo) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_pages"));
  ASSERT_NE(t, nullptr);
  for (int i = 0; i < 7; ++i) RecordTake(*t, "take" + std::to_string(i), 1);
  auto page = [&](int32_t size, const std::string& token, v1::ListTakesResponse* response) {
    grpc::ClientContext context;
    v1::ListTakesRequest request;
    request.set_page_size(size);
    request.set_page_token(token);
    return t->takes->List(&context, request, response);
  };
  std::vector<std::string> seen;
  std::string token;
  int pages = 0;
  do {
    v1::ListTakesResponse response;
    ASSERT_TRUE(page(3, token, &response).ok());
    EXPECT_LE(response.takes_size(), 3);
    for (const v1::Take& take : response.takes()) seen.push_back(take.take_id());
    token = response.next_page_token();
    if (++pages == 1) {
      // A take deleted and one added between pages: neither shifts the
      // pages still to come (keyset, not offset).
      v1::DeleteTakeResponse deleted;
      ASSERT_TRUE(Delete(*t, seen.front(), &deleted).ok());
      RecordTake(*t, "newer", 1);
    }
  } while (!token.empty());
  EXPECT_EQ(pages, 3);
  EXPECT_EQ(seen, (std::vector<std::string>{"take6", "take5", "take4", "take3", "take2", "take1",
                                            "take0"}));
  v1::ListTakesResponse response;
  EXPECT_EQ(page(-1, "", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(page(3, "not-a-token", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  // Zero asks for the default page; a huge size is taken as the maximum.
  ASSERT_TRUE(page(0, "", &response).ok());
  EXPECT_EQ(response.takes_size(), 7);
  EXPECT_TRUE(response.next_page_token().empty());
}

TEST(Takes, GetNamesUnknownAndMalformedIds) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_get"));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "known", 2);
  v1::Take take;
  ASSERT_TRUE(t->GetTake("known", &take).ok());
  EXPECT_EQ(take.take_id(), "known");
  EXPECT_EQ(take.name(), "test-known");
  EXPECT_EQ(take.durable_sequence(), 2u);
  EXPECT_GT(take.created_unix_ns(), 0);
  EXPECT_GE(take.updated_unix_ns(), take.created_unix_ns());
  EXPECT_EQ(take.size_bytes(), static_cast<int64_t>(fs::file_size(t->TakePath("known"))));
  EXPECT_EQ(t->GetTake("unknown", &take).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(t->GetTake("../known", &take).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

TEST(Takes, DeleteRefusesRecordingTakesAndFreesFiles) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_delete"));
  ASSERT_NE(t, nullptr);
  IngestClient recording(*t->ingest);
  recording.Open(MakeOpenTake("t", "daemon-a", 1));
  recording.SendSets(1, 3, 1);
  ASSERT_TRUE(recording.WaitAck(3));
  v1::DeleteTakeResponse response;
  EXPECT_EQ(Delete(*t, "t", &response).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  std::string bytes;
  int chunks = 0;
  EXPECT_EQ(Download(*t, "t", 0, &bytes, &chunks).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
  recording.Close(3);
  ASSERT_TRUE(recording.Finish().ok());
  const auto size = static_cast<int64_t>(fs::file_size(t->TakePath("t")));
  ASSERT_TRUE(Delete(*t, "t", &response).ok());
  EXPECT_EQ(response.freed_bytes(), size);
  EXPECT_FALSE(fs::exists(t->TakePath("t")));
  v1::Take take;
  EXPECT_EQ(t->GetTake("t", &take).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(Delete(*t, "t", &response).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(Delete(*t, "", &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

TEST(Takes, DownloadGivesTheFileByteForByte) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_download"));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "t", 40);
  const std::string file = *ReadFileToString(t->TakePath("t"));
  ASSERT_GT(file.size(), 50'000u);
  for (const int32_t chunk_bytes : {0, 4096, 1 << 24}) {
    std::string bytes;
    int chunks = 0;
    ASSERT_TRUE(Download(*t, "t", chunk_bytes, &bytes, &chunks).ok()) << chunk_bytes;
    EXPECT_EQ(bytes, file) << chunk_bytes;
    const int64_t per_chunk = chunk_bytes == 0 ? kDefaultDownloadChunkBytes : chunk_bytes;
    EXPECT_EQ(chunks, static_cast<int>((file.size() + per_chunk - 1) / per_chunk));
  }
  std::string bytes;
  int chunks = 0;
  EXPECT_EQ(Download(*t, "t", -1, &bytes, &chunks).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Download(*t, "t", (1 << 24) + 1, &bytes, &chunks).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Download(*t, "nope", 0, &bytes, &chunks).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Takes, InProcessChannelServesTheSameServices) {
  auto t = TestServer::Start(reenact::testing::MakeTempDir("takes_inprocess"));
  ASSERT_NE(t, nullptr);
  RecordTake(*t, "t", 2);
  auto stub = v1::Takes::NewStub(t->server->InProcessChannel());
  grpc::ClientContext context;
  v1::ListTakesResponse response;
  ASSERT_TRUE(stub->List(&context, v1::ListTakesRequest(), &response).ok());
  ASSERT_EQ(response.takes_size(), 1);
  EXPECT_EQ(response.takes(0).take_id(), "t");
}

}  // namespace
}  // namespace reenact::server
