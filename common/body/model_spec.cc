#include "common/body/model_spec.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"
#include "common/body/makehuman_importer.h"
#include "common/body/procedural_body.h"

namespace reenact::body {
namespace {

namespace fs = std::filesystem;

constexpr char kMakeHumanPrefix[] = "makehuman:";
constexpr size_t kMaxAssetNameChars = 64;

bool IsAssetName(const std::string& name) {
  if (name.empty() || name.size() > kMaxAssetNameChars || name[0] == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

}  // namespace

bool IsBodyModelSpec(const std::string& spec) {
  return spec == "procedural" || absl::StartsWith(spec, kMakeHumanPrefix);
}

absl::StatusOr<BodyModel> LoadBodyModelSpec(const std::string& spec) {
  if (spec == "procedural") return BuildProceduralBody();
  if (absl::StartsWith(spec, kMakeHumanPrefix)) return ImportMakeHuman(spec.substr(10));
  return absl::InvalidArgumentError(
      absl::StrCat("expected 'procedural' or 'makehuman:DIR', got '", spec, "'"));
}

bool IsAssetModelSpec(const std::string& spec) {
  return spec == "procedural" ||
         (absl::StartsWith(spec, kMakeHumanPrefix) && IsAssetName(spec.substr(10)));
}

std::vector<std::string> ListAssetModels(const std::vector<std::string>& asset_roots) {
  std::vector<std::string> names;
  for (const std::string& root : asset_roots) {
    std::error_code error;
    for (fs::directory_iterator it(root, error), end; !error && it != end; it.increment(error)) {
      const std::string name = it->path().filename().string();
      std::error_code type_error;
      if (IsAssetName(name) && it->is_directory(type_error)) names.push_back(name);
    }
  }
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  return names;
}

absl::StatusOr<std::string> ResolveAssetModelSpec(const std::string& spec,
                                                  const std::vector<std::string>& asset_roots) {
  if (spec == "procedural") return spec;
  if (!IsAssetModelSpec(spec)) {
    // Quoted only up to a length: the spec is the client's own text.
    return absl::InvalidArgumentError(absl::StrCat(
        "model must be 'procedural' or 'makehuman:NAME', NAME an asset folder of the server "
        "(1..",
        kMaxAssetNameChars, " of A-Z a-z 0-9 . _ -, no path); got '", spec.substr(0, 80),
        spec.size() > 80 ? "...'" : "'"));
  }
  const std::string name = spec.substr(10);
  if (asset_roots.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat("model ", spec,
                     ": this server has no MakeHuman assets (reenact-server "
                     "--assets DIR); use model=procedural"));
  }
  for (const std::string& root : asset_roots) {
    std::error_code error;
    const fs::path folder = fs::path(root) / name;
    if (fs::is_directory(folder, error)) return kMakeHumanPrefix + folder.string();
  }
  const std::vector<std::string> names = ListAssetModels(asset_roots);
  return absl::NotFoundError(absl::StrCat(
      "model ", spec, ": no such asset on this server; it has ",
      names.empty() ? "none" : absl::StrCat("makehuman:", absl::StrJoin(names, ", makehuman:"))));
}

absl::StatusOr<BodyModel> LoadAssetModelSpec(const std::string& spec,
                                             const std::vector<std::string>& asset_roots) {
  absl::StatusOr<std::string> resolved = ResolveAssetModelSpec(spec, asset_roots);
  if (!resolved.ok()) return resolved.status();
  absl::StatusOr<BodyModel> model = LoadBodyModelSpec(*resolved);
  if (model.ok() || spec == "procedural") return model;
  const std::string folder = resolved->substr(10);
  std::string message = absl::StrReplaceAll(model.status().message(), {{folder, spec}});
  for (const std::string& root : asset_roots) {
    // Said another way (a canonical path, say): nothing of it goes out.
    if (!root.empty() && absl::StrContains(message, root)) {
      message = "the asset's files could not be read as MakeHuman assets";
    }
  }
  return absl::Status(model.status().code(), absl::StrCat("model ", spec, ": ", message));
}

}  // namespace reenact::body
