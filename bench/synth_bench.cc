// Synthesis speed: a whole synthetic take written to disk, as `reenact synth`
// does it. The reference case is 10 s of 2 Kinect v2 sensors (300 instants,
// 600 sensor frames at 1920x1080 colour and 512x424 depth). Counters report
// sensor frames per second and the take's size.
#include <filesystem>

#include <benchmark/benchmark.h>

#include "common/synth/synthesizer.h"

namespace reenact::synth {
namespace {

void BM_SynthesizeTake(benchmark::State& state) {
  SynthOptions options;
  options.motion = "builtin:front-kick";
  options.body = "procedural";
  options.num_sensors = 2;
  options.seconds = static_cast<double>(state.range(0));
  const std::string path =
      (std::filesystem::temp_directory_path() / "reenact_synth_bench.mcap").string();
  SynthSummary summary;
  for (auto _ : state) {
    auto result = SynthesizeTake(options, path);
    if (!result.ok()) {
      state.SkipWithError(std::string(result.status().message()).c_str());
      return;
    }
    summary = *result;
  }
  const double sensor_frames = static_cast<double>(summary.frames) * summary.sensors;
  state.counters["sensor_frames"] = sensor_frames;
  state.counters["sensor_frames_per_s"] =
      benchmark::Counter(sensor_frames * state.iterations(), benchmark::Counter::kIsRate);
  state.counters["take_MB"] = summary.file_bytes / 1e6;
  state.SetLabel(summary.renderer);
  std::filesystem::remove(path);
}
BENCHMARK(BM_SynthesizeTake)->Arg(10)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace reenact::synth

BENCHMARK_MAIN();
