// Acclaim ASF/AMC reader (the CMU motion capture database's original format).
//
// ASF: ":units" (mass, length multiplier, angle deg|rad), ":root" (order of
// the root's AMC values, axis order, rest position and orientation),
// ":bonedata" (begin/end blocks: id, name, direction, length, axis ax ay az
// ORDER, dof, limits) and ":hierarchy" (lines "parent child child ...").
// Directions and axes are stated in the world frame of the rest pose.
// AMC: optional ":FULLY-SPECIFIED", ":DEGREES"/":RADIANS" headers, then per
// frame a line with the frame number and one line "bone value..." per bone
// with degrees of freedom, values in the order of the bone's dof.
//
// Forward kinematics (the standard Acclaim formulation): for bone b with axis
// rotation C_b and dof rotation M_b, its rotation relative to its parent in
// rest-aligned frames is L_b = C_b * M_b * C_b^-1, and the bone runs from its
// start (its parent's end) along direction_b * length_b. Multi-axis rotations
// apply in the order listed ("axis ... XYZ", "dof rx ry rz": X first, so
// M = Rz * Ry * Rx). Each bone becomes one Motion joint placed at the bone's
// START; a bone without children adds an end joint "<bone>_end" at its end.
//
// Lengths: ":units length k" means one file unit is 1/k inch, so
// metres_per_unit = 0.0254 / k (CMU: k = 0.45 -> 0.05644 m). AMC files do not
// state their frame rate; AsfAmcOptions gives it (CMU: 120 fps).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/body/motion.h"

namespace reenact::body {
namespace {

constexpr double kMetresPerInch = 0.0254;
// Deepest bone nesting accepted (guards the recursive skeleton walk; CMU
// skeletons are 8 bones deep).
constexpr int kMaxDepth = 256;

enum class Dof { kTx, kTy, kTz, kRx, kRy, kRz };

std::optional<Dof> DofFromName(absl::string_view name) {
  const std::string lower = absl::AsciiStrToLower(name);
  if (lower == "tx") return Dof::kTx;
  if (lower == "ty") return Dof::kTy;
  if (lower == "tz") return Dof::kTz;
  if (lower == "rx") return Dof::kRx;
  if (lower == "ry") return Dof::kRy;
  if (lower == "rz") return Dof::kRz;
  return std::nullopt;
}

struct AsfBone {
  std::string name;
  Eigen::Vector3d direction{0, 0, 0};  // Unit vector, rest world frame.
  double length_units = 0.0;
  Eigen::Quaterniond axis = Eigen::Quaterniond::Identity();  // C_b.
  std::vector<Dof> dofs;
  std::vector<std::string> children;
  int line = 0;  // Line of its "begin".
};

struct AsfSkeleton {
  double length_multiplier = 1.0;
  bool degrees = true;
  std::vector<Dof> root_order = {Dof::kTx, Dof::kTy, Dof::kTz, Dof::kRx, Dof::kRy, Dof::kRz};
  Eigen::Vector3d root_position_units{0, 0, 0};
  Eigen::Quaterniond root_axis = Eigen::Quaterniond::Identity();
  std::vector<std::string> root_children;
  std::map<std::string, AsfBone> bones;
};

// Splits `text` into lines without '\r'; line i is numbered i + 1.
std::vector<absl::string_view> SplitLines(absl::string_view text) {
  std::vector<absl::string_view> lines = absl::StrSplit(text, '\n');
  for (absl::string_view& line : lines) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  }
  if (lines.size() > 1 && lines.back().empty()) lines.pop_back();  // Final newline.
  return lines;
}

// Words of a line, with '#' comments and limit parentheses removed.
std::vector<absl::string_view> Words(absl::string_view line) {
  if (const size_t hash = line.find('#'); hash != absl::string_view::npos) {
    line = line.substr(0, hash);
  }
  return absl::StrSplit(line, absl::ByAnyChar(" \t()"), absl::SkipEmpty());
}

Eigen::Quaterniond AxisAngle(char axis, double radians) {
  const Eigen::Vector3d unit = axis == 'X'   ? Eigen::Vector3d::UnitX()
                               : axis == 'Y' ? Eigen::Vector3d::UnitY()
                                             : Eigen::Vector3d::UnitZ();
  return Eigen::Quaterniond(Eigen::AngleAxisd(radians, unit));
}

class LineError {
 public:
  explicit LineError(std::string path) : path_(std::move(path)) {}
  absl::Status operator()(int line, absl::string_view message) const {
    return absl::InvalidArgumentError(absl::StrCat(path_, ":", line, ": ", message));
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

absl::StatusOr<double> ParseNumber(const LineError& error, int line, absl::string_view word,
                                   absl::string_view what) {
  double value = 0.0;
  if (!absl::SimpleAtod(word, &value) || !std::isfinite(value)) {
    return error(line, absl::StrCat("bad number '", word, "' for ", what));
  }
  return value;
}

// Reads `count` numbers from words[first...]; errors name the line.
absl::StatusOr<Eigen::Vector3d> ParseVector3(const LineError& error, int line,
                                             const std::vector<absl::string_view>& words,
                                             absl::string_view what) {
  if (words.size() < 4) return error(line, absl::StrCat(what, " needs 3 numbers"));
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    ASSIGN_OR_RETURN(v[k], ParseNumber(error, line, words[static_cast<size_t>(k) + 1], what));
  }
  return v;
}

// C from three angles and an order token such as "XYZ" (applied X first).
absl::StatusOr<Eigen::Quaterniond> AxisRotationFromAngles(const LineError& error, int line,
                                                          const Eigen::Vector3d& angles,
                                                          absl::string_view order, bool degrees) {
  const std::string upper = absl::AsciiStrToUpper(order);
  if (upper.size() != 3 || upper.find_first_not_of("XYZ") != std::string::npos ||
      upper[0] == upper[1] || upper[1] == upper[2] || upper[0] == upper[2]) {
    return error(line, absl::StrCat("bad axis order '", order, "'"));
  }
  const double to_radians = degrees ? M_PI / 180.0 : 1.0;
  Eigen::Quaterniond c = Eigen::Quaterniond::Identity();
  for (char axis : upper) c = AxisAngle(axis, angles[axis - 'X'] * to_radians) * c;
  return c;
}

class AsfParser {
 public:
  AsfParser(const std::string& path, absl::string_view text) : error_(path) {
    lines_ = SplitLines(text);
  }

