// A body model named the way users name it on command lines and in job
// options: "procedural" (built by our code, procedural_body.h) or
// "makehuman:DIR" (MakeHuman's assets in DIR, makehuman_importer.h).
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "common/body/body_model.h"

namespace reenact::body {

// True for "procedural" and "makehuman:..." (the folder is not checked).
bool IsBodyModelSpec(const std::string& spec);

// InvalidArgument for another spec; the builder's or importer's errors.
absl::StatusOr<BodyModel> LoadBodyModelSpec(const std::string& spec);

}  // namespace reenact::body
