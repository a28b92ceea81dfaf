#include "common/io/reenactment_file.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/io/mcap_reader.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

using testing::MakeTestReenactment;

void ExpectSameMessages(const ReenactmentData& a, const ReenactmentData& b, bool keyframes) {
  EXPECT_EQ(a.info.SerializeAsString(), b.info.SerializeAsString());
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t i = 0; i < a.parts.size(); ++i) {
    EXPECT_EQ(a.parts[i].SerializeAsString(), b.parts[i].SerializeAsString()) << "part " << i;
  }
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t i = 0; i < a.frames.size(); ++i) {
    EXPECT_EQ(a.frames[i].SerializeAsString(), b.frames[i].SerializeAsString()) << "frame " << i;
  }
  if (!keyframes) return;
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  for (size_t i = 0; i < a.keyframes.size(); ++i) {
    EXPECT_EQ(a.keyframes[i].SerializeAsString(), b.keyframes[i].SerializeAsString());
  }
}

TEST(PackFloats, RoundTripsLittleEndian) {
  const std::vector<float> values = {1.0f, -2.5f, 0.0f, 3.25e-7f};
  const std::string packed = PackFloats(values);
  ASSERT_EQ(packed.size(), 16u);
  // 1.0f is 0x3F800000: little-endian bytes 00 00 80 3F.
  EXPECT_EQ(packed.substr(0, 4), std::string("\x00\x00\x80\x3F", 4));
  auto unpacked = UnpackFloats(packed);
  ASSERT_TRUE(unpacked.ok()) << unpacked.status();
  EXPECT_EQ(*unpacked, values);
  EXPECT_EQ(UnpackFloats("abc").status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(ReenactmentFile, RoundTripsEveryMessage) {
  const std::string path = testing::MakeTempDir("reen_roundtrip") + "/r.reen";
  testing::TestReenactmentOptions options;
  options.frames = 40;
  options.keyframes = 6;
  const ReenactmentData data = MakeTestReenactment(options);
  ASSERT_TRUE(WriteReenactmentFile(data, path).ok());
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));

  auto read = ReadReenactmentFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameMessages(data, *read, /*keyframes=*/true);

  auto skipped = ReadReenactmentFile(path, /*skip_keyframes=*/true);
  ASSERT_TRUE(skipped.ok()) << skipped.status();
  EXPECT_TRUE(skipped->keyframes.empty());
  ExpectSameMessages(data, *skipped, /*keyframes=*/false);

  // Any MCAP reader sees the four channels.
  auto mcap = McapReader::Open(path);
  ASSERT_TRUE(mcap.ok());
  EXPECT_EQ((*mcap)->channels().size(), 4u);
  EXPECT_NE((*mcap)->FindChannel(kReenactmentKeyframeTopic), nullptr);
  EXPECT_EQ((*mcap)->statistics().message_count, 1u + 3u + 40u + 6u);
}

TEST(ReenactmentFile, MissingFileIsNotFound) {
  auto read = ReadReenactmentFile("/nonexistent/dir/r.reen");
  EXPECT_EQ(read.status().code(), absl::StatusCode::kNotFound);
}

TEST(ReenactmentFile, TruncatedFileFails) {
  const std::string dir = testing::MakeTempDir("reen_truncated");
  const std::string path = dir + "/r.reen";
  ASSERT_TRUE(WriteReenactmentFile(MakeTestReenactment(), path).ok());
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  for (const double fraction : {0.0, 0.01, 0.3, 0.7, 0.99}) {
    const std::string cut = dir + "/cut.reen";
    ASSERT_TRUE(
        WriteFileAtomically(cut, bytes->substr(0, static_cast<size_t>(fraction * bytes->size())))
            .ok());
    auto read = ReadReenactmentFile(cut);
    EXPECT_FALSE(read.ok()) << "cut at " << fraction;
    EXPECT_TRUE(read.status().code() == absl::StatusCode::kDataLoss ||
                read.status().code() == absl::StatusCode::kInvalidArgument)
        << read.status();
  }
}