  absl::StatusOr<AsfSkeleton> Parse() {
    while (i_ < lines_.size()) {
      const std::vector<absl::string_view> words = Words(lines_[i_]);
      if (words.empty() || words[0][0] != ':') {
        ++i_;
        continue;
      }
      const int line = Line();
      ++i_;
      if (words[0] == ":units") {
        RETURN_IF_ERROR(ParseUnits());
      } else if (words[0] == ":root") {
        RETURN_IF_ERROR(ParseRoot());
      } else if (words[0] == ":bonedata") {
        RETURN_IF_ERROR(ParseBonedata());
      } else if (words[0] == ":hierarchy") {
        RETURN_IF_ERROR(ParseHierarchy());
        seen_hierarchy_ = true;
      } else if (words[0] != ":version" && words[0] != ":name" && words[0] != ":documentation") {
        return error_(line, absl::StrCat("unknown section '", words[0], "'"));
      }
    }
    if (!seen_hierarchy_) return error_(static_cast<int>(lines_.size()), "no :hierarchy");
    return std::move(skeleton_);
  }

 private:
  int Line() const { return static_cast<int>(i_) + 1; }

  // True while the current line belongs to the section (does not start ':').
  bool InSection(std::vector<absl::string_view>& words) {
    while (i_ < lines_.size()) {
      words = Words(lines_[i_]);
      if (!words.empty()) return words[0][0] != ':';
      ++i_;
    }
    return false;
  }

