// BVH (Biovision Hierarchy) reader. The format: a HIERARCHY section of nested
// ROOT / JOINT / End Site blocks, each with an OFFSET from its parent and (not
// for end sites) a CHANNELS list, then a MOTION section with "Frames: N",
// "Frame Time: t" (seconds) and N lines of channel values, in the order the
// channels were declared, angles in degrees.
//
// Rotation channels compose in the order declared: "Zrotation Xrotation
// Yrotation" gives parent_from_joint rotation R = Rz * Rx * Ry. The root's
// world translation is its OFFSET plus its position channels. Other joints'
// position channels (MakeHuman writes six channels everywhere, zeros for the
// translations) add to their OFFSET and must keep one value through the clip.
//
// Joint names: MatchJointSet (a recognised naming, a user's joint map, or
// both). Up axis: Blender and MakeHuman write Z-up files; when the rest
// pose's spine (SpineBase to the highest of Head, Neck, SpineShoulder) points
// mostly along +Z, every offset and rotation is turned by C = Rx(-90 deg),
// (x, y, z) -> (x, z, -y): offsets o' = C o, rotations R' = C R C^T, root
// translations t' = C t, so that every joint's world position becomes C p.
//
// Length unit: BvhOptions::metres_per_unit when > 0 (UnitSource::kGiven).
// Otherwise it is detected from stature (UnitSource::kDetectedFromStature):
// the rest pose (all rotations identity) is built in file units, its vertical
// extent along +Y, from the highest joint or end site (the top of the head) to
// the lowest (the sole of the lower foot), is taken to be kAssumedStatureM.
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/body/motion.h"

namespace reenact::body {
namespace {

// The largest offset, position or angle a file may hold: 1e6 is 10 km in
// centimetres or thousands of turns in degrees; past it joints overflow to
// infinity once scaled and posed.
constexpr double kMaxMagnitude = 1e6;

// Deepest joint nesting accepted (guards the recursive parser).
constexpr int kMaxDepth = 256;

enum class Channel { kXpos, kYpos, kZpos, kXrot, kYrot, kZrot };

std::optional<Channel> ChannelFromName(absl::string_view name) {
  if (name == "Xposition") return Channel::kXpos;
  if (name == "Yposition") return Channel::kYpos;
  if (name == "Zposition") return Channel::kZpos;
  if (name == "Xrotation") return Channel::kXrot;
  if (name == "Yrotation") return Channel::kYrot;
  if (name == "Zrotation") return Channel::kZrot;
  return std::nullopt;
}

bool IsRotation(Channel c) {
  return c == Channel::kXrot || c == Channel::kYrot || c == Channel::kZrot;
}

struct Token {
  absl::string_view text;
  int line = 0;
};

struct BvhJoint {
  std::string name;
  int parent = -1;
  Eigen::Vector3d offset_units{0, 0, 0};
  std::vector<Channel> channels;
  int first_channel = 0;  // Column of its first channel in a frame line.
  int channels_line = 0;  // Line of its CHANNELS keyword.
};

// Splits `text` into lines (without '\r' or '\n'); line i is numbered i + 1.
std::vector<absl::string_view> SplitLines(absl::string_view text) {
  std::vector<absl::string_view> lines = absl::StrSplit(text, '\n');
  for (absl::string_view& line : lines) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  }
  if (lines.size() > 1 && lines.back().empty()) lines.pop_back();  // Final newline.
  return lines;
}

std::vector<absl::string_view> SplitWords(absl::string_view line) {
  return absl::StrSplit(line, absl::ByAnyChar(" \t"), absl::SkipEmpty());
}

class BvhParser {
 public:
  BvhParser(std::string path, absl::string_view text) : path_(std::move(path)) {
    lines_ = SplitLines(text);
  }

  absl::Status Parse() {
    RETURN_IF_ERROR(TokenizeHierarchy());
    RETURN_IF_ERROR(ParseHierarchy());
    return ParseMotion();
  }

  const std::vector<BvhJoint>& joints() const { return joints_; }
  int num_channels() const { return num_channels_; }
  int num_frames() const { return num_frames_; }
  double frame_time_s() const { return frame_time_s_; }
  const std::vector<double>& values() const { return values_; }

 private:
  absl::Status Error(int line, absl::string_view message) const {
    return absl::InvalidArgumentError(absl::StrCat(path_, ":", line, ": ", message));
  }

  int LastLine() const { return static_cast<int>(lines_.size()); }

