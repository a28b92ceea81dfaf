// The one entry point of the reconstruction methods that the worker process
// (reenact-worker) calls: read a take, run the method the job names (from
// the registry, registry.h), write the reenactment to a file. The methods:
//
//   rigid-cylinders  thesis 3.3: cylinders from rectangles fitted in a
//                    representative frame (Eq. 3.3-3.5), VDTM by the
//                    pose-closest frame (Eq. 3.6); cylinders/.
//   rigid-carved     thesis 3.4: per-part registration (Eq. 3.7-3.9),
//                    per-part truncated SDF (Eq. 3.10-3.11), marching cubes,
//                    VDTM by the rotation-closest frame (Eq. 3.13-3.15);
//                    carving/.
//   body             thesis ch. 4: the statistical body model fitted to the
//                    merged point clouds (Eq. 4.4-4.8), textured into an
//                    atlas (4.4); body/.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/methods/option_reader.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// The options RunMethod reads itself (loading the take) before the method
// gets the rest; every method accepts them.
struct LoadOptions {
  TakeFramesOptions frames;
  absl::Status Read(methods::OptionReader& reader);
  absl::Status Validate() const { return absl::OkStatus(); }
};

// Checks a job as the worker will run it: InvalidArgument for an unknown
// method (naming the known ones) or options that the load or the method
// reject (naming the key, or the known keys for an unknown one); then the
// method's CheckAssets against `asset_roots` (the server's --assets), so
// that a model no worker could find fails at Submit.
absl::Status CheckJob(const std::string& method, const OptionMap& options,
                      const std::vector<std::string>& asset_roots = {});

// What a job of `method` with `options` is estimated to take of its
// worker's memory on a take of `take`'s size, bytes (memory_estimate.h):
// the program, the take's streams and decodes, and the method's own terms
// (ReconstructionMethod::MemoryBytes). An upper bound, checked against
// measured peaks; a server refuses jobs over its --job-memory-mb with it.
// CheckJob's errors.
absl::StatusOr<int64_t> JobMemoryBytes(const std::string& method, const OptionMap& options,
                                       const TakeSize& take);

// Longest part file a run reads (an atlas of 8192 px has 1 GiB of sums).
inline constexpr uint64_t kMaxPartFileBytes = uint64_t{2} << 30;

struct MethodInput {
  std::string take_path;  // The take's MCAP file.
  std::string method;     // A registered method's name (registry.h).
  // Method options (strings as submitted); unknown keys are InvalidArgument.
  OptionMap options;
  // Ids written into ReenactmentInfo.
  std::string reenactment_id;
  std::string take_id;
  std::string job_id;
  // Folders whose subfolders the option model=makehuman:NAME names (the
  // server's --assets); never from a client.
  std::vector<std::string> asset_roots = {};
  // A phase of a segmented job (kWhole: none): segment `segment_index` of
  // `segment_count`; the prepared part file (kSegment, kStitch) and every
  // segment's, in order (kStitch).
  MethodPhase phase = MethodPhase::kWhole;
  int segment_index = 0;
  int segment_count = 1;
  std::string prepared_path = {};
  std::vector<std::string> segment_paths = {};
};

// What a finished method reports (also written into ReenactmentInfo.figures).
struct MethodResult {
  int frames = 0;          // Instants (PartFrames) in the reenactment.
  int keyframes = 0;       // Texture keyframes kept.
  int64_t file_bytes = 0;  // Size of the written reenactment file.
  std::map<std::string, double> figures;
};

// Runs `input.method` on the take and writes the reenactment to `out_path`
// (through a temporary name: on failure nothing is left at `out_path`);
// the phases kPrepare and kSegment write their part file there instead.
// A take that holds no skeleton is tracked from its depth first, or gets
// the skeletons an earlier run tracked and kept beside it (take_tracking.h;
// progress stage "track", a log line "track: ...").
// InvalidArgument for an unknown method, unknown or malformed options, or a
// take the method cannot use (no depth; "no person in this take" when the
// tracker found nobody); Cancelled when `progress` returned false; DataLoss
// for a corrupt take.
absl::StatusOr<MethodResult> RunMethod(const MethodInput& input, const std::string& out_path,
                                       const ProgressCallback& progress = {},
                                       const LogCallback& log = {});

// The frames whose images one sensor's stream must hold for a run.
struct SensorFrameNeeds {
  std::string sensor_id;
  std::vector<int64_t> depth_frames;  // Sorted, each once (the sensor's own frame_index).
  std::vector<int64_t> color_frames;
};

// What a run of `input` (its phase) decodes of the take, by sensor and
// frame: loads `input.take_path` (the take, or the take without image
// bytes: ReadTake's empty selection) as RunMethod does and asks the method
// (ReconstructionMethod::Needs). A worker that streams the take reads only
// these frames' images. Errors as RunMethod's for the method, its options
// and the take.
absl::StatusOr<std::vector<SensorFrameNeeds>> FramesNeeded(const MethodInput& input);

}  // namespace reenact::recon
