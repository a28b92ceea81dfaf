// A body model named the way users name it on command lines and in job
// options: "procedural" (built by our code, procedural_body.h) or
// "makehuman:DIR" (MakeHuman's assets in DIR, makehuman_importer.h).
//
// A server never takes a folder from a client: job options name a MakeHuman
// body "makehuman:NAME", NAME being a folder under one of the server's asset
// roots (reenact-server --assets), and what a client sees of a failure names
// the asset, never a path on the server.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/body/body_model.h"

namespace reenact::body {

// True for "procedural" and "makehuman:..." (the folder is not checked).
bool IsBodyModelSpec(const std::string& spec);

// InvalidArgument for another spec; the builder's or importer's errors.
absl::StatusOr<BodyModel> LoadBodyModelSpec(const std::string& spec);

// True for "procedural" and "makehuman:NAME" with NAME a plain folder name:
// 1..64 of [A-Za-z0-9._-], not starting with a dot (so neither "." nor "..").
bool IsAssetModelSpec(const std::string& spec);

// The spec LoadBodyModelSpec reads for a model named by a client:
// "procedural" as it is, "makehuman:NAME" as "makehuman:ROOT/NAME" for the
// first of `asset_roots` that holds a folder NAME. InvalidArgument for
// another form (a path included), FailedPrecondition when there are no
// roots, NotFound naming the assets there are. No message holds a root.
absl::StatusOr<std::string> ResolveAssetModelSpec(const std::string& spec,
                                                  const std::vector<std::string>& asset_roots);

// ResolveAssetModelSpec, then LoadBodyModelSpec; an import error has the
// asset's folder replaced by its name ("makehuman:NAME/base.obj: ...").
absl::StatusOr<BodyModel> LoadAssetModelSpec(const std::string& spec,
                                             const std::vector<std::string>& asset_roots);

// The asset names (folders) under `asset_roots`, sorted, without repeats.
std::vector<std::string> ListAssetModels(const std::vector<std::string>& asset_roots);

}  // namespace reenact::body
