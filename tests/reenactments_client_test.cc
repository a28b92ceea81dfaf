// The client SDK's ReenactmentsClient and the `reenact reenactments ...` /
// `reenact export` commands against the server's Reenactments service over
// loopback: reassembly of the Fetch stream, progress, cancellation, error
// mapping, and the exported .glb.
#include "clients/sdk/reenactments_client.h"

#include <filesystem>
#include <memory>
#include <sstream>
#include <string>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/command.h"
#include "clients/cli/commands.h"

#include "common/io/reenactment_file.h"
#include "common/io/reenactment_test_util.h"
#include "common/testing/test_data.h"
#include "server/rpc/reenactments_service.h"
#include "server/store/reenactment_store.h"

namespace reenact {
namespace {

using testing::MakeTestReenactment;
using testing::TestReenactmentOptions;

struct Fixture {
  std::unique_ptr<server::ReenactmentStore> store;
  server::ServerContext context;
  std::unique_ptr<server::ReenactmentsService> service;
  std::unique_ptr<grpc::Server> grpc_server;
  client::ConnectionOptions connection;

  explicit Fixture(const std::string& name) {
    auto opened = server::ReenactmentStore::Open(testing::MakeTempDir(name));
    EXPECT_TRUE(opened.ok()) << opened.status();
    store = std::move(*opened);
    context.reenactments = store.get();
    service = std::make_unique<server::ReenactmentsService>(context);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(service.get());
    grpc_server = builder.BuildAndStart();
    connection.address = "127.0.0.1:" + std::to_string(port);
  }
  ~Fixture() { grpc_server->Shutdown(); }

  ReenactmentData Add(const TestReenactmentOptions& options) {
    ReenactmentData data = MakeTestReenactment(options);
    EXPECT_TRUE(WriteReenactmentFile(data, store->PathFor(options.id)).ok());
    EXPECT_TRUE(store->Add(options.id).ok());
    return data;
  }
};

TEST(ReenactmentsClient, FetchReassemblesWhatWasStored) {
  Fixture f("rclient_fetch");
  TestReenactmentOptions options;
  options.id = "r-client";
  options.parts = 15;
  options.frames = 1500;
  options.keyframes = 5;
  const ReenactmentData stored = f.Add(options);
  client::ReenactmentsClient client(f.connection);

  int calls = 0;
  double last_fraction = -1;
  bool monotonic = true;
  auto fetched = client.Fetch("r-client", /*skip_keyframes=*/false, [&](const Progress& p) {
    ++calls;
    monotonic = monotonic && p.fraction >= last_fraction;
    last_fraction = p.fraction;
    EXPECT_EQ(p.items_total, 15 + 1500 + 5);
    return true;
  });
  ASSERT_TRUE(fetched.ok()) << fetched.status();
  EXPECT_EQ(fetched->info.SerializeAsString(), stored.info.SerializeAsString());
  ASSERT_EQ(fetched->frames.size(), 1500u);
  EXPECT_EQ(fetched->frames[777].SerializeAsString(), stored.frames[777].SerializeAsString());
  ASSERT_EQ(fetched->keyframes.size(), 5u);
  EXPECT_EQ(fetched->parts[14].SerializeAsString(), stored.parts[14].SerializeAsString());
  EXPECT_GT(calls, 15);
  EXPECT_TRUE(monotonic);
  EXPECT_DOUBLE_EQ(last_fraction, 1.0);

  auto without = client.Fetch("r-client", /*skip_keyframes=*/true);
  ASSERT_TRUE(without.ok()) << without.status();
  EXPECT_TRUE(without->keyframes.empty());
}

TEST(ReenactmentsClient, ListGetDeleteAndErrors) {
  Fixture f("rclient_list");
  TestReenactmentOptions options;
  options.id = "r-one";
  f.Add(options);
  client::ReenactmentsClient client(f.connection);

  auto all = client.List();
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), 1u);
  EXPECT_EQ((*all)[0].info().reenactment_id(), "r-one");
  auto none = client.List("another-take");
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
  auto got = client.Get("r-one");
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->keyframe_count(), 2);

  const auto missing = client.Get("r-missing");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(std::string(missing.status().message()).find(f.connection.address), std::string::npos)
      << missing.status();
  EXPECT_EQ(client.Fetch("r-missing").status().code(), absl::StatusCode::kNotFound);

  // Progress returning false cancels.
  auto cancelled = client.Fetch("r-one", false, [](const Progress&) { return false; });
  EXPECT_EQ(cancelled.status().code(), absl::StatusCode::kCancelled);

  ASSERT_TRUE(client.Delete("r-one").ok());
  EXPECT_EQ(client.Delete("r-one").code(), absl::StatusCode::kNotFound);

  // Nobody listening.
  client::ConnectionOptions nowhere;
  nowhere.address = "127.0.0.1:1";
  nowhere.timeout_s = 2;
  EXPECT_EQ(client::ReenactmentsClient(nowhere).List().status().code(),
            absl::StatusCode::kUnavailable);
}