  absl::Status ParseUnits() {
    std::vector<absl::string_view> words;
    for (; InSection(words); ++i_) {
      if (words.size() < 2) return error_(Line(), "a unit needs a value");
      if (words[0] == "length") {
        ASSIGN_OR_RETURN(skeleton_.length_multiplier,
                         ParseNumber(error_, Line(), words[1], "length"));
        if (skeleton_.length_multiplier <= 0) return error_(Line(), "length must be > 0");
      } else if (words[0] == "angle") {
        if (words[1] != "deg" && words[1] != "rad") {
          return error_(Line(), absl::StrCat("angle unit '", words[1], "' is not deg or rad"));
        }
        skeleton_.degrees = words[1] == "deg";
      }
    }
    return absl::OkStatus();
  }

  absl::Status ParseRoot() {
    std::vector<absl::string_view> words;
    Eigen::Vector3d orientation(0, 0, 0);
    std::string axis_order = "XYZ";
    int axis_line = Line();
    for (; InSection(words); ++i_) {
      if (words[0] == "order") {
        skeleton_.root_order.clear();
        for (size_t k = 1; k < words.size(); ++k) {
          const std::optional<Dof> dof = DofFromName(words[k]);
          if (!dof) return error_(Line(), absl::StrCat("unknown root dof '", words[k], "'"));
          skeleton_.root_order.push_back(*dof);
        }
      } else if (words[0] == "axis") {
        if (words.size() != 2) return error_(Line(), "root axis needs one order token");
        axis_order = std::string(words[1]);
        axis_line = Line();
      } else if (words[0] == "position") {
        ASSIGN_OR_RETURN(skeleton_.root_position_units,
                         ParseVector3(error_, Line(), words, "root position"));
      } else if (words[0] == "orientation") {
        ASSIGN_OR_RETURN(orientation, ParseVector3(error_, Line(), words, "root orientation"));
      } else {
        return error_(Line(), absl::StrCat("unknown :root field '", words[0], "'"));
      }
    }
    ASSIGN_OR_RETURN(skeleton_.root_axis, AxisRotationFromAngles(error_, axis_line, orientation,
                                                                 axis_order, skeleton_.degrees));
    return absl::OkStatus();
  }

  absl::Status ParseBonedata() {
    std::vector<absl::string_view> words;
    while (InSection(words)) {
      if (words[0] != "begin") {
        return error_(Line(), absl::StrCat("expected 'begin', found '", words[0], "'"));
      }
      AsfBone bone;
      bone.line = Line();
      ++i_;
      RETURN_IF_ERROR(ParseBone(bone));
      if (bone.name.empty()) return error_(bone.line, "bone without a name");
      if (bone.name == "root" || skeleton_.bones.count(bone.name)) {
        return error_(bone.line, absl::StrCat("bone '", bone.name, "' defined twice"));
      }
      skeleton_.bones.emplace(bone.name, std::move(bone));
    }
    return absl::OkStatus();
  }

  // The fields of one bone, up to and including its "end".
  absl::Status ParseBone(AsfBone& bone) {
    std::vector<absl::string_view> words;
    for (; InSection(words); ++i_) {
      const absl::string_view key = words[0];
      if (key == "end") {
        ++i_;
        return absl::OkStatus();
      } else if (key == "name") {
        if (words.size() != 2) return error_(Line(), "name needs one word");
        bone.name = std::string(words[1]);
      } else if (key == "direction") {
        ASSIGN_OR_RETURN(bone.direction, ParseVector3(error_, Line(), words, "direction"));
      } else if (key == "length") {
        if (words.size() != 2) return error_(Line(), "length needs one number");
        ASSIGN_OR_RETURN(bone.length_units, ParseNumber(error_, Line(), words[1], "length"));
      } else if (key == "axis") {
        if (words.size() != 5) return error_(Line(), "axis needs 3 angles and an order");
        ASSIGN_OR_RETURN(const Eigen::Vector3d angles, ParseVector3(error_, Line(), words, "axis"));
        ASSIGN_OR_RETURN(
            bone.axis, AxisRotationFromAngles(error_, Line(), angles, words[4], skeleton_.degrees));
      } else if (key == "dof") {
        for (size_t k = 1; k < words.size(); ++k) {
          const std::optional<Dof> dof = DofFromName(words[k]);
          if (!dof || *dof == Dof::kTx || *dof == Dof::kTy || *dof == Dof::kTz) {
            return error_(Line(), absl::StrCat("unsupported dof '", words[k],
                                               "' (bones may only rotate: rx ry rz)"));
          }
          bone.dofs.push_back(*dof);
        }
      }
      // id, limits (and their continuation lines), bodymass, cofmass: unused.
    }
    return error_(Line(), absl::StrCat("bone block from line ", bone.line, " has no 'end'"));
  }

