#include "common/body/model_spec.h"

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/body/makehuman_importer.h"
#include "common/body/procedural_body.h"

namespace reenact::body {

bool IsBodyModelSpec(const std::string& spec) {
  return spec == "procedural" || absl::StartsWith(spec, "makehuman:");
}

absl::StatusOr<BodyModel> LoadBodyModelSpec(const std::string& spec) {
  if (spec == "procedural") return BuildProceduralBody();
  if (absl::StartsWith(spec, "makehuman:")) return ImportMakeHuman(spec.substr(10));
  return absl::InvalidArgumentError(
      absl::StrCat("expected 'procedural' or 'makehuman:DIR', got '", spec, "'"));
}

}  // namespace reenact::body
