// The client SDK's ReenactmentsClient and the `reenact reenactments ...` /
// `reenact export` commands against the server's Reenactments service over
// loopback: reassembly of the Fetch stream, progress, cancellation, error
// mapping, and the exported .glb.
#include "clients/sdk/reenactments_client.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "common/body/motion.h"
#include "common/io/body_reenactment.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"
#include "server/rpc/reenactments_service.h"
#include "server/store/reenactment_store.h"
#include "tests/testing/reenactments_server.h"

namespace reenact {
namespace {

using testing::MakeTestReenactment;
using testing::TestReenactmentOptions;

struct Fixture : testing::ReenactmentsTestServer {
  client::ConnectionOptions connection;

  explicit Fixture(const std::string& name) : ReenactmentsTestServer(name) {
    connection.address = address;
  }

  ReenactmentData Add(const TestReenactmentOptions& options) {
    return Store(MakeTestReenactment(options));
  }

  ReenactmentData AddBody(int frames, const std::string& id) {
    return Store(testing::MakeTestBodyReenactment(frames, id));
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
  // What arrived, written back as messages, is what was stored (read the
  // same way).
  const ReenactmentData got = ReenactmentToProto(*fetched);
  const ReenactmentData want = ReenactmentToProto(testing::ToPlain(stored));
  EXPECT_EQ(got.info.SerializeAsString(), want.info.SerializeAsString());
  ASSERT_EQ(got.frames.size(), 1500u);
  EXPECT_EQ(got.frames[777].SerializeAsString(), want.frames[777].SerializeAsString());
  ASSERT_EQ(got.keyframes.size(), 5u);
  EXPECT_EQ(got.parts[14].SerializeAsString(), stored.parts[14].SerializeAsString());
  EXPECT_GT(calls, 15);
  EXPECT_TRUE(monotonic);
  EXPECT_DOUBLE_EQ(last_fraction, 1.0);

  auto without = client.Fetch("r-client", /*skip_keyframes=*/true);
  ASSERT_TRUE(without.ok()) << without.status();
  EXPECT_TRUE(without->keyframes.empty());
}

TEST(ReenactmentsClient, FetchOfABodyReenactmentEqualsTheFile) {
  Fixture f("rclient_body");
  const ReenactmentData stored = f.AddBody(40, "r-body");
  f.Add(TestReenactmentOptions{.id = "r-rigid"});
  client::ReenactmentsClient client(f.connection);

  auto summary = client.Get("r-body");
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->part_count(), 0);
  EXPECT_EQ(summary->keyframe_count(), 0);
  EXPECT_EQ(summary->info().method(), "body");
  int64_t last_items = 0;
  auto fetched = client.Fetch("r-body", /*skip_keyframes=*/false, [&](const Progress& p) {
    EXPECT_EQ(p.items_total, 40);
    last_items = p.items_done;
    return true;
  });
  ASSERT_TRUE(fetched.ok()) << fetched.status();
  EXPECT_EQ(last_items, 40);
  ASSERT_TRUE(fetched->is_body());
  const ReenactmentData got = ReenactmentToProto(*fetched);
  const ReenactmentData want = ReenactmentToProto(testing::ToPlain(stored));
  EXPECT_EQ(got.info.SerializeAsString(), want.info.SerializeAsString());
  EXPECT_EQ(got.body[0].SerializeAsString(), stored.body[0].SerializeAsString());
  ASSERT_EQ(got.frames.size(), stored.frames.size());
  for (size_t f = 0; f < stored.frames.size(); ++f) {
    EXPECT_EQ(got.frames[f].SerializeAsString(), want.frames[f].SerializeAsString()) << f;
  }
  EXPECT_TRUE(fetched->parts.empty());
  EXPECT_TRUE(fetched->keyframes.empty());

