#include "common/io/take.h"

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <gtest/gtest.h>

#include "common/base/files.h"
#include "common/io/testing/small_take.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

using testing::WriteTestTake;
using testing::WrittenTake;

std::vector<std::string> RawMessages(const TakeReader& reader, const std::string& topic) {
  std::vector<std::string> out;
  auto messages = reader.mcap().ReadMessages(topic);
  EXPECT_TRUE(messages.ok()) << messages.status();
  if (messages.ok()) {
    for (const McapMessage& m : *messages) out.push_back(m.data);
  }
  return out;
}

TEST(TakeReader, ReadsBackEveryChannelOfTwoSensors) {
  const std::string path = testing::MakeTempDir("take_roundtrip") + "/take.mcap";
  const WrittenTake written = WriteTestTake(path, 2, 12);
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_TRUE((*reader)->report().indexed);
  EXPECT_EQ((*reader)->info().SerializeAsString(), written.info.SerializeAsString());
  ASSERT_EQ((*reader)->sensors().size(), 2u);
  EXPECT_EQ((*reader)->sensors().at("k1").world_from_depth().translation_m().x(), 1.5);

  const std::vector<TakeChannel> channels = (*reader)->channels();
  ASSERT_EQ(channels.size(), written.messages_by_topic.size());
  // 1 info + per sensor (calibration, colour, depth, mask, skeleton, gt depth)
  // + joints, body, mesh, topology.
  EXPECT_EQ(channels.size(), 1u + 2u * 6u + 4u);
  for (const TakeChannel& channel : channels) {
    const auto& expected = written.messages_by_topic.at(channel.topic);
    EXPECT_EQ(channel.message_count, expected.size()) << channel.topic;
    EXPECT_EQ(RawMessages(**reader, channel.topic), expected) << channel.topic;
  }
  EXPECT_EQ((*reader)->frame_count(), 12);
  EXPECT_EQ((*reader)->duration_ns(), 11 * written.period_ns);

  auto depth = (*reader)->ReadAll<v1::DepthImage>(SensorTopic("k0", "depth"));
  ASSERT_TRUE(depth.ok());
  ASSERT_EQ(depth->size(), 12u);
  for (size_t f = 0; f < depth->size(); ++f) EXPECT_EQ((*depth)[f].frame_index(), int64_t(f));
}

TEST(TakeReader, SchemasDescribeTheirMessages) {
  const std::string path = testing::MakeTempDir("take_schema") + "/take.mcap";
  WriteTestTake(path, 1, 2);
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok());
  for (const auto& [id, channel] : (*reader)->mcap().channels()) {
    const McapSchema& schema = (*reader)->mcap().schemas().at(channel.schema_id);
    EXPECT_EQ(schema.encoding, "protobuf");
    EXPECT_EQ(channel.message_encoding, "protobuf");
    google::protobuf::FileDescriptorSet set;
    ASSERT_TRUE(set.ParseFromString(schema.data)) << channel.topic;
    google::protobuf::DescriptorPool pool;
    for (const auto& file : set.file()) ASSERT_NE(pool.BuildFile(file), nullptr) << file.name();
    EXPECT_NE(pool.FindMessageTypeByName(schema.name), nullptr) << schema.name;
  }
}

TEST(TakeReader, RecoversTruncatedTake) {
  const std::string path = testing::MakeTempDir("take_truncated") + "/take.mcap";
  TakeWriterOptions options;
  options.mcap.chunk_size_bytes = 4096;
  const WrittenTake written = WriteTestTake(path, 2, 30, options);
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  ASSERT_TRUE(WriteFileAtomically(path, bytes->substr(0, bytes->size() * 2 / 3)).ok());
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_FALSE((*reader)->report().indexed);
  EXPECT_FALSE((*reader)->report().complete);
  EXPECT_NE((*reader)->report().Summary().find("byte offset"), std::string::npos);
  EXPECT_EQ((*reader)->info().name(), "test-take");
  EXPECT_EQ((*reader)->sensors().size(), 2u);
  const int64_t frames = (*reader)->frame_count();
  EXPECT_GT(frames, 5);
  EXPECT_LT(frames, 30);
  for (const TakeChannel& channel : (*reader)->channels()) {
    const std::vector<std::string> got = RawMessages(**reader, channel.topic);
    const auto& all = written.messages_by_topic.at(channel.topic);
    ASSERT_LE(got.size(), all.size());
    EXPECT_EQ(got, std::vector<std::string>(all.begin(), all.begin() + got.size()))
        << channel.topic;
  }
}