  // Tokens of every line before the one that starts with MOTION.
  absl::Status TokenizeHierarchy() {
    for (size_t i = 0; i < lines_.size(); ++i) {
      const std::vector<absl::string_view> words = SplitWords(lines_[i]);
      if (!words.empty() && words[0] == "MOTION") {
        motion_line_ = static_cast<int>(i);
        return absl::OkStatus();
      }
      for (absl::string_view w : words) tokens_.push_back({w, static_cast<int>(i) + 1});
    }
    return Error(LastLine(), "no MOTION section");
  }

  const Token* Next() { return pos_ < tokens_.size() ? &tokens_[pos_++] : nullptr; }

  int CurrentLine() const {
    if (pos_ < tokens_.size()) return tokens_[pos_].line;
    return motion_line_ + 1;  // Tokens ran out: report the MOTION line.
  }

  absl::Status Expect(absl::string_view word) {
    const Token* t = Next();
    if (t == nullptr) {
      return Error(CurrentLine(), absl::StrCat("expected '", word, "' before MOTION"));
    }
    if (t->text != word) {
      return Error(t->line, absl::StrCat("expected '", word, "', found '", t->text, "'"));
    }
    return absl::OkStatus();
  }

  absl::StatusOr<double> Number(const Token* t, absl::string_view what) {
    if (t == nullptr) return Error(CurrentLine(), absl::StrCat("missing ", what));
    double value = 0.0;
    if (!absl::SimpleAtod(t->text, &value) || !std::isfinite(value)) {
      return Error(t->line, absl::StrCat("bad number '", t->text, "' for ", what));
    }
    if (std::abs(value) > kMaxMagnitude) {
      return Error(t->line, absl::StrCat("number '", t->text, "' for ", what,
                                         " is out of range (|x| <= 1e6)"));
    }
    return value;
  }

  absl::StatusOr<Eigen::Vector3d> Offset() {
    RETURN_IF_ERROR(Expect("OFFSET"));
    Eigen::Vector3d offset;
    for (int k = 0; k < 3; ++k) {
      ASSIGN_OR_RETURN(offset[k], Number(Next(), "OFFSET"));
    }
    return offset;
  }

  absl::Status Channels(BvhJoint& joint) {
    RETURN_IF_ERROR(Expect("CHANNELS"));
    joint.channels_line = tokens_[pos_ - 1].line;
    const Token* count_token = Next();
    ASSIGN_OR_RETURN(const double count, Number(count_token, "the CHANNELS count"));
    if (count < 0 || count > 6 || count != std::floor(count)) {
      return Error(count_token->line, absl::StrCat("bad CHANNELS count ", count_token->text));
    }
    joint.first_channel = num_channels_;
    for (int k = 0; k < static_cast<int>(count); ++k) {
      const Token* t = Next();
      if (t == nullptr) return Error(CurrentLine(), "CHANNELS list ends early");
      const std::optional<Channel> channel = ChannelFromName(t->text);
      if (!channel) return Error(t->line, absl::StrCat("unknown channel '", t->text, "'"));
      joint.channels.push_back(*channel);
    }
    num_channels_ += static_cast<int>(count);
    return absl::OkStatus();
  }

  absl::Status ParseHierarchy() {
    RETURN_IF_ERROR(Expect("HIERARCHY"));
    RETURN_IF_ERROR(Expect("ROOT"));
    RETURN_IF_ERROR(ParseJoint(-1, 0));
    if (pos_ < tokens_.size()) {
      return Error(tokens_[pos_].line,
                   absl::StrCat("unexpected '", tokens_[pos_].text, "' after the ROOT block"));
    }
    return absl::OkStatus();
  }

  // Parses "name { OFFSET ... CHANNELS ... children }" after ROOT or JOINT.
  absl::Status ParseJoint(int parent, int depth) {
    if (depth > kMaxDepth) return Error(CurrentLine(), "joints nested too deeply");
    const Token* name = Next();
    if (name == nullptr || name->text == "{") return Error(CurrentLine(), "missing joint name");
    BvhJoint joint;
    joint.name = std::string(name->text);
    joint.parent = parent;
    RETURN_IF_ERROR(Expect("{"));
    ASSIGN_OR_RETURN(joint.offset_units, Offset());
    RETURN_IF_ERROR(Channels(joint));
    const int index = static_cast<int>(joints_.size());
    joints_.push_back(std::move(joint));
    while (true) {
      const Token* t = Next();
      if (t == nullptr) {
        return Error(CurrentLine(),
                     absl::StrCat("missing '}' closing joint '", joints_[index].name, "'"));
      }
      if (t->text == "}") return absl::OkStatus();
      if (t->text == "JOINT") {
        RETURN_IF_ERROR(ParseJoint(index, depth + 1));
      } else if (t->text == "End") {
        RETURN_IF_ERROR(ParseEndSite(index));
      } else {
        return Error(t->line,
                     absl::StrCat("expected JOINT, End Site or '}', found '", t->text, "'"));
      }
    }
  }

  absl::Status ParseEndSite(int parent) {
    RETURN_IF_ERROR(Expect("Site"));
    RETURN_IF_ERROR(Expect("{"));
    BvhJoint end;
    end.name = joints_[parent].name + "_end";
    end.parent = parent;
    end.first_channel = num_channels_;
    ASSIGN_OR_RETURN(end.offset_units, Offset());
    RETURN_IF_ERROR(Expect("}"));
    joints_.push_back(std::move(end));
    return absl::OkStatus();
  }

  // "Frames: N", "Frame Time: t", then N lines of num_channels_ values.
  absl::Status ParseMotion() {
    size_t i = static_cast<size_t>(motion_line_) + 1;
    auto next_words = [&]() {
      std::vector<absl::string_view> words;
      while (i < lines_.size() && (words = SplitWords(lines_[i])).empty()) ++i;
      return words;
    };
    std::vector<absl::string_view> words = next_words();
    if (words.size() != 2 || words[0] != "Frames:" || !absl::SimpleAtoi(words[1], &num_frames_) ||
        num_frames_ < 0) {
      return Error(static_cast<int>(std::min(i, lines_.size() - 1)) + 1,
                   "expected 'Frames: N' after MOTION");
    }
    if (static_cast<uint64_t>(num_frames_) * std::max<uint64_t>(joints_.size(), 1) >
        kMaxMotionJointFrames) {
      return Error(static_cast<int>(i) + 1,
                   absl::StrCat(num_frames_, " frames of ", joints_.size(), " joints exceed the ",
                                kMaxMotionJointFrames, " joint poses a motion may hold"));
    }
    ++i;
    words = next_words();
    if (words.size() != 3 || words[0] != "Frame" || words[1] != "Time:" ||
        !absl::SimpleAtod(words[2], &frame_time_s_) || !std::isfinite(frame_time_s_) ||
        frame_time_s_ <= 0) {
      return Error(static_cast<int>(std::min(i, lines_.size() - 1)) + 1,
                   "expected 'Frame Time: seconds' (> 0) after Frames");
    }
    ++i;
    // A frame takes a line: never reserve more than the lines left (a hostile
    // "Frames:" count must not allocate).
    const size_t frames_possible = std::min(static_cast<size_t>(num_frames_), lines_.size() - i);
    values_.reserve(frames_possible * static_cast<size_t>(num_channels_));
    int frame = 0;
    for (; i < lines_.size(); ++i) {
      words = SplitWords(lines_[i]);
      if (words.empty()) continue;
      const int line = static_cast<int>(i) + 1;
      if (frame >= num_frames_) {
        return Error(line, absl::StrCat("more frame lines than the ", num_frames_,
                                        " that 'Frames:' declares"));
      }
      if (static_cast<int>(words.size()) != num_channels_) {
        return Error(line,
                     absl::StrCat("frame ", frame, " has ", words.size(),
                                  " values, the hierarchy declares ", num_channels_, " channels"));
      }
      for (absl::string_view w : words) {
        double value = 0.0;
        if (!absl::SimpleAtod(w, &value) || !std::isfinite(value)) {
          return Error(line, absl::StrCat("bad number '", w, "' in frame ", frame));
        }
        if (std::abs(value) > kMaxMagnitude) {
          return Error(line, absl::StrCat("number '", w, "' in frame ", frame,
                                          " is out of range (|x| <= 1e6)"));
        }
        values_.push_back(value);
      }
      ++frame;
    }
    if (frame < num_frames_) {
      return Error(LastLine(), absl::StrCat("truncated motion: 'Frames:' declares ", num_frames_,
                                            " frames, the file holds ", frame));
    }
    return absl::OkStatus();
  }

