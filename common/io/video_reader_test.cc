#include "common/io/video_reader.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "common/io/video_writer.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

constexpr int kWidth = 64;
constexpr int kHeight = 48;
constexpr int kFrames = 40;
constexpr double kFps = 25.0;
// Mean absolute difference, 8-bit units over all channels, that a decoded
// frame may have from the frame written (H.264 at crf 18, 4:2:0 chroma).
constexpr double kMaxMeanAbsDiff = 3.0;

// Frame t: colour ramps whose level moves 5 units per frame in every channel
// (so neighbouring frames differ by about 5 on average), and a white 10x10
// square moving 1 px per frame to the right.
RgbImage PatternFrame(int t) {
  RgbImage image(kWidth, kHeight);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const bool in_square = x >= 2 + t && x < 12 + t && y >= 19 && y < 29;
      image.at(x, y, 0) = in_square ? 255 : static_cast<uint8_t>(10 + x / 2 + 5 * t);
      image.at(x, y, 1) = in_square ? 255 : static_cast<uint8_t>(230 - y / 2 - 5 * t);
      image.at(x, y, 2) = in_square ? 255 : static_cast<uint8_t>(20 + (x + y) / 4 + 5 * t);
    }
  }
  return image;
}

// Mean absolute difference of two images of the same size, 8-bit units.
double MeanAbsDiff(const RgbImage& a, const RgbImage& b) {
  if (a.width != b.width || a.height != b.height) return 255.0;
  int64_t sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i) sum += std::abs(int{a.data[i]} - int{b.data[i]});
  return static_cast<double>(sum) / static_cast<double>(a.data.size());
}

