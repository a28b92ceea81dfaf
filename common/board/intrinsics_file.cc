#include "common/board/intrinsics_file.h"

#include <cmath>
#include <cstdint>
#include <numbers>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::board {
namespace {

absl::Status Bad(absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat("camera intrinsics JSON: ", why));
}

// Reads the number `key` into `value`; absent keys leave it unchanged unless
// `required`.
absl::Status ReadNumber(const nlohmann::json& json, const char* key, bool required, double* value) {
  if (!json.contains(key))
    return required ? Bad(absl::StrCat("missing \"", key, "\"")) : absl::OkStatus();
  if (!json[key].is_number()) return Bad(absl::StrCat("\"", key, "\" is not a number"));
  *value = json[key].get<double>();
  return absl::OkStatus();
}

absl::Status ReadSize(const nlohmann::json& json, CameraIntrinsics* intrinsics) {
  for (auto [key, field] :
       {std::pair{"width", &intrinsics->width}, std::pair{"height", &intrinsics->height}}) {
    if (!json.contains(key) || !json[key].is_number_integer()) {
      return Bad(absl::StrCat("\"", key, "\" must be an integer"));
    }
    *field = json[key].get<int>();
  }
  return absl::OkStatus();
}

absl::Status ReadDistortion(const nlohmann::json& json, CameraIntrinsics* intrinsics) {
  const bool named = json.contains("k1") || json.contains("k2") || json.contains("k3") ||
                     json.contains("p1") || json.contains("p2");
  if (json.contains("distortion")) {
    if (named) return Bad("give \"distortion\" or k1..p2, not both");
    const nlohmann::json& d = json["distortion"];
    if (!d.is_array() || d.size() < 4 || d.size() > 5) {
      return Bad("\"distortion\" must be [k1, k2, p1, p2] or [k1, k2, p1, p2, k3]");
    }
    double* fields[] = {&intrinsics->k1, &intrinsics->k2, &intrinsics->p1, &intrinsics->p2,
                        &intrinsics->k3};
    for (size_t i = 0; i < d.size(); ++i) {
      if (!d[i].is_number()) return Bad("\"distortion\" holds a non-number");
      *fields[i] = d[i].get<double>();
    }
    return absl::OkStatus();
  }
  RETURN_IF_ERROR(ReadNumber(json, "k1", false, &intrinsics->k1));
  RETURN_IF_ERROR(ReadNumber(json, "k2", false, &intrinsics->k2));
  RETURN_IF_ERROR(ReadNumber(json, "k3", false, &intrinsics->k3));
  RETURN_IF_ERROR(ReadNumber(json, "p1", false, &intrinsics->p1));
  return ReadNumber(json, "p2", false, &intrinsics->p2);
}

}  // namespace

absl::StatusOr<CameraIntrinsics> IntrinsicsFromFieldOfView(int width, int height,
                                                           double horizontal_fov_deg) {
  if (width <= 0 || height <= 0 || !(horizontal_fov_deg > 1.0 && horizontal_fov_deg < 179.0)) {
    return absl::InvalidArgumentError(absl::StrCat("IntrinsicsFromFieldOfView: ", width, "x",
                                                   height, " pixels, ", horizontal_fov_deg,
                                                   " degrees"));
  }
  CameraIntrinsics intrinsics;
  intrinsics.width = width;
  intrinsics.height = height;
  const double half_fov_rad = 0.5 * horizontal_fov_deg * std::numbers::pi / 180.0;
  intrinsics.fx = intrinsics.fy = 0.5 * width / std::tan(half_fov_rad);
  intrinsics.cx = 0.5 * (width - 1);
  intrinsics.cy = 0.5 * (height - 1);
  return intrinsics;
}

absl::StatusOr<CameraIntrinsics> ParseIntrinsicsJson(absl::string_view text) {
  const nlohmann::json json =
      nlohmann::json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded() || !json.is_object()) return Bad("not a JSON object");
  CameraIntrinsics intrinsics;
  RETURN_IF_ERROR(ReadSize(json, &intrinsics));
  if (json.contains("horizontal_fov_deg") && !json.contains("fx")) {
    double fov_deg = 0.0;
    RETURN_IF_ERROR(ReadNumber(json, "horizontal_fov_deg", true, &fov_deg));
    ASSIGN_OR_RETURN(intrinsics,
                     IntrinsicsFromFieldOfView(intrinsics.width, intrinsics.height, fov_deg));
  } else {
    RETURN_IF_ERROR(ReadNumber(json, "fx", true, &intrinsics.fx));
    RETURN_IF_ERROR(ReadNumber(json, "fy", true, &intrinsics.fy));
    RETURN_IF_ERROR(ReadNumber(json, "cx", true, &intrinsics.cx));
    RETURN_IF_ERROR(ReadNumber(json, "cy", true, &intrinsics.cy));
  }
  RETURN_IF_ERROR(ReadDistortion(json, &intrinsics));
  if (absl::Status status = intrinsics.Validate(); !status.ok()) return Bad(status.message());
  return intrinsics;
}

absl::StatusOr<CameraIntrinsics> LoadIntrinsicsFile(const std::string& path) {
  // An intrinsics file is a few hundred bytes; 1 MiB is plenty.
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, uint64_t{1} << 20));
  absl::StatusOr<CameraIntrinsics> intrinsics = ParseIntrinsicsJson(text);
  if (!intrinsics.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", intrinsics.status().message()));
  }
  return intrinsics;
}

std::string FormatIntrinsicsJson(const CameraIntrinsics& intrinsics) {
  const nlohmann::json json = {
      {"width", intrinsics.width}, {"height", intrinsics.height}, {"fx", intrinsics.fx},
      {"fy", intrinsics.fy},       {"cx", intrinsics.cx},         {"cy", intrinsics.cy},
      {"k1", intrinsics.k1},       {"k2", intrinsics.k2},         {"p1", intrinsics.p1},
      {"p2", intrinsics.p2},       {"k3", intrinsics.k3}};
  return json.dump(2) + "\n";
}

}  // namespace reenact::board
