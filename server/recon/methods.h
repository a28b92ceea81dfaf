// The reconstruction methods a job can run, behind one entry point that the
// worker process (reenact-worker) calls: read a take, build a reenactment,
// write it to a file.
//
//   rigid-cylinders  thesis 3.3: cylinders from rectangles fitted in a
//                    representative frame (Eq. 3.3-3.5), VDTM by the
//                    pose-closest frame (Eq. 3.6).
//   rigid-carved     thesis 3.4: per-part registration (Eq. 3.7-3.9),
//                    per-part truncated SDF (Eq. 3.10-3.11), marching cubes,
//                    VDTM by the rotation-closest frame (Eq. 3.13-3.15).
//   body             thesis ch. 4: the statistical body model fitted to the
//                    merged point clouds (Eq. 4.4-4.8), textured into an
//                    atlas (4.4); body/body_method.h.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"

namespace reenact::recon {

struct MethodInput {
  std::string take_path;  // The take's MCAP file.
  std::string method;     // One of MethodNames().
  // Method options (strings as submitted); unknown keys are InvalidArgument.
  std::map<std::string, std::string> options;
  // Ids written into ReenactmentInfo.
  std::string reenactment_id;
  std::string take_id;
  std::string job_id;
  // Folders whose subfolders the option model=makehuman:NAME names (the
  // server's --assets); never from a client.
  std::vector<std::string> asset_roots = {};
};

// What a finished method reports (also written into ReenactmentInfo.figures).
struct MethodResult {
  int frames = 0;          // Instants (PartFrames) in the reenactment.
  int keyframes = 0;       // Texture keyframes kept.
  int64_t file_bytes = 0;  // Size of the written reenactment file.
  std::map<std::string, double> figures;
};

// Human-readable log lines of a running method (one line per call).
using LogCallback = std::function<void(const std::string& line)>;

// Names of the methods RunMethod accepts.
std::vector<std::string> MethodNames();

// Runs `input.method` on the take and writes the reenactment to `out_path`
// (through a temporary name: on failure nothing is left at `out_path`).
// InvalidArgument for an unknown method, unknown or malformed options, or a
// take the method cannot use (no skeleton, no depth); Cancelled when
// `progress` returned false; DataLoss for a corrupt take.
absl::StatusOr<MethodResult> RunMethod(const MethodInput& input, const std::string& out_path,
                                       const ProgressCallback& progress = {},
                                       const LogCallback& log = {});

}  // namespace reenact::recon
