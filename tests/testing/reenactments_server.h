// Test-only: the server's Reenactments service on a loopback port over a
// reenactment store in a temporary folder, for the client SDK's tests.
#pragma once

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "common/io/reenactment_file.h"
#include "common/testing/test_data.h"
#include "server/rpc/reenactments_service.h"
#include "server/store/reenactment_store.h"

namespace reenact::testing {

struct ReenactmentsTestServer {
  std::unique_ptr<server::ReenactmentStore> store;
  server::ServerContext context;
  std::unique_ptr<server::ReenactmentsService> service;
  std::unique_ptr<grpc::Server> grpc_server;
  std::string address;  // 127.0.0.1:PORT

  explicit ReenactmentsTestServer(const std::string& name) {
    auto opened = server::ReenactmentStore::Open(MakeTempDir(name));
    EXPECT_TRUE(opened.ok()) << opened.status();
    store = std::move(*opened);
    context.reenactments = store.get();
    service = std::make_unique<server::ReenactmentsService>(context);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(service.get());
    grpc_server = builder.BuildAndStart();
    address = "127.0.0.1:" + std::to_string(port);
  }
  ~ReenactmentsTestServer() { grpc_server->Shutdown(); }

  // Writes `data` into the store and indexes it.
  ReenactmentData Store(ReenactmentData data) {
    const std::string& id = data.info.reenactment_id();
    EXPECT_TRUE(WriteReenactmentFile(data, store->PathFor(id)).ok());
    EXPECT_TRUE(store->Add(id).ok());
    return data;
  }
};

}  // namespace reenact::testing