  std::string path_;
  std::vector<absl::string_view> lines_;
  std::vector<Token> tokens_;
  size_t pos_ = 0;
  int motion_line_ = 0;  // 0-based index of the MOTION line.
  std::vector<BvhJoint> joints_;
  int num_channels_ = 0;
  int num_frames_ = 0;
  double frame_time_s_ = 0.0;
  std::vector<double> values_;  // [frame * num_channels_ + column]
};

Eigen::Quaterniond AxisRotation(Channel c, double degrees) {
  const double radians = degrees * M_PI / 180.0;
  switch (c) {
    case Channel::kXrot:
      return Eigen::Quaterniond(Eigen::AngleAxisd(radians, Eigen::Vector3d::UnitX()));
    case Channel::kYrot:
      return Eigen::Quaterniond(Eigen::AngleAxisd(radians, Eigen::Vector3d::UnitY()));
    case Channel::kZrot:
      return Eigen::Quaterniond(Eigen::AngleAxisd(radians, Eigen::Vector3d::UnitZ()));
    default:
      return Eigen::Quaterniond::Identity();
  }
}

// Rest positions (file units) of every joint: offsets summed down the tree.
std::vector<Eigen::Vector3d> RestPositionsUnits(const std::vector<BvhJoint>& joints) {
  std::vector<Eigen::Vector3d> position(joints.size(), Eigen::Vector3d::Zero());
  for (size_t j = 0; j < joints.size(); ++j) {
    if (joints[j].parent >= 0) {
      position[j] = position[static_cast<size_t>(joints[j].parent)] + joints[j].offset_units;
    }
  }
  return position;
}

// Vertical extent (file units) of the rest pose: highest minus lowest joint.
double RestHeightUnits(const std::vector<BvhJoint>& joints) {
  double min_y = 0.0;
  double max_y = 0.0;
  for (const Eigen::Vector3d& p : RestPositionsUnits(joints)) {
    min_y = std::min(min_y, p.y());
    max_y = std::max(max_y, p.y());
  }
  return max_y - min_y;
}

// Value of channel `c` of `joint` at `frame`.
double ChannelValue(const BvhParser& parser, const BvhJoint& joint, size_t c, int frame) {
  return parser.values()[static_cast<size_t>(frame) * static_cast<size_t>(parser.num_channels()) +
                         static_cast<size_t>(joint.first_channel) + c];
}

// Adds the position channels of every joint but the root to its offset; an
// error when one changes by more than a thousandth of the rest height.
absl::Status FoldJointTranslations(const std::string& path, const BvhParser& parser,
                                   std::vector<BvhJoint>& joints) {
  const double tolerance_units = 1e-3 * RestHeightUnits(joints);
  for (size_t j = 1; j < joints.size(); ++j) {
    BvhJoint& joint = joints[j];
    for (size_t c = 0; c < joint.channels.size(); ++c) {
      if (IsRotation(joint.channels[c]) || parser.num_frames() == 0) continue;
      const double first = ChannelValue(parser, joint, c, 0);
      for (int f = 1; f < parser.num_frames(); ++f) {
        if (std::abs(ChannelValue(parser, joint, c, f) - first) > tolerance_units) {
          return absl::InvalidArgumentError(
              absl::StrCat(path, ":", joint.channels_line, ": joint '", joint.name,
                           "' translates during the clip (frame ", f,
                           "); only the root may move, bones that stretch are not supported"));
        }
      }
      joint.offset_units[static_cast<int>(joint.channels[c]) - static_cast<int>(Channel::kXpos)] +=
          first;
    }
  }
  return absl::OkStatus();
}

// C = Rx(-90 deg): file (x, y, z) -> (x, z, -y).
Eigen::Matrix3d YUpFromZUp() {
  Eigen::Matrix3d c;
  c << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return c;
}

// Whether the rest pose's spine points mostly along +Z: from SpineBase to the
// highest-ranked of Head, Neck, SpineShoulder that the match places.
bool IsZUp(const std::vector<BvhJoint>& joints, const CanonicalSources& sources) {
  const std::vector<Eigen::Vector3d> rest = RestPositionsUnits(joints);
  const auto at = [&](KinectV2Joint joint) -> std::optional<Eigen::Vector3d> {
    const CanonicalSource& s = sources[static_cast<size_t>(Index(joint))];
    if (s.joint < 0) return std::nullopt;
    Eigen::Vector3d p = rest[static_cast<size_t>(s.joint)];
    if (s.toward >= 0) p += s.fraction * joints[static_cast<size_t>(s.toward)].offset_units;
    return p;
  };
  const std::optional<Eigen::Vector3d> base = at(KinectV2Joint::kSpineBase);
  if (!base) return false;
  for (KinectV2Joint top :
       {KinectV2Joint::kHead, KinectV2Joint::kNeck, KinectV2Joint::kSpineShoulder}) {
    if (const std::optional<Eigen::Vector3d> p = at(top)) {
      const Eigen::Vector3d up = *p - *base;
      return up.z() > std::abs(up.y()) && up.z() > std::abs(up.x());
    }
  }
  return false;
}

// The file's length unit: given, or the rest pose's height taken as
// kAssumedStatureM.
absl::Status SetUnit(const std::string& path, const std::vector<BvhJoint>& joints,
                     const BvhOptions& options, MotionInfo& info) {
  if (options.metres_per_unit > 0) {
    info.metres_per_unit = options.metres_per_unit;
    info.unit_source = UnitSource::kGiven;
    return absl::OkStatus();
  }
  const double height_units = RestHeightUnits(joints);
  if (!(height_units > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat(path,
                     ": the rest pose has no height along +Y, so its length unit cannot be "
                     "detected; give it explicitly"));
  }
  info.metres_per_unit = kAssumedStatureM / height_units;
  info.unit_source = UnitSource::kDetectedFromStature;
  return absl::OkStatus();
}

// Local rotations of every frame and the root's translations (metres), turned
// by `turn` (identity, or YUpFromZUp for a Z-up file).
struct BvhFrames {
  std::vector<std::vector<Eigen::Quaterniond>> rotations;  // [frame][joint]
  std::vector<Eigen::Vector3d> root_translations_m;        // [frame]
};

BvhFrames ComputeFrames(const BvhParser& parser, const std::vector<BvhJoint>& joints,
                        const Eigen::Matrix3d& turn, double metres_per_unit) {
  const int num_frames = parser.num_frames();
  const Eigen::Quaterniond turn_q(turn);
  BvhFrames frames;
  frames.rotations.assign(static_cast<size_t>(num_frames),
                          std::vector<Eigen::Quaterniond>(joints.size()));
  frames.root_translations_m.resize(static_cast<size_t>(num_frames));
  for (int f = 0; f < num_frames; ++f) {
    Eigen::Vector3d root_units = joints[0].offset_units;
    for (size_t j = 0; j < joints.size(); ++j) {
      Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
      for (size_t c = 0; c < joints[j].channels.size(); ++c) {
        const double value = ChannelValue(parser, joints[j], c, f);
        const Channel channel = joints[j].channels[c];
        if (IsRotation(channel)) {
          rotation = rotation * AxisRotation(channel, value);
        } else if (j == 0) {
          root_units[static_cast<int>(channel) - static_cast<int>(Channel::kXpos)] += value;
        }
      }
      frames.rotations[static_cast<size_t>(f)][j] = turn_q * rotation * turn_q.conjugate();
    }
    frames.root_translations_m[static_cast<size_t>(f)] = turn * root_units * metres_per_unit;
  }
  return frames;
}

}  // namespace