TEST(ReenactmentFile, CorruptedFileFails) {
  const std::string dir = testing::MakeTempDir("reen_corrupt");
  const std::string path = dir + "/r.reen";
  ASSERT_TRUE(WriteReenactmentFile(MakeTestReenactment(), path).ok());
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  // Flip bytes in the middle of the first chunk: its CRC or its compression
  // breaks.
  auto mcap = McapReader::Open(path);
  ASSERT_TRUE(mcap.ok());
  ASSERT_FALSE((*mcap)->chunks().empty());
  const McapChunkInfo& chunk = (*mcap)->chunks().front();
  std::string damaged = *bytes;
  const size_t middle = chunk.chunk_offset + chunk.chunk_length / 2;
  for (size_t i = middle; i < middle + 16; ++i) damaged[i] ^= 0x5A;
  ASSERT_TRUE(WriteFileAtomically(dir + "/bad.reen", damaged).ok());
  auto read = ReadReenactmentFile(dir + "/bad.reen");
  EXPECT_FALSE(read.ok());
  // Not an MCAP file at all.
  ASSERT_TRUE(WriteFileAtomically(dir + "/text.reen", "hello, this is not a reenactment").ok());
  EXPECT_EQ(ReadReenactmentFile(dir + "/text.reen").status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ReenactmentFile, InvalidDataIsRejectedOnWriteAndNothingIsLeft) {
  const std::string dir = testing::MakeTempDir("reen_invalid");
  const std::string path = dir + "/r.reen";
  const ReenactmentData good = MakeTestReenactment();
  ASSERT_TRUE(ValidateReenactment(good).ok());

  std::vector<std::pair<std::string, ReenactmentData>> cases;
  auto add = [&](const std::string& name, auto mutate) {
    ReenactmentData d = good;
    mutate(d);
    cases.emplace_back(name, std::move(d));
  };
  add("normals size", [](ReenactmentData& d) {
    d.parts[0].mutable_normals_in_part_f32()->resize(d.parts[0].normals_in_part_f32().size() - 12);
  });
  add("uvs not a multiple", [](ReenactmentData& d) { d.parts[1].mutable_uvs_f32()->append("x"); });
  add("index out of range", [](ReenactmentData& d) { d.parts[2].set_triangle_indices(5, 24); });
  add("index count", [](ReenactmentData& d) { d.parts[2].add_triangle_indices(0); });
  add("NaN position", [](ReenactmentData& d) {
    std::vector<float> p = *UnpackFloats(d.parts[0].positions_in_part_m_f32());
    p[7] = std::numeric_limits<float>::quiet_NaN();
    d.parts[0].set_positions_in_part_m_f32(PackFloats(p));
  });
  add("NaN pose", [](ReenactmentData& d) {
    d.frames[2].mutable_parts(0)->mutable_world_from_part()->mutable_translation_m()->set_y(NAN);
  });
  add("infinite joint",
      [](ReenactmentData& d) { d.frames[1].mutable_joints_in_world_m(3)->set_x(INFINITY); });
  add("missing pose", [](ReenactmentData& d) { d.frames[3].mutable_parts()->RemoveLast(); });
  add("frame count", [](ReenactmentData& d) { d.info.set_frame_count(4); });
  add("frame index", [](ReenactmentData& d) { d.frames[2].set_frame_index(7); });
  add("missing mesh", [](ReenactmentData& d) { d.parts.pop_back(); });
  add("mesh name", [](ReenactmentData& d) { d.parts[1].set_name("elbow"); });
  add("zero quaternion", [](ReenactmentData& d) {
    d.frames[0].mutable_parts(0)->mutable_world_from_part()->mutable_rotation()->set_w(0);
  });
  add("keyframe frame", [](ReenactmentData& d) { d.keyframes[0].set_frame_index(5); });
  add("keyframe sensor", [](ReenactmentData& d) { d.keyframes[1].set_sensor_id("k9"); });
  add("visibility bits",
      [](ReenactmentData& d) { d.keyframes[0].mutable_vertex_visible_bits(1)->push_back('\0'); });
  for (const auto& [name, data] : cases) {
    const absl::Status validated = ValidateReenactment(data);
    EXPECT_EQ(validated.code(), absl::StatusCode::kInvalidArgument) << name;
    EXPECT_EQ(WriteReenactmentFile(data, path).code(), absl::StatusCode::kInvalidArgument) << name;
    EXPECT_FALSE(std::filesystem::exists(path)) << name;
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp")) << name;
  }
}

TEST(ReenactmentFile, FailedWriteKeepsTheOldFile) {
  const std::string dir = testing::MakeTempDir("reen_keep");
  const std::string path = dir + "/r.reen";
  ASSERT_TRUE(WriteReenactmentFile(MakeTestReenactment(), path).ok());
  ReenactmentData bad = MakeTestReenactment();
  bad.info.set_frame_count(99);
  EXPECT_FALSE(WriteReenactmentFile(bad, path).ok());
  EXPECT_TRUE(ReadReenactmentFile(path).ok());
  // A folder that does not exist: an error, not a crash.
  EXPECT_FALSE(WriteReenactmentFile(MakeTestReenactment(), dir + "/no/such/r.reen").ok());
}

}  // namespace
}  // namespace reenact