  absl::Status ParseHierarchy() {
    std::vector<absl::string_view> words;
    for (; InSection(words); ++i_) {
      if (words[0] == "begin" || words[0] == "end") continue;
      const std::string parent(words[0]);
      if (parent != "root" && !skeleton_.bones.count(parent)) {
        return error_(Line(), absl::StrCat("unknown bone '", parent, "' in :hierarchy"));
      }
      for (size_t k = 1; k < words.size(); ++k) {
        const std::string child(words[k]);
        if (!skeleton_.bones.count(child)) {
          return error_(Line(), absl::StrCat("unknown bone '", child, "' in :hierarchy"));
        }
        (parent == "root" ? skeleton_.root_children : skeleton_.bones[parent].children)
            .push_back(child);
      }
    }
    return absl::OkStatus();
  }

  LineError error_;
  std::vector<absl::string_view> lines_;
  size_t i_ = 0;
  bool seen_hierarchy_ = false;
  AsfSkeleton skeleton_;
};

// The skeleton as Motion joints (root first, depth first) and, per joint, the
// ASF bone it stands for (nullptr for the root and end joints).
struct JointLayout {
  std::vector<MotionJoint> joints;
  std::vector<const AsfBone*> bones;
  std::set<std::string> added;  // Bones placed so far.
};

absl::Status AddBone(const AsfSkeleton& skeleton, const std::string& name, int parent,
                     const Eigen::Vector3d& offset_m, double metres_per_unit, int depth,
                     const std::string& asf_path, JointLayout& layout) {
  const AsfBone& bone = skeleton.bones.at(name);
  if (!layout.added.insert(name).second) {
    return absl::InvalidArgumentError(
        absl::StrCat(asf_path, ": bone '", name, "' appears twice in :hierarchy"));
  }
  if (depth > kMaxDepth) {
    return absl::InvalidArgumentError(absl::StrCat(asf_path, ":", bone.line, ": bone '", name,
                                                   "' is nested more than ", kMaxDepth,
                                                   " bones deep in :hierarchy"));
  }
  const int index = static_cast<int>(layout.joints.size());
  layout.joints.push_back({name, parent, offset_m});
  layout.bones.push_back(&bone);
  const double norm = bone.direction.norm();
  const Eigen::Vector3d end_m =
      norm > 0 ? Eigen::Vector3d(bone.direction / norm * bone.length_units * metres_per_unit)
               : Eigen::Vector3d::Zero();
  if (bone.children.empty()) {
    layout.joints.push_back({name + "_end", index, end_m});
    layout.bones.push_back(nullptr);
  }
  for (const std::string& child : bone.children) {
    RETURN_IF_ERROR(
        AddBone(skeleton, child, index, end_m, metres_per_unit, depth + 1, asf_path, layout));
  }
  return absl::OkStatus();
}

Eigen::Quaterniond DofRotation(const std::vector<Dof>& dofs, const double* values,
                               double to_radians) {
  Eigen::Quaterniond m = Eigen::Quaterniond::Identity();
  for (size_t k = 0; k < dofs.size(); ++k) {
    const double radians = values[k] * to_radians;
    switch (dofs[k]) {
      case Dof::kRx:
        m = AxisAngle('X', radians) * m;
        break;
      case Dof::kRy:
        m = AxisAngle('Y', radians) * m;
        break;
      case Dof::kRz:
        m = AxisAngle('Z', radians) * m;
        break;
      default:
        break;
    }
  }
  return m;
}

struct AmcFrames {
  std::vector<std::vector<Eigen::Quaterniond>> rotations;  // [frame][joint]
  std::vector<Eigen::Vector3d> root_translations_m;
};

class AmcParser {
 public:
  AmcParser(const std::string& amc_path, const std::string& asf_path, const AsfSkeleton& skeleton,
            const JointLayout& layout, double metres_per_unit)
      : error_(amc_path),
        asf_path_(asf_path),
        skeleton_(skeleton),
        layout_(layout),
        metres_per_unit_(metres_per_unit),
        degrees_(skeleton.degrees) {
    for (size_t j = 0; j < layout.joints.size(); ++j) {
      if (j == 0 || layout.bones[j] != nullptr) joint_of_[layout.joints[j].name] = j;
    }
  }