absl::StatusOr<Motion> ReadBvh(const std::string& path, const BvhOptions& options) {
  if (!std::isfinite(options.metres_per_unit)) {
    return absl::InvalidArgumentError("BvhOptions::metres_per_unit must be finite");
  }
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, kMaxBvhBytes));
  BvhParser parser(path, text);
  RETURN_IF_ERROR(parser.Parse());
  std::vector<BvhJoint> bvh_joints = parser.joints();
  RETURN_IF_ERROR(FoldJointTranslations(path, parser, bvh_joints));

  std::vector<std::string> names;
  std::vector<int> parents;
  for (const BvhJoint& j : bvh_joints) {
    names.push_back(j.name);
    parents.push_back(j.parent);
  }
  ASSIGN_OR_RETURN(const JointSetMatch match,
                   MatchJointSet(names, parents, options.joint_map, path));

  MotionInfo info;
  info.path = path;
  info.format = "bvh";
  info.num_frames = parser.num_frames();
  info.fps = 1.0 / parser.frame_time_s();
  info.joint_set = match.set;
  info.joint_map = options.joint_map;
  info.turned_from_z_up = IsZUp(bvh_joints, match.sources);
  const Eigen::Matrix3d turn =
      info.turned_from_z_up ? YUpFromZUp() : Eigen::Matrix3d(Eigen::Matrix3d::Identity());
  for (BvhJoint& joint : bvh_joints) joint.offset_units = turn * joint.offset_units;
  RETURN_IF_ERROR(SetUnit(path, bvh_joints, options, info));

  std::vector<MotionJoint> joints;
  joints.reserve(bvh_joints.size());
  for (const BvhJoint& j : bvh_joints) {
    joints.push_back({j.name, j.parent, j.offset_units * info.metres_per_unit});
  }
  BvhFrames frames = ComputeFrames(parser, bvh_joints, turn, info.metres_per_unit);
  return Motion(std::move(info), std::move(joints), std::move(frames.rotations),
                std::move(frames.root_translations_m));
}

}  // namespace reenact::body