// The bytes of the pattern written by VideoWriter to `file_name` (its
// extension picks the container) with H.264 at crf 18, a key frame every 10.
std::string EncodePattern(const std::string& file_name) {
  const std::string dir = testing::MakeTempDir("video_reader");
  const std::string path = dir + "/" + file_name;
  VideoWriterOptions options;
  options.codec = VideoCodec::kH264;
  options.crf = 18;
  options.keyframe_interval = 10;
  auto writer = VideoWriter::Open(path, kWidth, kHeight, kFps, options);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (!writer.ok()) return "";
  for (int t = 0; t < kFrames; ++t) EXPECT_TRUE((*writer)->Append(PatternFrame(t)).ok());
  EXPECT_TRUE((*writer)->Close().ok());
  std::ifstream file(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  std::filesystem::remove_all(dir);
  return bytes;
}

// Expects frame `index` of `reader` to be the pattern's frame `index`;
// returns its mean absolute difference (255 when it does not read).
double ExpectPatternFrame(VideoReader& reader, int index) {
  absl::StatusOr<RgbImage> frame = reader.Frame(index);
  EXPECT_TRUE(frame.ok()) << "frame " << index << ": " << frame.status();
  if (!frame.ok()) return 255.0;
  const double diff = MeanAbsDiff(*frame, PatternFrame(index));
  EXPECT_LE(diff, kMaxMeanAbsDiff) << "frame " << index;
  // The index is right, not merely close: the neighbours match worse.
  if (index > 0) {
    EXPECT_LT(diff, MeanAbsDiff(*frame, PatternFrame(index - 1))) << "frame " << index;
  }
  if (index + 1 < kFrames) {
    EXPECT_LT(diff, MeanAbsDiff(*frame, PatternFrame(index + 1))) << "frame " << index;
  }
  return diff;
}

TEST(VideoReader, ReadsEveryFrameInPresentationOrder) {
  const std::string bytes = EncodePattern("pattern.mp4");
  ASSERT_FALSE(bytes.empty());
  auto reader = VideoReader::Open(bytes);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_EQ((*reader)->frame_count(), kFrames);
  EXPECT_EQ((*reader)->width(), kWidth);
  EXPECT_EQ((*reader)->height(), kHeight);
  EXPECT_NEAR((*reader)->fps(), kFps, 1e-9);
  double max_diff = 0.0;
  double mean_diff = 0.0;
  for (int t = 0; t < kFrames; ++t) {
    const double diff = ExpectPatternFrame(**reader, t);
    max_diff = std::max(max_diff, diff);
    mean_diff += diff / kFrames;
  }
  std::printf("%zu bytes, %d frames: mean absolute difference mean %.3f, max %.3f (8-bit)\n",
              bytes.size(), kFrames, mean_diff, max_diff);
}

TEST(VideoReader, RandomAccessSeeksBack) {
  const std::string bytes = EncodePattern("pattern.mp4");
  auto reader = VideoReader::Open(bytes);
  ASSERT_TRUE(reader.ok()) << reader.status();
  double max_diff = 0.0;
  for (int index : {35, 5, 20, 39, 0, 0, 9, 10, 9}) {
    max_diff = std::max(max_diff, ExpectPatternFrame(**reader, index));
  }
  std::printf("random access: max mean absolute difference %.3f (8-bit)\n", max_diff);
}

// Matroska declares no frame count: Open counts the packets.
TEST(VideoReader, CountsFramesWhenTheContainerDoesNot) {
  const std::string bytes = EncodePattern("pattern.mkv");
  auto reader = VideoReader::Open(bytes);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_EQ((*reader)->frame_count(), kFrames);
  EXPECT_NEAR((*reader)->fps(), kFps, 1e-9);
  for (int index : {0, 1, 2, 39, 15, 30, 31}) ExpectPatternFrame(**reader, index);
}

TEST(VideoReader, RejectsBytesThatAreNoVideo) {
  auto empty = VideoReader::Open("");
  EXPECT_TRUE(absl::IsInvalidArgument(empty.status())) << empty.status();

  std::string garbage(1024, '\0');
  uint32_t state = 12345;
  for (char& c : garbage) {
    state = state * 1664525u + 1013904223u;
    c = static_cast<char>(state >> 24);
  }
  auto noise = VideoReader::Open(garbage);
  ASSERT_FALSE(noise.ok());
  EXPECT_TRUE(absl::IsInvalidArgument(noise.status()) || absl::IsDataLoss(noise.status()))
      << noise.status();
}

// VideoWriter puts the index first, so half a file still opens; the frames
// whose data are gone are DataLoss, and the reader goes on serving the others.
TEST(VideoReader, TruncatedFileLosesItsLateFrames) {
  const std::string bytes = EncodePattern("pattern.mp4");
  const std::string half = bytes.substr(0, bytes.size() / 2);
  auto reader = VideoReader::Open(half);
  if (!reader.ok()) {
    EXPECT_TRUE(absl::IsInvalidArgument(reader.status()) || absl::IsDataLoss(reader.status()))
        << reader.status();
    return;
  }
  int first_lost = -1;
  for (int t = 0; t < kFrames && first_lost < 0; ++t) {
    absl::StatusOr<RgbImage> frame = (*reader)->Frame(t);
    if (frame.ok()) continue;
    EXPECT_TRUE(absl::IsDataLoss(frame.status())) << frame.status();
    first_lost = t;
    std::printf("half of %zu bytes: frames 0..%d read, then: %s\n", bytes.size(), t - 1,
                frame.status().ToString().c_str());
  }
  EXPECT_GT(first_lost, 0);
  absl::StatusOr<RgbImage> last = (*reader)->Frame(kFrames - 1);
  EXPECT_TRUE(absl::IsDataLoss(last.status())) << last.status();
  // Still usable: earlier frames read after the errors.
  ExpectPatternFrame(**reader, 0);
  if (first_lost > 1) ExpectPatternFrame(**reader, first_lost - 1);
}

TEST(VideoReader, IndexOutsideTheVideoIsOutOfRange) {
  const std::string bytes = EncodePattern("pattern.mp4");
  auto reader = VideoReader::Open(bytes);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_TRUE(absl::IsOutOfRange((*reader)->Frame(-1).status()));
  EXPECT_TRUE(absl::IsOutOfRange((*reader)->Frame(kFrames).status()));
  ExpectPatternFrame(**reader, 3);
}

}  // namespace
}  // namespace reenact
