#include "server/recon/methods.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

#include <gtest/gtest.h>

#include "common/io/jpeg.h"
#include "common/io/reenactment_file.h"
#include "server/recon/body_parts.h"
#include "server/recon/testing/short_take.h"

namespace reenact::recon {
namespace {

using recon::testing::GetSharedTake;

MethodInput CylindersInput() {
  MethodInput input;
  input.take_path = GetSharedTake().path;
  input.method = "rigid-cylinders";
  input.reenactment_id = "r-test";
  input.take_id = "t-test";
  input.job_id = "j-test";
  input.options = {{"texture_size_px", "128"}, {"threads", "2"}};
  return input;
}

TEST(RunMethod, RigidCylindersWritesAValidReenactment) {
  RECON_REQUIRE_SHARED_TAKE();
  const std::string out = reenact::testing::MakeTempDir("recon_run") + "/r.reen";
  std::vector<Progress> progress;
  std::vector<std::string> log;
  auto result = RunMethod(
      CylindersInput(), out,
      [&](const Progress& p) {
        progress.push_back(p);
        return true;
      },
      [&](const std::string& line) { log.push_back(line); });
  ASSERT_TRUE(result.ok()) << result.status();
  const int instants = GetSharedTake().summary.frames;
  EXPECT_EQ(result->frames, instants);
  EXPECT_GT(result->keyframes, instants);  // Two sensors, (nearly) every instant.
  EXPECT_EQ(result->file_bytes, static_cast<int64_t>(std::filesystem::file_size(out)));

  auto data = ReadReenactmentFile(out);
  ASSERT_TRUE(data.ok()) << data.status();
  const v1::ReenactmentInfo& info = data->info;
  EXPECT_EQ(info.reenactment_id(), "r-test");
  EXPECT_EQ(info.take_id(), "t-test");
  EXPECT_EQ(info.job_id(), "j-test");
  EXPECT_EQ(info.method(), "rigid-cylinders");
  EXPECT_EQ(info.texture_mode(), v1::TEXTURE_MODE_POSE_CLOSEST);
  EXPECT_EQ(info.options().at("texture_size_px"), "128");
  EXPECT_EQ(info.frame_count(), instants);
  EXPECT_NEAR(info.fps(), 15.0, 1e-9);
  ASSERT_EQ(info.part_names_size(), kNumBodyParts);
  EXPECT_EQ(info.part_names(4), "forearm_left");
  EXPECT_EQ(info.sensors_size(), 2);
  for (const char* figure : {"representative_frame", "seconds", "frames_per_second",
                             "radius_mm.forearm_left", "keyframes"}) {
    EXPECT_TRUE(info.figures().contains(figure)) << figure;
  }
  ASSERT_EQ(data->parts.size(), static_cast<size_t>(kNumBodyParts));
  for (int p = 0; p < kNumBodyParts; ++p) {
    EXPECT_EQ(data->parts[p].part(), p);
    EXPECT_GT(data->parts[p].radius_rate(), 0.0f);
    EXPECT_GT(data->parts[p].reference_length_m(), 0.0f);
    EXPECT_FALSE(data->parts[p].baked_texture_jpeg().empty()) << p;
    EXPECT_FALSE(data->parts[p].uvs_f32().empty()) << p;
  }
  ASSERT_EQ(data->frames.size(), static_cast<size_t>(instants));
  for (int i = 0; i < instants; ++i) {
    const v1::PartFrame& frame = data->frames[i];
    EXPECT_EQ(frame.frame_index(), i);
    ASSERT_EQ(frame.parts_size(), kNumBodyParts);
    EXPECT_EQ(frame.joints_in_world_m_size(), 25);
    for (const v1::PartPose& pose : frame.parts()) {
      EXPECT_TRUE(pose.valid());
      // The bone length over the reference length: near 1 on a rigid body.
      EXPECT_NEAR(pose.scale(), 1.0, 0.25);
    }
  }
  EXPECT_EQ(data->keyframes.size(), static_cast<size_t>(result->keyframes));
  // For a look by eye: RECON_TEST_DUMP_DIR=/some/dir writes the baked textures.
  if (const char* dump = std::getenv("RECON_TEST_DUMP_DIR"); dump != nullptr) {
    auto write_ppm = [&](const std::string& name, const std::string& jpeg) {
      auto image = DecodeJpeg(jpeg);
      if (!image.ok()) return;
      std::ofstream out(std::string(dump) + "/" + name + ".ppm", std::ios::binary);
      out << "P6\n" << image->width << " " << image->height << "\n255\n";
      out.write(reinterpret_cast<const char*>(image->data.data()),
                static_cast<std::streamsize>(image->data.size()));
    };
    for (const v1::PartMesh& part : data->parts) write_ppm(part.name(), part.baked_texture_jpeg());
    if (!data->keyframes.empty()) write_ppm("keyframe0", data->keyframes[0].color_jpeg());
  }
  std::printf(
      "[ figures  ] rigid-cylinders: %d instants, %d keyframes, %.0f kB, %.2f s "
      "(%.1f frames/s), representative frame %.0f\n",
      result->frames, result->keyframes, result->file_bytes / 1024.0, info.figures().at("seconds"),
      info.figures().at("frames_per_second"), info.figures().at("representative_frame"));

  // Progress: the stages in order, fractions never going back.
  std::vector<std::string> stages;
  double last = 0;
  for (const Progress& p : progress) {
    if (stages.empty() || stages.back() != p.stage) stages.push_back(p.stage);
    EXPECT_GE(p.fraction, last - 1e-12) << p.stage;
    last = p.fraction;
  }
  EXPECT_EQ(stages, (std::vector<std::string>{"load", "shape", "pose", "texture", "write"}));
  EXPECT_DOUBLE_EQ(progress.back().fraction, 1.0);
  EXPECT_GE(log.size(), 3u);
}

TEST(RunMethod, RejectsUnknownMethodsAndOptions) {
  RECON_REQUIRE_SHARED_TAKE();
  const std::string dir = reenact::testing::MakeTempDir("recon_bad_options");
  MethodInput input = CylindersInput();
  input.options["colour_of_the_sky"] = "blue";
  auto result = RunMethod(input, dir + "/r.reen");
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(result.status().message().find("colour_of_the_sky"), std::string::npos);
  input = CylindersInput();
  input.options["lambda"] = "much";
  EXPECT_EQ(RunMethod(input, dir + "/r.reen").status().code(), absl::StatusCode::kInvalidArgument);
  input = CylindersInput();
  input.options["threads"] = "-3";
  EXPECT_EQ(RunMethod(input, dir + "/r.reen").status().code(), absl::StatusCode::kInvalidArgument);
  input = CylindersInput();
  input.method = "rigid-spheres";
  EXPECT_EQ(RunMethod(input, dir + "/r.reen").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(std::filesystem::exists(dir + "/r.reen"));
}

// The dispatch to carving/rigid_carved.cc (its own tests measure it).
TEST(RunMethod, RigidCarvedWritesAValidReenactment) {
  RECON_REQUIRE_SHARED_TAKE();
  const std::string out = reenact::testing::MakeTempDir("recon_run_carved") + "/r.reen";
  MethodInput input = CylindersInput();
  input.method = "rigid-carved";
  input.options = {{"threads", "2"}};  // Carved meshes need the default 512 px textures.
  auto result = RunMethod(input, out);
  ASSERT_TRUE(result.ok()) << result.status();
  auto data = ReadReenactmentFile(out, /*skip_keyframes=*/true);
  ASSERT_TRUE(data.ok()) << data.status();
  EXPECT_EQ(data->info.method(), "rigid-carved");
  EXPECT_EQ(data->info.texture_mode(), v1::TEXTURE_MODE_ROTATION_CLOSEST);
  EXPECT_EQ(data->parts.size(), static_cast<size_t>(kNumBodyParts));
  EXPECT_EQ(data->frames.size(), static_cast<size_t>(GetSharedTake().summary.frames));
  EXPECT_TRUE(data->info.figures().contains("seconds"));
}

TEST(RunMethod, BadTakesAreErrorsAndLeaveNoFile) {
  const std::string dir = reenact::testing::MakeTempDir("recon_bad_take");
  MethodInput input = CylindersInput();
  input.take_path = dir + "/missing.mcap";
  EXPECT_EQ(RunMethod(input, dir + "/r.reen").status().code(), absl::StatusCode::kNotFound);
  { std::ofstream(dir + "/corrupt.mcap") << "\x89MCAP0\r\n garbage garbage garbage"; }
  input.take_path = dir + "/corrupt.mcap";
  auto corrupt = RunMethod(input, dir + "/r.reen");
  EXPECT_TRUE(absl::IsInvalidArgument(corrupt.status()) || absl::IsDataLoss(corrupt.status()))
      << corrupt.status();
  EXPECT_FALSE(std::filesystem::exists(dir + "/r.reen"));
}

TEST(RunMethod, CancelledThroughProgress) {
  RECON_REQUIRE_SHARED_TAKE();
  const std::string dir = reenact::testing::MakeTempDir("recon_cancel");
  auto result = RunMethod(CylindersInput(), dir + "/r.reen",
                          [](const Progress& p) { return p.stage != "texture"; });
  EXPECT_EQ(result.status().code(), absl::StatusCode::kCancelled);
  EXPECT_FALSE(std::filesystem::exists(dir + "/r.reen"));
}

}  // namespace
}  // namespace reenact::recon
