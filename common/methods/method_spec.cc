#include "common/methods/method_spec.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/methods/option_reader.h"

namespace reenact::methods {

const char* OptionTypeName(OptionType type) {
  switch (type) {
    case OptionType::kInt:
      return "int";
    case OptionType::kDouble:
      return "double";
    case OptionType::kBool:
      return "bool";
    case OptionType::kString:
      return "string";
  }
  return "string";
}

const char* TextureModeName(TextureMode mode) {
  switch (mode) {
    case TextureMode::kPoseClosest:
      return "pose-closest";
    case TextureMode::kRotationClosest:
      return "rotation-closest";
    case TextureMode::kBodyAtlas:
      return "body-atlas";
  }
  return "rotation-closest";
}

const MethodSpec* FindMethod(const std::vector<MethodSpec>& specs, const std::string& name) {
  for (const MethodSpec& spec : specs) {
    if (spec.name == name) return &spec;
  }
  return nullptr;
}

absl::Status CheckOptions(const MethodSpec& spec,
                          const std::map<std::string, std::string>& options) {
  OptionReader reader(options);
  for (const OptionSpec& option : spec.options) {
    absl::Status status;
    switch (option.type) {
      case OptionType::kInt: {
        int value = 0;
        status = option.has_bounds ? reader.Int(option.name, &value, static_cast<int>(option.min),
                                                static_cast<int>(option.max))
                                   : reader.Int(option.name, &value);
        break;
      }
      case OptionType::kDouble: {
        double value = 0.0;
        status = option.has_bounds ? reader.Double(option.name, &value, option.min, option.max)
                                   : reader.Double(option.name, &value);
        break;
      }
      case OptionType::kBool: {
        bool value = false;
        status = reader.Bool(option.name, &value);
        break;
      }
      case OptionType::kString: {
        std::string value;
        status = reader.String(option.name, &value);
        break;
      }
    }
    if (!status.ok()) return status;
  }
  return reader.Finish();
}

absl::Status UnknownMethodError(const std::vector<MethodSpec>& specs, const std::string& name) {
  std::vector<std::string> names;
  names.reserve(specs.size());
  for (const MethodSpec& spec : specs) names.push_back(spec.name);
  // Clients choose the name: quote at most 80 characters of it.
  const std::string shown = name.size() > 80 ? name.substr(0, 80) + "..." : name;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown method \"", shown, "\" (known: ", absl::StrJoin(names, ", "), ")"));
}

}  // namespace reenact::methods