TEST(TakeReader, RejectsWrongMessageType) {
  const std::string path = testing::MakeTempDir("take_type") + "/take.mcap";
  WriteTestTake(path, 1, 2);
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok());
  auto wrong = (*reader)->ReadAll<v1::ColorImage>(SensorTopic("k0", "depth"));
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(TakeWriter, RejectsUnknownAndDuplicateSensors) {
  const std::string path = testing::MakeTempDir("take_sensors") + "/take.mcap";
  auto writer = TakeWriter::Open(path, v1::TakeInfo());
  ASSERT_TRUE(writer.ok());
  EXPECT_TRUE((*writer)->AddSensor(testing::TestCalibration("k0", 0)).ok());
  EXPECT_EQ((*writer)->AddSensor(testing::TestCalibration("k0", 0)).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ((*writer)->AddSensor(testing::TestCalibration("a/b", 0)).code(),
            absl::StatusCode::kInvalidArgument);
  v1::DepthImage depth;
  depth.set_sensor_id("k9");
  EXPECT_EQ((*writer)->WriteDepth(depth).code(), absl::StatusCode::kFailedPrecondition);
  depth.set_sensor_id("k0");
  depth.set_host_stamp_ns(-1);
  EXPECT_EQ((*writer)->WriteDepth(depth).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE((*writer)->Close().ok());
  depth.set_host_stamp_ns(1);
  EXPECT_EQ((*writer)->WriteDepth(depth).code(), absl::StatusCode::kFailedPrecondition);
}

// Writes frame sets [first, last] of sensor "k0" (depth only) with their
// ingest records, flushing the chunk after each set.
void WriteFrameSets(TakeWriter& writer, int first, int last) {
  for (int seq = first; seq <= last; ++seq) {
    v1::DepthImage depth;
    depth.set_sensor_id("k0");
    depth.set_host_stamp_ns(1'000'000 * seq);
    depth.set_frame_index(seq - 1);
    depth.set_encoding("rvl");
    depth.set_data(std::string(50 + seq, static_cast<char>(seq)));
    ASSERT_TRUE(writer.WriteDepth(depth).ok());
    v1::FrameSetRecord record;
    record.set_sequence(seq);
    record.set_stamp_ns(depth.host_stamp_ns());
    record.add_sensor_ids("k0");
    ASSERT_TRUE(writer.WriteFrameSetRecord(record).ok());
    ASSERT_TRUE(writer.FlushChunk().ok());
  }
}

std::vector<uint64_t> RecordSequences(const TakeReader& reader) {
  std::vector<uint64_t> out;
  auto records = reader.ReadAll<v1::FrameSetRecord>(kIngestFrameSetTopic);
  EXPECT_TRUE(records.ok()) << records.status();
  if (records.ok()) {
    for (const v1::FrameSetRecord& r : *records) out.push_back(r.sequence());
  }
  return out;
}

TEST(TakeWriter, AppendsToFinishedTakeAndKeepsSensors) {
  const std::string path = testing::MakeTempDir("take_append") + "/take.mcap";
  v1::TakeInfo info;
  info.set_name("append");
  info.set_start_stamp_ns(1000);
  {
    auto writer = TakeWriter::Open(path, info);
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->AddSensor(testing::TestCalibration("k0", 0)).ok());
    WriteFrameSets(**writer, 1, 4);
    ASSERT_TRUE((*writer)->Close().ok());
  }
  McapAppendReport report;
  auto writer = TakeWriter::OpenForAppend(path, {}, &report);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ((*writer)->info().name(), "append");
  ASSERT_EQ((*writer)->sensors().size(), 1u);
  EXPECT_EQ((*writer)->AddSensor(testing::TestCalibration("k0", 0)).code(),
            absl::StatusCode::kInvalidArgument);
  WriteFrameSets(**writer, 5, 7);
  v1::SensorLostRecord lost;
  lost.set_sensor_id("k0");
  lost.set_stamp_ns(9'000'000);
  lost.set_reason("unplugged");
  ASSERT_TRUE((*writer)->WriteSensorLost(lost).ok());
  lost.set_sensor_id("k5");
  EXPECT_EQ((*writer)->WriteSensorLost(lost).code(), absl::StatusCode::kFailedPrecondition);
  ASSERT_TRUE((*writer)->Close().ok());

  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_TRUE((*reader)->report().indexed);
  EXPECT_EQ(RecordSequences(**reader), (std::vector<uint64_t>{1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ((*reader)->frame_count(), 7);
  auto losses = (*reader)->ReadAll<v1::SensorLostRecord>(kIngestSensorLostTopic);
  ASSERT_TRUE(losses.ok());
  ASSERT_EQ(losses->size(), 1u);
  EXPECT_EQ(losses->front().reason(), "unplugged");
  // One channel per topic: the reopened writer reused the existing ones.
  std::set<std::string> topics;
  for (const TakeChannel& c : (*reader)->channels()) EXPECT_TRUE(topics.insert(c.topic).second);
}

TEST(TakeWriter, AppendsAfterCrashAtTheLastWholeFrameSet) {
  const std::string path = testing::MakeTempDir("take_append_crash") + "/take.mcap";
  v1::TakeInfo info;
  info.set_name("crash");
  {
    auto writer = TakeWriter::Open(path, info);
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->AddSensor(testing::TestCalibration("k0", 0)).ok());
    WriteFrameSets(**writer, 1, 6);
    ASSERT_TRUE((*writer)->Sync().ok());
    v1::DepthImage half;  // Frame of set 7, whose record never comes.
    half.set_sensor_id("k0");
    half.set_host_stamp_ns(7'000'000);
    ASSERT_TRUE((*writer)->WriteDepth(half).ok());
    ASSERT_TRUE((*writer)->Abort().ok());
  }
  // Tear the last chunk too, as a crash in the middle of a write would.
  const uint64_t size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 7);
  McapAppendReport report;
  auto writer = TakeWriter::OpenForAppend(path, {}, &report);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_GT(report.dropped_bytes, 0u);
  WriteFrameSets(**writer, 6, 8);
  ASSERT_TRUE((*writer)->Close().ok());
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok());
  EXPECT_EQ(RecordSequences(**reader), (std::vector<uint64_t>{1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ((*reader)->frame_count(), 8);
}

TEST(TakeReader, RejectsFileThatIsNotMcap) {
  const std::string path = testing::MakeTempDir("take_not") + "/take.mcap";
  ASSERT_TRUE(WriteFileAtomically(path, "{\"json\": true}").ok());
  EXPECT_EQ(TakeReader::Open(path).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact
