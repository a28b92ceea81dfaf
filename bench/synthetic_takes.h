// What the accuracy benchmark commands on synthetic takes (novel_view_e2e,
// body_tracked_e2e) share: the flags that describe their takes, CMU clips
// named without their extension, and the method options given as k=v.
#pragma once

#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_split.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/synth/synthesizer.h"

namespace reenact::bench {

// The comma-separated items of `text`.
inline std::vector<std::string> SplitList(const std::string& text) {
  return absl::StrSplit(text, ',', absl::SkipEmpty());
}

// The flags every such command reads (their names, for Flags::Parse:
// kTakeFlags) and their values.
inline const std::set<std::string> kTakeFlags = {"seconds",      "fps",   "every", "color-width",
                                                 "color-height", "shape", "work",  "data",
                                                 "json",         "option"};
struct TakeSettings {
  double seconds = 2.0;
  double fps = 15.0;
  int every = 2;  // Evaluate every k-th instant.
  int color_width = 1920;
  int color_height = 1080;
  std::string shape = "random:5";
  std::string work;  // Where takes are cached and results written.
  std::string data;  // The test data folder (mocap/cmu, body/makehuman).
  std::string json;  // Where the rows go as JSON; empty: nowhere.
  // Extra options of the body method (--option k=v,...).
  std::map<std::string, std::string> body_options;
};

// Reads kTakeFlags over the defaults already in `s`.
inline absl::Status ReadTakeSettings(const Flags& flags, TakeSettings* s) {
  ASSIGN_OR_RETURN(s->seconds, flags.GetDouble("seconds", s->seconds));
  ASSIGN_OR_RETURN(s->fps, flags.GetDouble("fps", s->fps));
  ASSIGN_OR_RETURN(s->every, flags.GetInt("every", s->every));
  ASSIGN_OR_RETURN(s->color_width, flags.GetInt("color-width", s->color_width));
  ASSIGN_OR_RETURN(s->color_height, flags.GetInt("color-height", s->color_height));
  s->shape = flags.GetOr("shape", s->shape);
  s->work = flags.GetOr("work", s->work);
  s->data = flags.GetOr("data", s->data);
  s->json = flags.GetOr("json", "");
  for (const std::string& kv : SplitList(flags.GetOr("option", ""))) {
    const size_t eq = kv.find('=');
    if (eq == std::string::npos) return absl::InvalidArgumentError("--option wants k=v: " + kv);
    s->body_options[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  return absl::OkStatus();
}

// Sets the motion of `options` to the CMU clip `motion` under
// DATA/mocap/cmu, named without extension: NAME.bvh, or NAME.amc with the
// ASF of its subject (the name's prefix before the first '_' and its kind
// after the first '-', e.g. 09_06-run.amc -> 09-run.asf). NotFound when
// neither exists.
inline absl::Status SetCmuMotion(const std::string& data, const std::string& motion,
                                 synth::SynthOptions* options) {
  namespace fs = std::filesystem;
  const fs::path cmu = fs::path(data) / "mocap" / "cmu";
  if (fs::exists(cmu / (motion + ".bvh"))) {
    options->motion = (cmu / (motion + ".bvh")).string();
    return absl::OkStatus();
  }
  if (!fs::exists(cmu / (motion + ".amc"))) {
    return absl::NotFoundError("no clip " + motion + " (.bvh or .amc) under " + cmu.string());
  }
  options->motion = (cmu / (motion + ".amc")).string();
  const std::string subject = motion.substr(0, motion.find('_'));
  const size_t dash = motion.find('-');
  const std::string kind = dash == std::string::npos ? "" : motion.substr(dash);
  options->asf_path = (cmu / (subject + kind + ".asf")).string();
  if (!fs::exists(options->asf_path)) {
    return absl::NotFoundError("no ASF " + options->asf_path + " for " + motion);
  }
  return absl::OkStatus();
}

}  // namespace reenact::bench
