// The take a server makes for one read of a phase of a split job
// (common/io/take_selection.h), on a synthetic 4 s take of two Kinect v2
// sensors (512x424 depth, 1920x1080 colour, 30 fps): the take without image
// bytes (what every phase reads first), and a segment's share (the depth of
// the first half, the colour of every other instant in it). Rates are of
// the take read; the counters give the made file's size.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>

#include "common/io/take.h"
#include "common/io/take_selection.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

constexpr int kFrames = 120;  // 4 s at 30 fps.

const std::string& TakePath() {
  static const std::string* path = [] {
    auto* p = new std::string(std::filesystem::temp_directory_path() /
                              "reenact_take_selection_bench.mcap");
    if (!std::filesystem::exists(*p)) {
      synth::SynthOptions options;
      options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
      options.motion = "builtin:front-kick";
      options.num_sensors = 2;
      options.seconds = kFrames / 30.0;
      if (!synth::SynthesizeTake(options, *p).ok()) p->clear();
    }
    return p;
  }();
  return *path;
}

void Run(benchmark::State& state, const v1::TakeSelection& selection) {
  if (TakePath().empty()) {
    state.SkipWithError("the take could not be synthesised");
    return;
  }
  auto take = TakeReader::Open(TakePath());
  if (!take.ok()) {
    state.SkipWithError(std::string(take.status().message()).c_str());
    return;
  }
  const std::string out = TakePath() + ".made";
  for (auto _ : state) {
    if (const absl::Status made = WriteTakeSelection(**take, selection, out); !made.ok()) {
      state.SkipWithError(std::string(made.message()).c_str());
      return;
    }
  }
  const auto in_bytes = static_cast<int64_t>(std::filesystem::file_size(TakePath()));
  const auto out_bytes = static_cast<int64_t>(std::filesystem::file_size(out));
  state.SetBytesProcessed(state.iterations() * in_bytes);
  state.counters["take_MB"] = 1e-6 * static_cast<double>(in_bytes);
  state.counters["made_MB"] = 1e-6 * static_cast<double>(out_bytes);
  std::filesystem::remove(out);
}

void BM_TakeWithoutImages(benchmark::State& state) { Run(state, {}); }
BENCHMARK(BM_TakeWithoutImages)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HalfTheTakesSegment(benchmark::State& state) {
  v1::TakeSelection selection;
  for (const char* id : {"k0", "k1"}) {
    v1::FrameRange* depth = selection.add_depth();
    depth->set_sensor_id(id);
    depth->set_first(0);
    depth->set_end(kFrames / 2);
    for (int f = 0; f < kFrames / 2; f += 2) {
      v1::FrameRange* color = selection.add_color();
      color->set_sensor_id(id);
      color->set_first(f);
      color->set_end(f + 1);
    }
  }
  Run(state, selection);
}
BENCHMARK(BM_HalfTheTakesSegment)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace reenact

BENCHMARK_MAIN();
