// Reactors that end a streaming call at once with a status: what a
// callback-API handler returns for a call it refuses before doing anything
// (no token, a role without access).
#pragma once

#include <grpcpp/support/server_callback.h>

namespace reenact::rpc {

// A server-streaming reactor that ends at once with `status`.
template <typename T>
class RefusedWriter final : public grpc::ServerWriteReactor<T> {
 public:
  explicit RefusedWriter(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

// A client-streaming reactor that ends at once with `status`.
template <typename T>
class RefusedReader final : public grpc::ServerReadReactor<T> {
 public:
  explicit RefusedReader(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

// A bidirectional reactor that ends at once with `status`.
template <typename Request, typename Response>
class RefusedBidi final : public grpc::ServerBidiReactor<Request, Response> {
 public:
  explicit RefusedBidi(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

}  // namespace reenact::rpc