struct CliRun {
  int code = -1;
  std::string out, err;
};

CliRun Cli(const std::vector<std::string>& argv) {
  std::ostringstream out, err;
  CliRun r;
  r.code = cli::Dispatch(argv, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

TEST(ReenactCli, ListsShowsAndExports) {
  Fixture f("rcli");
  TestReenactmentOptions options;
  options.id = "r-cli";
  options.frames = 8;
  const ReenactmentData stored = f.Add(options);
  const std::string server = f.connection.address;

  const CliRun list = Cli({"reenactments", "list", "--server", server, "--json"});
  ASSERT_EQ(list.code, 0) << list.err;
  const nlohmann::json listed = nlohmann::json::parse(list.out);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0]["reenactment_id"], "r-cli");
  EXPECT_EQ(listed[0]["frame_count"], 8);
  EXPECT_EQ(listed[0]["keyframe_count"], 2);
  const CliRun filtered = Cli({"reenactments", "list", "--server", server, "--take", "nope"});
  ASSERT_EQ(filtered.code, 0) << filtered.err;
  EXPECT_NE(filtered.out.find("(no reenactments)"), std::string::npos);

  const CliRun show = Cli({"reenactments", "show", "r-cli", "--server", server});
  ASSERT_EQ(show.code, 0) << show.err;
  EXPECT_NE(show.out.find(stored.info.take_id()), std::string::npos) << show.out;
  EXPECT_EQ(Cli({"reenactments", "show", "--reenactment", "r-nope", "--server", server}).code,
            cli::kExitFailure);

  const std::string dir = testing::MakeTempDir("rcli_out");
  const CliRun remote = Cli({"export", "--server", server, "--reenactment", "r-cli", "--format",
                             "glb", "--out", dir + "/remote.glb", "--quiet", "--json"});
  ASSERT_EQ(remote.code, 0) << remote.err;
  const nlohmann::json summary = nlohmann::json::parse(remote.out);
  EXPECT_EQ(summary["nodes"], 4);
  EXPECT_EQ(summary["animation_channels"], 9);
  EXPECT_EQ(summary["bytes"].get<int64_t>(),
            static_cast<int64_t>(std::filesystem::file_size(dir + "/remote.glb")));

  // The same reenactment from its file exports to the same bytes.
  const CliRun local = Cli({"export", "--in", f.store->PathFor("r-cli"), "--format", "glb", "--out",
                            dir + "/local.glb"});
  ASSERT_EQ(local.code, 0) << local.err;
  EXPECT_EQ(std::filesystem::file_size(dir + "/local.glb"),
            std::filesystem::file_size(dir + "/remote.glb"));

  // Usage errors.
  EXPECT_EQ(Cli({"export", "--in", "x.reen", "--format", "obj", "--out", "y"}).code,
            cli::kExitUsage);
  EXPECT_EQ(Cli({"export", "--out", "y"}).code, cli::kExitUsage);
  EXPECT_EQ(Cli({"export", "--in", "x.reen", "--reenactment", "r", "--out", "y"}).code,
            cli::kExitUsage);
  EXPECT_EQ(Cli({"export", "--in", dir + "/missing.reen", "--out", dir + "/m.glb"}).code,
            cli::kExitFailure);

  const CliRun deleted = Cli({"reenactments", "delete", "r-cli", "--server", server});
  ASSERT_EQ(deleted.code, 0) << deleted.err;
  EXPECT_TRUE(f.store->List().empty());
}

}  // namespace
}  // namespace reenact