  absl::StatusOr<AmcFrames> Parse(absl::string_view text) {
    const std::vector<absl::string_view> lines = SplitLines(text);
    int frame_line = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
      const int line = static_cast<int>(i) + 1;
      const std::vector<absl::string_view> words = Words(lines[i]);
      if (words.empty()) continue;
      if (words[0][0] == ':') {
        if (words[0] == ":DEGREES") degrees_ = true;
        if (words[0] == ":RADIANS") degrees_ = false;
        continue;
      }
      int number = 0;
      if (words.size() == 1 && absl::SimpleAtoi(words[0], &number)) {
        if (!frames_.rotations.empty()) RETURN_IF_ERROR(CheckComplete(frame_line));
        // In 64 bits: a first frame numbered near INT_MAX must not overflow.
        if (!frames_.rotations.empty() && number != int64_t{first_number_} + NumFrames()) {
          return error_(line, absl::StrCat("frame number ", number, " out of sequence"));
        }
        if (frames_.rotations.empty()) first_number_ = number;
        if ((frames_.rotations.size() + 1) * std::max<uint64_t>(layout_.joints.size(), 1) >
            kMaxMotionJointFrames) {
          return error_(line, absl::StrCat("more than ", kMaxMotionJointFrames,
                                           " joint poses (frames times bones)"));
        }
        StartFrame();
        frame_line = line;
        continue;
      }
      if (frames_.rotations.empty()) {
        return error_(line, "bone values before the first frame number");
      }
      RETURN_IF_ERROR(ParseBoneLine(line, words));
    }
    if (!frames_.rotations.empty()) RETURN_IF_ERROR(CheckComplete(frame_line));
    return std::move(frames_);
  }

 private:
  int NumFrames() const { return static_cast<int>(frames_.rotations.size()); }

  void StartFrame() {
    frames_.rotations.emplace_back(layout_.joints.size(), Eigen::Quaterniond::Identity());
    frames_.root_translations_m.push_back(skeleton_.root_position_units * metres_per_unit_);
    seen_.assign(layout_.joints.size(), false);
  }

  // Every bone that has degrees of freedom, and the root, must appear in every
  // frame; a missing one means the file was cut short.
  absl::Status CheckComplete(int frame_line) const {
    for (size_t j = 0; j < layout_.joints.size(); ++j) {
      const bool needs_values = j == 0 || (layout_.bones[j] && !layout_.bones[j]->dofs.empty());
      if (needs_values && !seen_[j]) {
        return error_(frame_line, absl::StrCat("frame ", int64_t{first_number_} + NumFrames() - 1,
                                               " lacks bone '", layout_.joints[j].name,
                                               "' (truncated or incomplete frame)"));
      }
    }
    return absl::OkStatus();
  }

