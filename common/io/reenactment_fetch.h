// The messages of a Reenactments.Fetch stream (reenactments_service.proto)
// put back together into a ReenactmentData, checking the order the service
// promises: the info, the body mesh (body-model reenactments) and the
// pieces of its appearance video, part meshes, frame batches, keyframes.
// Every client of Fetch (clients/sdk, the server's HTTP front) reads the
// stream through it.
#pragma once

#include "absl/status/status.h"
#include "common/io/reenactment_file.h"
#include "reenact/v1/reenactments_service.pb.h"

namespace reenact {

// Moves one message of the stream into `data`. `stage` starts at 0 and
// carries from call to call. DataLoss for an empty message, one out of
// order, or a piece of an appearance video before any body mesh.
absl::Status AppendFetchChunk(v1::FetchReenactmentChunk& chunk, ReenactmentData* data, int* stage);

}  // namespace reenact
