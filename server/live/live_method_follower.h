// The live hub's followers from the method registry: the follower of a job
// of method M is M's own (recon::ReconstructionMethod::MakeLiveFollower,
// e.g. the body method's fit FrameSet by FrameSet, thesis ch. 4), behind the
// hub's LiveFollower interface, so that the hub and the rest of
// reenact_server need not link the reconstruction library; reenact-server's
// main plugs this factory into ServerOptions::live.
#pragma once

#include <string>
#include <vector>

#include "server/live/live_hub.h"

namespace reenact::server {

// Asks the registry for the job's method and has it make the follower:
// Unimplemented for a method that cannot follow a take, InvalidArgument for
// an unknown method, bad options or calibrations, the method's own errors
// (e.g. body: the model's). A model is looked up under `asset_roots` (the
// server's --assets).
LiveFollowerFactory MakeLiveMethodFollowerFactory(std::vector<std::string> asset_roots = {});

}  // namespace reenact::server
