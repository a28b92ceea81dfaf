// Test-only: a Server on 127.0.0.1:0 over a fresh data folder, with stubs,
// and a synchronous client for one Ingest stream.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "common/testing/test_data.h"
#include "reenact/v1/ingest_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/server.h"
#include "server/testing/test_takes.h"

namespace reenact::server::testing {

// A running server and stubs to it.
struct TestServer {
  std::string data_dir;
  std::unique_ptr<Server> server;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::Ingest::Stub> ingest;
  std::unique_ptr<v1::Takes::Stub> takes;

  // Starts a server on `data_dir` (created if missing; kept as it is).
  static std::unique_ptr<TestServer> Start(const std::string& data_dir,
                                           ServerOptions options = {}) {
    auto t = std::make_unique<TestServer>();
    t->data_dir = data_dir;
    options.data_dir = data_dir;
    options.listen_address = "127.0.0.1:0";
    options.store.catalog_update_period_s = 3600;
    auto server = Server::Start(options);
    EXPECT_TRUE(server.ok()) << server.status();
    if (!server.ok()) return nullptr;
    t->server = std::move(*server);
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    args.SetMaxSendMessageSize(-1);
    t->channel =
        grpc::CreateCustomChannel(t->server->address(), grpc::InsecureChannelCredentials(), args);
    t->ingest = v1::Ingest::NewStub(t->channel);
    t->takes = v1::Takes::NewStub(t->channel);
    return t;
  }

  std::string TakePath(const std::string& take_id) const {
    return data_dir + "/takes/" + take_id + ".mcap";
  }

  // Takes.Get, or the status as an error.
  grpc::Status GetTake(const std::string& take_id, v1::Take* take) {
    grpc::ClientContext context;
    v1::GetTakeRequest request;
    request.set_take_id(take_id);
    return takes->Get(&context, request, take);
  }
};

// One Ingest stream driven synchronously.
class IngestClient {
 public:
  explicit IngestClient(v1::Ingest::Stub& stub) : stream_(stub.Ingest(&context_)) {}

  bool Send(const v1::IngestRequest& request) { return stream_->Write(request); }
  bool Open(const v1::OpenTake& open) {
    v1::IngestRequest r;
    *r.mutable_open() = open;
    return Send(r);
  }
  bool SendSet(const v1::FrameSet& set) {
    v1::IngestRequest r;
    *r.mutable_frame_set() = set;
    return Send(r);
  }
  bool SendSets(uint64_t first, uint64_t last, int sensors) {
    for (uint64_t s = first; s <= last; ++s) {
      if (!SendSet(MakeFrameSet(s, SensorIds(sensors)))) return false;
    }
    return true;
  }
  bool Close(uint64_t last_sequence) {
    v1::IngestRequest r;
    r.mutable_close()->set_last_sequence(last_sequence);
    r.mutable_close()->set_reason("stopped");
    return Send(r);
  }
  // The next answer, or nothing at the end of the stream.
  std::optional<v1::IngestResponse> Read() {
    v1::IngestResponse response;
    if (!stream_->Read(&response)) return std::nullopt;
    if (response.has_ack()) acks_.push_back(response.ack().durable_sequence());
    if (response.has_closed()) closed_ = response.closed();
    return response;
  }
  // Reads until TakeOpened (nothing when the stream ends first).
  std::optional<v1::TakeOpened> ReadOpened() {
    while (auto r = Read()) {
      if (r->has_opened()) return r->opened();
    }
    return std::nullopt;
  }
  // Reads until an Ack of at least `sequence`; false when the stream ends.
  bool WaitAck(uint64_t sequence) {
    while (acks_.empty() || acks_.back() < sequence) {
      if (!Read()) return false;
    }
    return true;
  }
  // Half-closes, reads what is left (keeping TakeClosed) and returns the
  // stream's status.
  grpc::Status Finish() {
    stream_->WritesDone();
    while (Read()) {
    }
    return stream_->Finish();
  }
  void Cancel() { context_.TryCancel(); }

  const std::vector<uint64_t>& acks() const { return acks_; }
  const std::optional<v1::TakeClosed>& closed() const { return closed_; }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::IngestRequest, v1::IngestResponse>> stream_;
  std::vector<uint64_t> acks_;
  std::optional<v1::TakeClosed> closed_;
};

}  // namespace reenact::server::testing
