// The Follow stream of the Reenactments service (reenactments_service.proto):
// a subscriber of a live job's follow (server/live/live_hub.h). Events are
// queued and written one at a time; a subscriber that falls more than
// kFollowMaxQueuedFrames frames behind loses the oldest frames (never a mesh
// nor the end), so a slow client holds neither the follower nor much memory.
#pragma once

#include <grpcpp/grpcpp.h>

#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "server/rpc/server_context.h"

namespace reenact::server {

// Frame events a Follow stream holds for a slow client (2 s at 30 fps).
inline constexpr int kFollowMaxQueuedFrames = 64;

// The reactor of one Follow call: NOT_FOUND / INVALID_ARGUMENT for unknown
// or malformed job ids; a job that follows nothing gets one FollowEnd
// (NOT_FOLLOWING) and the stream ends OK.
grpc::ServerWriteReactor<v1::FollowEvent>* NewFollowStream(ServerContext& context,
                                                           const v1::FollowRequest& request);

}  // namespace reenact::server
