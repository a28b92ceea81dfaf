// The body tracker per 512x424 Kinect v2 depth frame: the network (the
// default) and the forest, each alone and with the body-model refinement, on
// a sequence of a held-out motion (CMU 131_03, not in the training motions)
// seen 2.5 m away. Needs ../shared/data and the shipped models. For one
// core: taskset -c 0 build/bench/tracker_bench.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "common/testing/test_data.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/training_data.h"

namespace reenact::tracking {
namespace {

const std::vector<TrainingImage>* Frames() {
  static const std::vector<TrainingImage>* frames = [] {
    const TrainingDataOptions o =
        SequenceOptions(testing::TestDataPath("mocap/cmu/131_03.bvh"), 30, 2.5, 2.5, 7);
    auto images = SynthesizeTrainingImages(o, /*keep_full_frames=*/true);
    if (!images.ok()) {
      std::fprintf(stderr, "tracker_bench: %s\n", std::string(images.status().message()).c_str());
      return static_cast<std::vector<TrainingImage>*>(nullptr);
    }
    return new std::vector<TrainingImage>(*std::move(images));
  }();
  return frames;
}

void BM_Track(benchmark::State& state) {
  const std::vector<TrainingImage>* frames = Frames();
  if (frames == nullptr || frames->empty()) {
    state.SkipWithError("no frames (../shared/data missing?)");
    return;
  }
  BodyTrackerOptions options;
  options.refine = state.range(0) != 0;
  options.method = state.range(1) != 0 ? TrackerMethod::kForest : TrackerMethod::kNetwork;
  auto tracker = BodyTracker::Create(options);
  if (!tracker.ok()) {
    state.SkipWithError(std::string(tracker.status().message()).c_str());
    return;
  }
  size_t i = 0;
  for (auto _ : state) {
    const TrainingImage& frame = (*frames)[i++ % frames->size()];
    auto people = (*tracker)->Track(frame.full_depth_mm, frame.full_intrinsics, &frame.full_mask);
    benchmark::DoNotOptimize(people);
  }
  const char* method = options.method == TrackerMethod::kNetwork ? "network" : "forest";
  state.SetLabel(options.refine ? std::string(method) + " + body-model refinement" : method);
}
BENCHMARK(BM_Track)
    ->Args({0, 0})
    ->Args({1, 0})
    ->Args({0, 1})
    ->Args({1, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace reenact::tracking

BENCHMARK_MAIN();
