// The per-frame appearance video of a body reenactment (body_texturing.h's
// BakeAppearanceVideo format): encoding one atlas frame, and decoding one in
// a player (VideoReader) playing on, or jumping to a random instant. The
// frames are synthetic atlases of `size` pixels: a smooth chart-like pattern
// with fine detail whose shading drifts from frame to frame, as a turning
// limb's does; 60 frames at 15 fps, a key frame a second, crf 23, as the
// body method writes them.
//
//   build/bench/appearance_video_bench
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "common/base/image.h"
#include "common/io/video_reader.h"
#include "common/io/video_writer.h"

namespace reenact {
namespace {

constexpr int kFrames = 60;
constexpr double kFps = 15.0;

RgbImage SyntheticAtlas(int size, int frame) {
  RgbImage atlas(size, size);
  std::mt19937 noise(7);
  std::uniform_int_distribution<int> grain(-6, 6);
  const double shade = 0.85 + 0.15 * std::sin(0.3 * frame);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double u = static_cast<double>(x) / size, v = static_cast<double>(y) / size;
      const double pattern =
          0.5 + 0.25 * std::sin(40.0 * u) * std::cos(33.0 * v) + 0.2 * ((x / 8 + y / 8) % 2);
      for (int c = 0; c < 3; ++c) {
        const double value = 255.0 * shade * pattern * (0.6 + 0.2 * c) + grain(noise);
        atlas.at(x, y, c) = static_cast<uint8_t>(std::clamp(value, 0.0, 255.0));
      }
    }
  }
  return atlas;
}

std::string EncodedVideo(int size) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("appearance_bench_" + std::to_string(size) + ".mp4"))
                               .string();
  VideoWriterOptions options;
  options.crf = 23;
  options.keyframe_interval = static_cast<int>(kFps);
  auto writer = VideoWriter::Open(path, size, size, kFps, options);
  if (!writer.ok()) return "";
  for (int k = 0; k < kFrames; ++k) {
    if (!(*writer)->Append(SyntheticAtlas(size, k)).ok()) return "";
  }
  if (!(*writer)->Close().ok()) return "";
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  return bytes;
}

void BM_EncodeFrame(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  const std::string path =
      (std::filesystem::temp_directory_path() / "appearance_encode.mp4").string();
  std::vector<RgbImage> frames;
  frames.reserve(8);
  for (int k = 0; k < 8; ++k) frames.push_back(SyntheticAtlas(size, k));
  VideoWriterOptions options;
  options.crf = 23;
  options.keyframe_interval = static_cast<int>(kFps);
  auto writer = VideoWriter::Open(path, size, size, kFps, options);
  if (!writer.ok()) {
    state.SkipWithError("no video encoder");
    return;
  }
  int k = 0;
  for (auto _ : state) {
    if (!(*writer)->Append(frames[k++ % frames.size()]).ok()) state.SkipWithError("append failed");
  }
  (*writer)->Close().IgnoreError();
  std::filesystem::remove(path);
}
BENCHMARK(BM_EncodeFrame)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

// Decodes frames of a `size` px video: the next one each time (wrapping
// seeks back once per kFrames), or (`random`) one at a random instant.
void DecodeFrames(benchmark::State& state, bool random) {
  const int size = static_cast<int>(state.range(0));
  const std::string bytes = EncodedVideo(size);
  auto reader = VideoReader::Open(bytes);
  if (bytes.empty() || !reader.ok()) {
    state.SkipWithError("no video");
    return;
  }
  std::mt19937 engine(3);
  std::uniform_int_distribution<int> instant(0, kFrames - 1);
  int k = 0;
  for (auto _ : state) {
    auto frame = (*reader)->Frame(random ? instant(engine) : k);
    if (!frame.ok()) state.SkipWithError("decode failed");
    benchmark::DoNotOptimize(frame);
    k = (k + 1) % kFrames;
  }
  state.counters["bytes_per_s"] = static_cast<double>(bytes.size()) * kFps / kFrames;
}

void BM_DecodeNextFrame(benchmark::State& state) { DecodeFrames(state, /*random=*/false); }
BENCHMARK(BM_DecodeNextFrame)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_DecodeRandomFrame(benchmark::State& state) { DecodeFrames(state, /*random=*/true); }
BENCHMARK(BM_DecodeRandomFrame)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace reenact

BENCHMARK_MAIN();
