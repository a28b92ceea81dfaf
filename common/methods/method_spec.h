// What the processes other than the worker need to know of a reconstruction
// method, without linking it: its name, what it does, its options (names,
// types, defaults, bounds, documentation), whether it can follow a take
// live, and how its reenactments are textured (the viewer's Eq. 3.6 or
// Eq. 3.13 keyframe ranking, or a body-model atlas). The methods themselves
// and their one registry are in server/recon (registry.h); the server hands
// these specs to clients through Jobs.ListMethods, and each reenactment
// records its texture mode (ReenactmentInfo.texture_mode).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace reenact::methods {

enum class OptionType { kInt, kDouble, kBool, kString };

// "int", "double", "bool", "string".
const char* OptionTypeName(OptionType type);

struct OptionSpec {
  std::string name;
  OptionType type = OptionType::kString;
  std::string default_value;  // As text, the way a job would give it.
  // Bounds of kInt and kDouble options (has_bounds false: any value).
  bool has_bounds = false;
  double min = 0.0;
  double max = 0.0;
  std::string doc;
  // Read by every method before its own options (loading the take).
  bool common = false;
  // Read only when a job follows its take while it is recorded (a live job);
  // the worker that runs the method on the whole take never gets it.
  bool live_only = false;
};

// How a method's reenactments pick texture keyframes when rendered.
enum class TextureMode {
  kPoseClosest,      // Eq. 3.6: one ranking by skeleton pose for all parts.
  kRotationClosest,  // Eq. 3.13: per part, by the part's rotation.
  kBodyAtlas,        // Thesis 4.4: one atlas baked on the body model.
};

const char* TextureModeName(TextureMode mode);

struct MethodSpec {
  std::string name;     // What a job names: "rigid-carved".
  std::string summary;  // One line.
  std::string thesis;   // Sections and equations it implements.
  // Whether a job may follow its take while it is recorded (the method
  // makes its own live follower).
  bool live = false;
  TextureMode texture = TextureMode::kRotationClosest;
  std::vector<OptionSpec> options;
  // Whether one take may be split across several workers (a job's
  // segments > 1): a prepare phase, segments, and a stitch.
  bool segmentable = false;
};

// The spec named `name` among `specs`, or null.
const MethodSpec* FindMethod(const std::vector<MethodSpec>& specs, const std::string& name);

// Checks `options` against what `spec` lists: InvalidArgument for a name it
// does not list (naming those it does), a value that does not parse as the
// option's type or lies outside its bounds. What spans options (the
// method's Validate()) is the method's own check (server/recon).
absl::Status CheckOptions(const MethodSpec& spec,
                          const std::map<std::string, std::string>& options);

// InvalidArgument for an unknown method, listing the known ones.
absl::Status UnknownMethodError(const std::vector<MethodSpec>& specs, const std::string& name);

}  // namespace reenact::methods
