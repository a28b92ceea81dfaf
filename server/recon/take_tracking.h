// Loading a take for a method, with skeletons even where the take stores
// none: a take imported from another tool's recording (`reenact import`), or
// synthesised or captured without a tracker, holds depth but no skeleton,
// and every method needs one. Such a take is tracked here with the capture
// daemon's tracker (tracking::BodyTracker, default options), sensor by
// sensor over its stored depth (tracking::TrackTakeSensor), and the
// skeletons are kept beside the take (TrackedSkeletonsPath), so a take is
// tracked once, by its first job, not once per job.
//
// The file beside the take is trusted only when it is whole (its checksum)
// and was made from this take (size and checksums of the take's first and
// last MiB, which hold the MCAP header and the summary with every chunk's
// offset) by this tracker (the model or forest file's size and checksum);
// otherwise it is ignored and the take tracked again. It is written through
// a temporary name and renamed, so concurrent jobs on the same take (each
// may track it) never see half a file. When it cannot be written (a
// read-only take) the job goes on with the skeletons it tracked.
//
// Network workers (server/worker/work_agent.h) read a copy of the take in
// their scratch folder, which goes with the job; they track that copy for
// each job (phase) they run. Only the server's own workers read the stored
// take in place and keep the skeletons for later jobs.
#pragma once

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// Where the skeletons tracked from the take at `take_path` are kept.
std::string TrackedSkeletonsPath(const std::string& take_path);

// TakeFrames::Load for a method: a take whose frames hold no skeleton at all
// gets the skeletons kept beside it or, when there are none (or they are
// corrupt or stale), tracked from its depth and kept. `log` gets a line
// "track: ..." saying which. `load_progress` gets stage "load" (items:
// messages read), `track_progress` stage "track" (items: depth frames of all
// sensors) while the take is tracked; either returning false cancels
// (Cancelled). TakeFrames::Load's errors; InvalidArgument containing "no
// person in this take" when the tracker found nobody in any frame; DataLoss
// naming the sensor and frame for depth that does not decode; the tracker's
// errors when its model cannot be loaded.
absl::StatusOr<std::unique_ptr<TakeFrames>> LoadTakeForMethod(
    const std::string& path, const TakeFramesOptions& options = {},
    const ProgressCallback& load_progress = {}, const ProgressCallback& track_progress = {},
    const LogCallback& log = {});

}  // namespace reenact::recon
