// The live hub's follower for the method "body": recon::LiveBodyFollower
// (server/recon/body/live_body.h, thesis ch. 4 applied FrameSet by FrameSet)
// behind the hub's LiveFollower interface, so that the hub and the rest of
// reenact_server need not link the reconstruction library; reenact-server's
// main plugs this factory into ServerOptions::live.
#pragma once

#include <string>
#include <vector>

#include "server/live/live_hub.h"

namespace reenact::server {

// Makes a recon::LiveBodyFollower per live job: the job's options are the
// method body's (plus shape_spacing); InvalidArgument for bad options or
// calibrations, the model's errors. model=makehuman:NAME is looked up under
// `asset_roots` (the server's --assets).
LiveFollowerFactory MakeLiveBodyFollowerFactory(std::vector<std::string> asset_roots = {});

}  // namespace reenact::server
