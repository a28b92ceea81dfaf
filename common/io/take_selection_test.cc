#include "common/io/take_selection.h"

#include <filesystem>
#include <map>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "absl/strings/match.h"
#include "common/io/take_convert.h"
#include "common/io/testing/small_take.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

void AddRange(google::protobuf::RepeatedPtrField<v1::FrameRange>* ranges, const std::string& id,
              int64_t first, int64_t end) {
  v1::FrameRange* range = ranges->Add();
  range->set_sensor_id(id);
  range->set_first(first);
  range->set_end(end);
}

// By sensor id and frame index.
std::map<std::pair<std::string, int64_t>, SensorFrame> FramesOf(const RecordedTake& take) {
  std::map<std::pair<std::string, int64_t>, SensorFrame> out;
  for (const SensorFrame& f : take.frames) out[{f.sensor_id, f.frame_index}] = f;
  return out;
}

TEST(TakeSelection, KeepsEveryMessageAndTheBytesOfTheSelectedFramesOnly) {
  const std::string dir = testing::MakeTempDir("take_selection");
  const std::string whole_path = dir + "/whole.mcap";
  testing::WriteTestTake(whole_path, /*sensor_count=*/2, /*frames=*/10);
  auto whole_reader = TakeReader::Open(whole_path);
  ASSERT_TRUE(whole_reader.ok()) << whole_reader.status();
  v1::TakeSelection selection;
  const std::string k0 = (*whole_reader)->sensors().begin()->first;
  const std::string k1 = std::next((*whole_reader)->sensors().begin())->first;
  AddRange(selection.mutable_depth(), k0, 2, 5);
  AddRange(selection.mutable_depth(), k0, 4, 6);  // Overlapping ranges merge.
  AddRange(selection.mutable_color(), k1, 0, 1);
  AddRange(selection.mutable_color(), k1, 7, 100);  // Past the end is fine.
  const std::string made_path = dir + "/made.mcap";
  ASSERT_TRUE(WriteTakeSelection(**whole_reader, selection, made_path).ok());

  auto whole = ReadRecordedTake(whole_path);
  auto made = ReadRecordedTake(made_path);
  ASSERT_TRUE(whole.ok() && made.ok()) << whole.status() << made.status();
  EXPECT_EQ(made->info.name, whole->info.name);
  EXPECT_EQ(made->sensors.size(), 2u);
  const auto whole_frames = FramesOf(*whole);
  const auto made_frames = FramesOf(*made);
  ASSERT_EQ(made_frames.size(), 20u);
  ASSERT_EQ(whole_frames.size(), 20u);
  int depth_kept = 0;
  int color_kept = 0;
  for (const auto& [key, frame] : made_frames) {
    const SensorFrame& original = whole_frames.at(key);
    const auto& [id, index] = key;
    ASSERT_TRUE(frame.depth && frame.mask && frame.color) << id << " " << index;
    const bool want_depth = id == k0 && index >= 2 && index < 6;
    const bool want_color = id == k1 && (index == 0 || index >= 7);
    EXPECT_EQ(frame.depth->data, want_depth ? original.depth->data : "") << id << " " << index;
    EXPECT_EQ(frame.mask->data, want_depth ? original.mask->data : "") << id << " " << index;
    EXPECT_EQ(frame.color->data, want_color ? original.color->data : "") << id << " " << index;
    // What groups frames into instants is kept for every frame.
    EXPECT_EQ(frame.depth->host_stamp_ns, original.depth->host_stamp_ns);
    EXPECT_EQ(frame.depth->encoding, original.depth->encoding);
    EXPECT_EQ(frame.color->host_stamp_ns, original.color->host_stamp_ns);
    ASSERT_EQ(frame.skeletons.size(), original.skeletons.size());
    EXPECT_EQ(frame.skeletons[0].joints.size(), original.skeletons[0].joints.size());
    depth_kept += want_depth;
    color_kept += want_color;
  }
  EXPECT_EQ(depth_kept, 4);
  EXPECT_EQ(color_kept, 4);

  // The ground truth stays behind; the made take is smaller.
  auto made_reader = TakeReader::Open(made_path);
  ASSERT_TRUE(made_reader.ok()) << made_reader.status();
  for (const TakeChannel& channel : (*made_reader)->channels()) {
    EXPECT_FALSE(absl::StartsWith(channel.topic, "/ground_truth")) << channel.topic;
  }
  EXPECT_LT(std::filesystem::file_size(made_path), std::filesystem::file_size(whole_path));

  // An empty selection: every message, no image bytes.
  const std::string index_path = dir + "/index.mcap";
  ASSERT_TRUE(WriteTakeSelection(**whole_reader, {}, index_path).ok());
  auto index = ReadRecordedTake(index_path);
  ASSERT_TRUE(index.ok()) << index.status();
  ASSERT_EQ(index->frames.size(), 20u);
  for (const SensorFrame& frame : index->frames) {
    ASSERT_TRUE(frame.depth && frame.color);
    EXPECT_TRUE(frame.depth->data.empty() && frame.color->data.empty());
  }
}

TEST(TakeSelection, RefusesBadSelectionsAndStopsWhenCancelled) {
  const std::string dir = testing::MakeTempDir("take_selection_bad");
  testing::WriteTestTake(dir + "/whole.mcap", 1, 4);
  auto reader = TakeReader::Open(dir + "/whole.mcap");
  ASSERT_TRUE(reader.ok()) << reader.status();
  const std::string id = (*reader)->sensors().begin()->first;
  const std::string out = dir + "/made.mcap";

  v1::TakeSelection unknown;
  AddRange(unknown.mutable_depth(), "no-such-sensor", 0, 1);
  EXPECT_TRUE(absl::IsInvalidArgument(WriteTakeSelection(**reader, unknown, out)));
  v1::TakeSelection negative;
  AddRange(negative.mutable_color(), id, -1, 3);
  EXPECT_TRUE(absl::IsInvalidArgument(WriteTakeSelection(**reader, negative, out)));
  v1::TakeSelection reversed;
  AddRange(reversed.mutable_depth(), id, 3, 2);
  EXPECT_TRUE(absl::IsInvalidArgument(WriteTakeSelection(**reader, reversed, out)));
  v1::TakeSelection many;
  for (int i = 0; i <= kMaxSelectionRanges; ++i) AddRange(many.mutable_depth(), id, i, i + 1);
  const absl::Status too_many = WriteTakeSelection(**reader, many, out);
  EXPECT_TRUE(absl::IsInvalidArgument(too_many)) << too_many;
  EXPECT_NE(too_many.message().find("at most"), std::string::npos) << too_many;

  const absl::Status cancelled = WriteTakeSelection(**reader, {}, out, [] { return true; });
  EXPECT_TRUE(absl::IsCancelled(cancelled)) << cancelled;
}

}  // namespace
}  // namespace reenact