  auto mesh = client.FetchBodyMesh("r-body");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->SerializeAsString(), stored.body[0].SerializeAsString());
  EXPECT_EQ(client.FetchBodyMesh("r-rigid").status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(client.FetchBodyMesh("r-missing").status().code(), absl::StatusCode::kNotFound);
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

// `reenact export --server SERVER --reenactment ID --format FORMAT --out
// PATH --quiet --json`: its JSON summary (empty when it failed).
nlohmann::json ExportJson(const std::string& server, const std::string& id,
                          const std::string& format, const std::string& path) {
  const CliRun run = Cli({"export", "--server", server, "--reenactment", id, "--format", format,
                          "--out", path, "--quiet", "--json"});
  EXPECT_EQ(run.code, 0) << run.err;
  return run.code == 0 ? nlohmann::json::parse(run.out) : nlohmann::json::object();
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
  const nlohmann::json summary = ExportJson(server, "r-cli", "glb", dir + "/remote.glb");
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

  // BVH is the skeleton of a body model; a rigid reenactment has none.
  const CliRun rigid_bvh = Cli({"export", "--server", server, "--reenactment", "r-cli", "--format",
                                "bvh", "--out", dir + "/rigid.bvh", "--quiet"});
  EXPECT_EQ(rigid_bvh.code, cli::kExitUsage);
  EXPECT_NE(rigid_bvh.err.find("--format bvh needs a body-model reenactment"), std::string::npos)
      << rigid_bvh.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/rigid.bvh"));

  const CliRun deleted = Cli({"reenactments", "delete", "r-cli", "--server", server});
  ASSERT_EQ(deleted.code, 0) << deleted.err;
  EXPECT_TRUE(f.store->List().empty());
}

TEST(ReenactCli, ShowsAndExportsABodyReenactment) {
  Fixture f("rcli_body");
  const ReenactmentData stored = f.AddBody(6, "r-body-cli");
  const std::string server = f.connection.address;
  const int vertices = testing::TestBodyModel().num_vertices();

  const CliRun show = Cli({"reenactments", "show", "r-body-cli", "--server", server});
  ASSERT_EQ(show.code, 0) << show.err;
  EXPECT_NE(show.out.find("body model  procedural"), std::string::npos) << show.out;
  EXPECT_NE(show.out.find("=0.500"), std::string::npos) << show.out;
  EXPECT_NE(show.out.find("=-0.500"), std::string::npos) << show.out;
  EXPECT_NE(show.out.find(absl::StrCat("mesh        ", vertices, " vertices, ",
                                       stored.body[0].triangle_indices_size() / 3, " triangles")),
            std::string::npos)
      << show.out;
  EXPECT_NE(show.out.find("atlas       64 x 64 JPEG"), std::string::npos) << show.out;
  EXPECT_NE(show.out.find("appearance  the static atlas alone"), std::string::npos) << show.out;
  EXPECT_EQ(show.out.find("parts "), std::string::npos) << show.out;
  {
    // With an appearance video over several Fetch messages: show says so,
    // and Fetch and FetchBodyMesh put it back together.
    ReenactmentData with_video = testing::MakeTestBodyReenactment(6, "r-body-video");
    v1::AppearanceVideo& video = *with_video.body[0].mutable_appearance();
    std::string bytes((size_t{5} << 19) + 7, '\0');
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 131 >> 5);
    video.set_mp4(bytes);
    video.set_size_px(512);
    video.set_frame_count(6);
    video.set_codec("libx264");
    f.Store(with_video);
    const CliRun shown = Cli({"reenactments", "show", "r-body-video", "--server", server});
    ASSERT_EQ(shown.code, 0) << shown.err;
    EXPECT_NE(shown.out.find("appearance  6 frames of 512 x 512, libx264 video (2.5 MiB)"),
              std::string::npos)
        << shown.out;
    const client::ReenactmentsClient client(f.connection);
    auto mesh = client.FetchBodyMesh("r-body-video");
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    EXPECT_TRUE(mesh->appearance().mp4() == bytes);
    auto fetched = client.Fetch("r-body-video", /*skip_keyframes=*/true);
    ASSERT_TRUE(fetched.ok()) << fetched.status();
    EXPECT_TRUE(fetched->body->appearance_mp4 == bytes);
    EXPECT_EQ(fetched->body->appearance_frame_count, 6);
    // `export --format appearance` writes the video as stored; without one
    // it says why and writes nothing.
    const std::string out_dir = testing::MakeTempDir("rcli_appearance_out");
    const CliRun exported = Cli({"export", "--server", server, "--reenactment", "r-body-video",
                                 "--format", "appearance", "--out", out_dir + "/a.mp4", "--quiet"});
    ASSERT_EQ(exported.code, 0) << exported.err;
    EXPECT_NE(exported.out.find("6 frames of 512x512"), std::string::npos) << exported.out;
    std::ifstream in(out_dir + "/a.mp4", std::ios::binary);
    const std::string written((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
    EXPECT_TRUE(written == bytes) << written.size() << " bytes";
    const CliRun none = Cli({"export", "--server", server, "--reenactment", "r-body-cli",
                             "--format", "appearance", "--out", out_dir + "/none.mp4", "--quiet"});
    EXPECT_EQ(none.code, cli::kExitFailure) << none.err;
    EXPECT_NE(none.err.find("has no appearance video"), std::string::npos) << none.err;
    EXPECT_FALSE(std::filesystem::exists(out_dir + "/none.mp4"));
  }
  const CliRun json = Cli({"reenactments", "show", "r-body-cli", "--server", server, "--json"});
  ASSERT_EQ(json.code, 0) << json.err;
  const nlohmann::json shown = nlohmann::json::parse(json.out);
  EXPECT_EQ(shown["body"]["model_name"], "procedural");
  EXPECT_EQ(shown["body"]["vertices"].get<int>(), vertices);
  EXPECT_EQ(shown["body"]["atlas_width"].get<int>(), 64);
  EXPECT_EQ(shown["body"]["shape"].size(), static_cast<size_t>(stored.body[0].shape_size()));

  const std::string dir = testing::MakeTempDir("rcli_body_out");
  const nlohmann::json glb_summary = ExportJson(server, "r-body-cli", "glb", dir + "/body.glb");
  EXPECT_EQ(glb_summary["joints"], 25);
  EXPECT_EQ(glb_summary["meshes"], 1);
  EXPECT_EQ(glb_summary["frames_offsets_left_out"], 1);
  EXPECT_EQ(glb_summary["animation_channels"], 26);

  const nlohmann::json bvh_summary = ExportJson(server, "r-body-cli", "bvh", dir + "/body.bvh");
  EXPECT_EQ(bvh_summary["joints"], 25);
  EXPECT_EQ(bvh_summary["frames"], 6);
  EXPECT_EQ(bvh_summary["units"], "m");
  // The file reads back as the posed joints (0.1 mm), in metres by default.
  body::BvhOptions options;
  options.metres_per_unit = 1.0;
  auto motion = body::ReadBvh(dir + "/body.bvh", options);
  ASSERT_TRUE(motion.ok()) << motion.status();
  auto mesh = DecodeBodyMesh(stored.body[0]);
  ASSERT_TRUE(mesh.ok());
  for (int frame = 0; frame < 6; ++frame) {
    auto posed = PoseBodyMesh(*mesh, stored.frames[frame].body());
    ASSERT_TRUE(posed.ok());
    const auto world = motion->WorldFromJoints(frame);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      const Eigen::Vector3d read = world[motion->canonical_to_source()[j]].translation();
      EXPECT_LT((read - posed->joints_m[j]).norm(), 0.1e-3) << "frame " << frame << " joint " << j;
    }
  }
  // The same from the file, in words.
  const CliRun local = Cli({"export", "--in", f.store->PathFor("r-body-cli"), "--format", "bvh",
                            "--out", dir + "/local.bvh"});
  ASSERT_EQ(local.code, 0) << local.err;
  EXPECT_NE(local.out.find("25 Kinect v2 joints, 6 frames"), std::string::npos) << local.out;
  EXPECT_EQ(std::filesystem::file_size(dir + "/local.bvh"),
            std::filesystem::file_size(dir + "/body.bvh"));
  // --units cm: the same joints read as centimetres; a unit it does not know
  // is a usage error.
  const CliRun cm = Cli({"export", "--in", f.store->PathFor("r-body-cli"), "--format", "bvh",
                         "--units", "cm", "--out", dir + "/cm.bvh"});
  ASSERT_EQ(cm.code, 0) << cm.err;
  EXPECT_NE(cm.out.find("centimetres"), std::string::npos) << cm.out;
  options.metres_per_unit = 0.01;
  auto in_cm = body::ReadBvh(dir + "/cm.bvh", options);
  ASSERT_TRUE(in_cm.ok()) << in_cm.status();
  const auto world_m = motion->WorldFromJoints(3);
  const auto world_cm = in_cm->WorldFromJoints(3);
  for (size_t j = 0; j < world_m.size(); ++j) {
    EXPECT_LT((world_m[j].translation() - world_cm[j].translation()).norm(), 0.1e-3) << j;
  }
  const CliRun inches = Cli({"export", "--in", f.store->PathFor("r-body-cli"), "--format", "bvh",
                             "--units", "in", "--out", dir + "/in.bvh"});
  EXPECT_EQ(inches.code, cli::kExitUsage);
  EXPECT_NE(inches.err.find("--units in is not supported"), std::string::npos) << inches.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/in.bvh"));
}

}  // namespace
}  // namespace reenact
