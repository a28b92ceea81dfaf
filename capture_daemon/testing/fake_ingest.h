// Test-only: an Ingest service (proto/reenact/v1/ingest_service.proto) kept in
// memory, served in-process on 127.0.0.1:<free port>. It checks the protocol
// as the real server does (sequence must be durable + 1, daemon id must match
// on resume), acknowledges every `ack_every` sets, and can be told to kill
// the stream with UNAVAILABLE after a given number of sets, or to refuse
// OpenTake with a given status.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "reenact/v1/ingest_service.grpc.pb.h"

namespace reenact::capture::testing {

// What the fake holds of one take.
struct FakeTake {
  v1::OpenTake open;
  std::vector<v1::FrameSet> sets;  // In arrival order.
  std::vector<v1::SensorLost> lost;
  bool closed = false;
  int streams = 0;  // Ingest streams that opened this take.
};

class FakeIngestService final : public v1::Ingest::Service {
 public:
  grpc::Status Ingest(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::IngestResponse, v1::IngestRequest>* stream) override {
    v1::IngestRequest request;
    std::string take_id;
    uint64_t since_ack = 0;
    while (stream->Read(&request)) {
      std::unique_lock<std::mutex> lock(mutex_);
      v1::IngestResponse response;
      if (request.has_open()) {
        if (refuse_open_.error_code() != grpc::StatusCode::OK) return refuse_open_;
        take_id = request.open().take_id();
        FakeTake& take = takes_[take_id];
        if (take.streams > 0 && take.open.daemon_id() != request.open().daemon_id()) {
          return grpc::Status(grpc::StatusCode::PERMISSION_DENIED, "another daemon's take");
        }
        if (take.streams == 0) take.open = request.open();
        ++take.streams;
        response.mutable_opened()->set_take_id(take_id);
        response.mutable_opened()->set_durable_sequence(take.sets.size());
        response.mutable_opened()->set_resumed(take.streams > 1);
      } else if (take_id.empty()) {
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "OpenTake first");
      } else if (request.has_frame_set()) {
        FakeTake& take = takes_[take_id];
        if (request.frame_set().sequence() != take.sets.size() + 1) {
          return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "sequence out of order");
        }
        take.sets.push_back(request.frame_set());
        ++total_sets_;
        if (kill_after_sets_ > 0 && total_sets_ == kill_after_sets_) {
          // Forget the sets not yet acknowledged (those since the last Ack
          // and this one): they were never durable.
          take.sets.resize(take.sets.size() - since_ack - 1);
          return grpc::Status(grpc::StatusCode::UNAVAILABLE, "stream killed by the test");
        }
        if (++since_ack < ack_every_) continue;
        since_ack = 0;
        response.mutable_ack()->set_durable_sequence(take.sets.size());
      } else if (request.has_sensor_lost()) {
        takes_[take_id].lost.push_back(request.sensor_lost());
        continue;
      } else if (request.has_close()) {
        FakeTake& take = takes_[take_id];
        take.closed = true;
        response.mutable_closed()->set_take_id(take_id);
        response.mutable_closed()->set_durable_sequence(take.sets.size());
        response.mutable_closed()->set_frame_set_count(static_cast<int64_t>(take.sets.size()));
        lock.unlock();
        stream->Write(response);
        return grpc::Status::OK;
      }
      lock.unlock();
      if (!stream->Write(response)) return grpc::Status::OK;
    }
    // The client went away: whatever it sent is kept (as durable).
    return grpc::Status::OK;
  }

  void set_kill_after_sets(uint64_t n) {
    std::lock_guard<std::mutex> lock(mutex_);
    kill_after_sets_ = n;
  }
  void set_ack_every(uint64_t n) {
    std::lock_guard<std::mutex> lock(mutex_);
    ack_every_ = n;
  }
  void set_refuse_open(grpc::Status status) {
    std::lock_guard<std::mutex> lock(mutex_);
    refuse_open_ = std::move(status);
  }
  // FrameSets received over every stream, resends included.
  uint64_t sets_received() {
    std::lock_guard<std::mutex> lock(mutex_);
    return total_sets_;
  }
  std::map<std::string, FakeTake> takes() {
    std::lock_guard<std::mutex> lock(mutex_);
    return takes_;
  }

 private:
  std::mutex mutex_;
  std::map<std::string, FakeTake> takes_;
  uint64_t total_sets_ = 0;
  uint64_t kill_after_sets_ = 0;
  uint64_t ack_every_ = 4;
  grpc::Status refuse_open_ = grpc::Status::OK;
};

// The fake served on 127.0.0.1 at a port the system picks (or `port`).
class FakeIngestServer {
 public:
  explicit FakeIngestServer(int port = 0) {
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials(),
                             &port_);
    builder.SetMaxReceiveMessageSize(64 << 20);
    builder.RegisterService(&service_);
    server_ = builder.BuildAndStart();
  }
  ~FakeIngestServer() { Shutdown(); }
  void Shutdown() {
    if (server_)
      server_->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
    server_.reset();
  }
  bool ok() const { return server_ != nullptr && port_ != 0; }
  int port() const { return port_; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  FakeIngestService& service() { return service_; }

 private:
  FakeIngestService service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
};

}  // namespace reenact::capture::testing
