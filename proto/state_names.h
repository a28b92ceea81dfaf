// The names of take and job states, one table for every side: the catalog
// stores them, the CLI, the JSON outputs and the HTTP API show them.
// "recording", "complete", "interrupted"; "queued", "running", "succeeded",
// "failed", "cancelled"; "unspecified" for anything else.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "reenact/v1/jobs_service.pb.h"
#include "reenact/v1/takes_service.pb.h"

namespace reenact {

// Static strings (std::string, so that std and absl string views both take
// them).
const std::string& TakeStateName(v1::TakeState state);
const std::string& JobStateName(v1::JobState state);

// The state of a name above (exactly as written there); nullopt for any
// other text, "unspecified" included.
std::optional<v1::TakeState> TakeStateFromName(std::string_view name);
std::optional<v1::JobState> JobStateFromName(std::string_view name);

}  // namespace reenact
