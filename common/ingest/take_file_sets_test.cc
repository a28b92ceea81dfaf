#include "common/ingest/take_file_sets.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact::ingest {
namespace {

constexpr int64_t kPeriodNs = 33'333'333;

// Payload bytes that identify (sensor, frame, stream).
std::string Payload(const std::string& sensor, int64_t frame, const std::string& stream,
                    size_t bytes = 64) {
  std::string data = sensor + "/" + std::to_string(frame) + "/" + stream + "/";
  while (data.size() < bytes) data.push_back(static_cast<char>('a' + data.size() % 26));
  return data;
}

struct TakeSpec {
  int frames = 5;
  size_t depth_bytes = 64;
  bool records = false;       // Write /ingest/frame_set records.
  bool sensor_major = false;  // All of k0's frames, then all of k1's.
};

// Two sensors; k1's frames 4 ms after k0's; colour on every frame, a mask
// on even frames of k0, two skeletons on k1's frame 2; ground truth joints
// per instant; a stray colour image of k0 with no depth (frame 99).
std::string WriteTake(const std::string& path, const TakeSpec& spec) {
  v1::TakeInfo info;
  info.set_name("upload-test");
  info.set_fps(30);
  auto writer = TakeWriter::Open(path, info);
  EXPECT_TRUE(writer.ok()) << writer.status();
  for (const char* id : {"k0", "k1"}) {
    v1::SensorCalibration calibration;
    calibration.set_sensor_id(id);
    EXPECT_TRUE((*writer)->AddSensor(calibration).ok());
  }
  auto write_frame = [&](const std::string& sensor, int64_t i) {
    const int64_t stamp = 1'000'000'000 + i * kPeriodNs + (sensor == "k1" ? 4'000'000 : 0);
    v1::DepthImage depth;
    depth.set_sensor_id(sensor);
    depth.set_host_stamp_ns(stamp);
    depth.set_device_stamp_ns(stamp / 2);
    depth.set_frame_index(i);
    depth.set_data(Payload(sensor, i, "depth", spec.depth_bytes));
    v1::ColorImage color;
    color.set_sensor_id(sensor);
    color.set_host_stamp_ns(stamp);
    color.set_frame_index(i);
    color.set_data(Payload(sensor, i, "color"));
    // Colour first for k1: the order within a frame does not matter.
    if (sensor == "k1") {
      EXPECT_TRUE((*writer)->WriteColor(color).ok());
    }
    EXPECT_TRUE((*writer)->WriteDepth(depth).ok());
    if (sensor == "k0") {
      EXPECT_TRUE((*writer)->WriteColor(color).ok());
    }
    if (sensor == "k0" && i % 2 == 0) {
      v1::ActorMask mask;
      mask.set_sensor_id(sensor);
      mask.set_host_stamp_ns(stamp);
      mask.set_frame_index(i);
      mask.set_data(Payload(sensor, i, "mask"));
      EXPECT_TRUE((*writer)->WriteMask(mask).ok());
    }
    if (sensor == "k1" && i == 2) {
      for (int body = 0; body < 2; ++body) {
        v1::Skeleton skeleton;
        skeleton.set_sensor_id(sensor);
        skeleton.set_host_stamp_ns(stamp);
        skeleton.set_frame_index(i);
        skeleton.set_body_index(body);
        EXPECT_TRUE((*writer)->WriteSkeleton(skeleton).ok());
      }
    }
  };
  if (spec.sensor_major) {
    for (const char* sensor : {"k0", "k1"}) {
      for (int i = 0; i < spec.frames; ++i) write_frame(sensor, i);
    }
  } else {
    for (int i = 0; i < spec.frames; ++i) {
      for (const char* sensor : {"k0", "k1"}) write_frame(sensor, i);
      v1::GroundTruthJoints joints;
      joints.set_stamp_ns(1'000'000'000 + i * kPeriodNs);
      EXPECT_TRUE((*writer)->WriteGroundTruthJoints(joints).ok());
      if (spec.records) {
        // Frame 3 of k1 went missing from its set.
        v1::FrameSetRecord record;
        record.set_sequence(static_cast<uint64_t>(i + 1));
        record.set_stamp_ns(1'000'000'000 + i * kPeriodNs + 2'000'000);
        record.add_sensor_ids("k0");
        record.add_frame_indices(i);
        if (i != 3) {
          record.add_sensor_ids("k1");
          record.add_frame_indices(i);
        } else {
          record.add_missing_sensor_ids("k1");
        }
        EXPECT_TRUE((*writer)->WriteFrameSetRecord(record).ok());
      }
    }
  }
  v1::ColorImage stray;
  stray.set_sensor_id("k0");
  stray.set_host_stamp_ns(5'000'000'000);
  stray.set_frame_index(99);
  stray.set_data("stray");
  EXPECT_TRUE((*writer)->WriteColor(stray).ok());
  EXPECT_TRUE((*writer)->Close().ok());
  return path;
}

std::vector<v1::FrameSet> ReadSets(const TakeFileSets& sets) {
  std::vector<v1::FrameSet> out;
  const absl::Status status = sets.ForEach([&out](v1::FrameSet set) {
    out.push_back(std::move(set));
    return absl::OkStatus();
  });
  EXPECT_TRUE(status.ok()) << status;
  return out;
}

TEST(TakeFileSets, GroupsFramesByIndexWithEveryStreamOfTheFrame) {
  const std::string dir = testing::MakeTempDir("take_file_sets");
  auto sets = TakeFileSets::Open(WriteTake(dir + "/take.mcap", {}));
  ASSERT_TRUE(sets.ok()) << sets.status();
  const TakeFilePlan& plan = (*sets)->plan();
  EXPECT_EQ(plan.frame_sets, 5);
  EXPECT_EQ(plan.frames, 10);
  EXPECT_FALSE(plan.from_ingest_records);
  EXPECT_EQ(plan.messages_left_out, 1);  // The stray colour image.
  EXPECT_EQ(plan.ground_truth_messages, 5);
  EXPECT_EQ(plan.frames_per_sensor.at("k1"), 5);
  ASSERT_EQ((*sets)->sensors().size(), 2u);

  const std::vector<v1::FrameSet> read = ReadSets(**sets);
  ASSERT_EQ(read.size(), 5u);
  for (size_t i = 0; i < read.size(); ++i) {
    const v1::FrameSet& set = read[i];
    EXPECT_EQ(set.sequence(), i + 1);
    EXPECT_EQ(set.stamp_ns(), 1'000'000'000 + static_cast<int64_t>(i) * kPeriodNs + 2'000'000);
    EXPECT_EQ(set.skew_ns(), 4'000'000);
    ASSERT_EQ(set.frames_size(), 2);
    for (const v1::Frame& frame : set.frames()) {
      const std::string& s = frame.sensor_id();
      EXPECT_EQ(frame.frame_index(), static_cast<int64_t>(i));
      EXPECT_EQ(frame.host_stamp_ns(), frame.depth().host_stamp_ns());
      EXPECT_EQ(frame.device_stamp_ns(), frame.depth().device_stamp_ns());
      EXPECT_EQ(frame.depth().data(), Payload(s, static_cast<int64_t>(i), "depth"));
      EXPECT_EQ(frame.color().data(), Payload(s, static_cast<int64_t>(i), "color"));
      const bool mask = s == "k0" && i % 2 == 0;
      EXPECT_EQ(frame.has_mask(), mask) << s << " " << i;
      EXPECT_EQ(frame.skeletons_size(), s == "k1" && i == 2 ? 2 : 0);
    }
  }
}

TEST(TakeFileSets, IngestRecordsDecideTheSets) {
  const std::string dir = testing::MakeTempDir("take_file_sets_records");
  TakeSpec spec;
  spec.records = true;
  auto sets = TakeFileSets::Open(WriteTake(dir + "/take.mcap", spec));
  ASSERT_TRUE(sets.ok()) << sets.status();
  EXPECT_TRUE((*sets)->plan().from_ingest_records);
  // k1's frame 3 is in no record: left out with its colour.
  EXPECT_EQ((*sets)->plan().frames, 9);
  EXPECT_EQ((*sets)->plan().messages_left_out, 1 + 2);
  const std::vector<v1::FrameSet> read = ReadSets(**sets);
  ASSERT_EQ(read.size(), 5u);
  EXPECT_EQ(read[3].frames_size(), 1);
  ASSERT_EQ(read[3].missing_sensor_ids_size(), 1);
  EXPECT_EQ(read[3].missing_sensor_ids(0), "k1");
  EXPECT_EQ(read[4].stamp_ns(), 1'000'000'000 + 4 * kPeriodNs + 2'000'000);
}

TEST(TakeFileSets, FingerprintFollowsTheContent) {
  const std::string dir = testing::MakeTempDir("take_file_sets_fingerprint");
  auto a = TakeFileSets::Open(WriteTake(dir + "/a.mcap", {}));
  auto b = TakeFileSets::Open(WriteTake(dir + "/b.mcap", {}));
  TakeSpec longer;
  longer.frames = 6;
  auto c = TakeFileSets::Open(WriteTake(dir + "/c.mcap", longer));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ((*a)->plan().fingerprint, (*b)->plan().fingerprint);
  EXPECT_NE((*a)->plan().fingerprint, (*c)->plan().fingerprint);
}

TEST(TakeFileSets, RefusesToBufferATakeFarOutOfOrder) {
  const std::string dir = testing::MakeTempDir("take_file_sets_order");
  TakeSpec spec;
  spec.frames = 16;
  spec.depth_bytes = 500 << 10;
  // Every set waits for k1, whose frames come after all of k0's 8 MB (readers
  // sort by log time only within a 4 MiB chunk).
  spec.sensor_major = true;
  auto sets =
      TakeFileSets::Open(WriteTake(dir + "/take.mcap", spec), {.max_buffered_bytes = 1 << 20});
  ASSERT_TRUE(sets.ok()) << sets.status();
  int handed = 0;
  const absl::Status status = (*sets)->ForEach([&handed](v1::FrameSet) {
    ++handed;
    return absl::OkStatus();
  });
  EXPECT_TRUE(absl::IsResourceExhausted(status)) << status;
  EXPECT_EQ(handed, 0);
  // With room for it, the same file streams whole.
  auto roomy = TakeFileSets::Open(dir + "/take.mcap");
  ASSERT_TRUE(roomy.ok());
  EXPECT_EQ(ReadSets(**roomy).size(), 16u);
}

TEST(TakeFileSets, BadFilesGiveClearErrors) {
  const std::string dir = testing::MakeTempDir("take_file_sets_bad");
  EXPECT_FALSE(TakeFileSets::Open(dir + "/missing.mcap").ok());
  {
    std::ofstream junk(dir + "/junk.mcap", std::ios::binary);
    junk << "this is not an MCAP file at all";
  }
  const absl::Status junk = TakeFileSets::Open(dir + "/junk.mcap").status();
  EXPECT_FALSE(junk.ok());
  EXPECT_NE(junk.message().find("junk.mcap"), std::string::npos) << junk;
  // A take with sensors but no depth has nothing to send.
  v1::TakeInfo info;
  auto writer = TakeWriter::Open(dir + "/empty.mcap", info);
  ASSERT_TRUE(writer.ok());
  v1::SensorCalibration calibration;
  calibration.set_sensor_id("k0");
  ASSERT_TRUE((*writer)->AddSensor(calibration).ok());
  ASSERT_TRUE((*writer)->Close().ok());
  EXPECT_TRUE(absl::IsFailedPrecondition(TakeFileSets::Open(dir + "/empty.mcap").status()));
  EXPECT_TRUE(absl::IsInvalidArgument(
      TakeFileSets::Open(dir + "/empty.mcap", {.max_buffered_bytes = 0}).status()));
}

}  // namespace
}  // namespace reenact::ingest