  absl::Status ParseBoneLine(int line, const std::vector<absl::string_view>& words) {
    const std::string name(words[0]);
    const auto it = joint_of_.find(name);
    if (it == joint_of_.end()) {
      return error_(line, absl::StrCat("bone '", name, "' is not in the skeleton ", asf_path_));
    }
    const size_t j = it->second;
    if (seen_[j]) return error_(line, absl::StrCat("bone '", name, "' twice in one frame"));
    seen_[j] = true;
    const std::vector<Dof>& dofs = j == 0 ? skeleton_.root_order : layout_.bones[j]->dofs;
    if (words.size() != dofs.size() + 1) {
      return error_(line, absl::StrCat("bone '", name, "' has ", words.size() - 1,
                                       " values, its dof declares ", dofs.size()));
    }
    std::vector<double> values(dofs.size());
    for (size_t k = 0; k < dofs.size(); ++k) {
      ASSIGN_OR_RETURN(values[k], ParseNumber(error_, line, words[k + 1], name));
    }
    const double to_radians = degrees_ ? M_PI / 180.0 : 1.0;
    const Eigen::Quaterniond m = DofRotation(dofs, values.data(), to_radians);
    const Eigen::Quaterniond& c = j == 0 ? skeleton_.root_axis : layout_.bones[j]->axis;
    frames_.rotations.back()[j] = c * m * c.conjugate();  // L = C M C^-1.
    if (j == 0) {
      Eigen::Vector3d translation_units = skeleton_.root_position_units;
      for (size_t k = 0; k < dofs.size(); ++k) {
        const int d = static_cast<int>(dofs[k]);
        if (d <= static_cast<int>(Dof::kTz)) translation_units[d] += values[k];
      }
      frames_.root_translations_m.back() = translation_units * metres_per_unit_;
    }
    return absl::OkStatus();
  }

  LineError error_;
  std::string asf_path_;
  const AsfSkeleton& skeleton_;
  const JointLayout& layout_;
  double metres_per_unit_;
  bool degrees_;
  std::map<std::string, size_t> joint_of_;
  std::vector<bool> seen_;
  int first_number_ = 0;
  AmcFrames frames_;
};

}  // namespace

absl::StatusOr<Motion> ReadAsfAmc(const std::string& asf_path, const std::string& amc_path) {
  return ReadAsfAmc(asf_path, amc_path, AsfAmcOptions{});
}

absl::StatusOr<Motion> ReadAsfAmc(const std::string& asf_path, const std::string& amc_path,
                                  const AsfAmcOptions& options) {
  if (!std::isfinite(options.frames_per_second) || options.frames_per_second <= 0) {
    return absl::InvalidArgumentError("AsfAmcOptions::frames_per_second must be > 0");
  }
  if (!std::isfinite(options.metres_per_unit)) {
    return absl::InvalidArgumentError("AsfAmcOptions::metres_per_unit must be finite");
  }
  ASSIGN_OR_RETURN(const std::string asf_text, ReadFileToString(asf_path, kMaxBvhBytes));
  ASSIGN_OR_RETURN(const std::string amc_text, ReadFileToString(amc_path, kMaxBvhBytes));
  AsfParser asf_parser(asf_path, asf_text);
  ASSIGN_OR_RETURN(const AsfSkeleton skeleton, asf_parser.Parse());

  MotionInfo info;
  info.path = amc_path;
  info.format = "asf/amc";
  info.fps = options.frames_per_second;
  info.metres_per_unit = kMetresPerInch / skeleton.length_multiplier;
  info.unit_source = UnitSource::kAsfHeader;
  if (options.metres_per_unit > 0) {
    info.metres_per_unit = options.metres_per_unit;
    info.unit_source = UnitSource::kGiven;
  }

  JointLayout layout;
  layout.joints.push_back({"root", -1, Eigen::Vector3d::Zero()});
  layout.bones.push_back(nullptr);
  for (const std::string& child : skeleton.root_children) {
    RETURN_IF_ERROR(AddBone(skeleton, child, 0, Eigen::Vector3d::Zero(), info.metres_per_unit,
                            /*depth=*/1, asf_path, layout));
  }

  std::vector<std::string> names;
  std::vector<int> parents;
  for (const MotionJoint& j : layout.joints) {
    names.push_back(j.name);
    parents.push_back(j.parent);
  }
  ASSIGN_OR_RETURN(const JointSetMatch match,
                   MatchJointSet(names, parents, options.joint_map, asf_path));
  info.joint_set = match.set;
  info.joint_map = options.joint_map;

  AmcParser amc_parser(amc_path, asf_path, skeleton, layout, info.metres_per_unit);
  ASSIGN_OR_RETURN(AmcFrames frames, amc_parser.Parse(amc_text));
  info.num_frames = static_cast<int>(frames.rotations.size());
  return Motion(std::move(info), std::move(layout.joints), std::move(frames.rotations),
                std::move(frames.root_translations_m));
}

}  // namespace reenact::body
