// `reenact motion info` and `reenact motion joints`: a BVH or ASF/AMC motion
// as the tool sees it (frames, rate, joints, length unit) and the canonical
// (Kinect v2) joint positions of one frame, in metres. Both take --joint-map
// FILE (JSON: their joint name -> Kinect v2 joint name) and --metres-per-unit
// X (overrides the detected or declared length unit).
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iomanip>
#include <optional>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
#include "common/body/motion.h"

namespace reenact::cli {
namespace {

// FILE and --asf from parsed flags; a usage error when FILE is missing or an
// AMC motion comes without its skeleton.
absl::Status CheckMotionArgs(const Flags& flags) {
  if (flags.positional().size() != 1) {
    return absl::InvalidArgumentError("expected exactly one motion FILE (.bvh or .amc)");
  }
  const std::string& path = flags.positional()[0];
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".amc" && flags.GetOr("asf", "").empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": an AMC motion needs --asf SKELETON"));
  }
  if (extension != ".amc" && extension != ".bvh") {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": unknown motion format (expected .bvh, or .amc with --asf)"));
  }
  return absl::OkStatus();
}

// --metres-per-unit from parsed flags: 0 (the file's own unit) when absent.
absl::StatusOr<double> MetresPerUnitFlag(const Flags& flags) {
  absl::StatusOr<double> metres_per_unit = flags.GetDouble("metres-per-unit", 0.0);
  if (!metres_per_unit.ok()) return metres_per_unit.status();
  if (flags.Has("metres-per-unit") && !(*metres_per_unit > 0)) {
    return absl::InvalidArgumentError("--metres-per-unit must be a length > 0 (metres)");
  }
  body::MotionReadOptions options;
  options.metres_per_unit = *metres_per_unit;
  if (absl::Status status = options.Validate(); !status.ok()) return status;
  return *metres_per_unit;
}

// Reads the motion named by the flags; prints the error and sets `exit_code`
// (usage 2 or failure 1) when that fails.
std::optional<body::Motion> LoadMotion(const Flags& flags, std::ostream& err, int& exit_code) {
  absl::Status status = CheckMotionArgs(flags);
  absl::StatusOr<double> metres_per_unit = MetresPerUnitFlag(flags);
  if (status.ok()) status = metres_per_unit.status();
  if (!status.ok()) {
    exit_code = ReportError(status, err);
    return std::nullopt;
  }
  body::MotionReadOptions options;
  options.asf_path = flags.GetOr("asf", "");
  options.metres_per_unit = *metres_per_unit;
  if (const std::optional<std::string> map_path = flags.Get("joint-map")) {
    absl::StatusOr<std::vector<body::JointMapping>> joint_map = body::ReadJointMap(*map_path);
    if (!joint_map.ok()) {
      // A joint map that cannot be read or parsed is bad input, as a motion is.
      err << "reenact: --joint-map: " << joint_map.status().message() << "\n";
      exit_code = kExitFailure;
      return std::nullopt;
    }
    options.joint_map = std::move(joint_map).value();
  }
  absl::StatusOr<body::Motion> motion = body::ReadMotion(flags.positional()[0], options);
  if (!motion.ok()) {
    // A file that cannot be read or parsed is a failure, not a usage error.
    err << "reenact: " << motion.status().message() << "\n";
    exit_code = kExitFailure;
    return std::nullopt;
  }
  return std::move(motion).value();
}

// Height of the rest pose (all rotations identity), metres: highest joint
// or end site minus lowest, the stature the length unit gives the skeleton.
double RestHeightM(const body::Motion& motion) {
  double top = 0.0;
  double bottom = 0.0;
  for (const Eigen::Isometry3d& world_from_joint : motion.RestWorldFromJoints()) {
    top = std::max(top, world_from_joint.translation().y());
    bottom = std::min(bottom, world_from_joint.translation().y());
  }
  return top - bottom;
}

nlohmann::json InfoJson(const body::Motion& motion, const Flags& flags) {
  const body::MotionInfo& info = motion.info();
  nlohmann::json names = nlohmann::json::array();
  for (const body::MotionJoint& joint : motion.joints()) names.push_back(joint.name);
  nlohmann::json joint_map = nullptr;
  if (flags.Has("joint-map")) {
    joint_map = {{"file", flags.GetOr("joint-map", "")}, {"entries", info.joint_map.size()}};
  }
  int canonical_joints = 0;
  for (int source : motion.canonical_to_source()) canonical_joints += source >= 0 ? 1 : 0;
  return {
      {"file", info.path},
      {"format", info.format},
      {"frames", info.num_frames},
      {"fps", info.fps},
      {"duration_s", info.fps > 0 ? info.num_frames / info.fps : 0.0},
      {"joint_count", motion.joints().size()},
      {"joints", names},
      {"joint_set", std::string(body::JointSetName(info.joint_set))},
      {"joint_map", joint_map},
      {"kinect_joints", canonical_joints},
      {"metres_per_unit", info.metres_per_unit},
      {"unit_source", std::string(body::UnitSourceName(info.unit_source))},
      {"rest_height_m", RestHeightM(motion)},
      {"turned_from_z_up", info.turned_from_z_up},
  };
}

// How the length unit was set, for the text report.
std::string UnitExplanation(const nlohmann::json& info) {
  const std::string source = info["unit_source"].get<std::string>();
  const double height_m = info["rest_height_m"].get<double>();
  if (source == "detected_from_stature") {
    return absl::StrCat(source, ": the rest pose, ",
                        height_m / info["metres_per_unit"].get<double>(), " units tall, taken as ",
                        body::kAssumedStatureM, " m; --metres-per-unit overrides");
  }
  return absl::StrCat(source, "; rest pose ", height_m, " m tall");
}

void PrintInfoText(const nlohmann::json& info, std::ostream& out) {
  out << "file:            " << info["file"].get<std::string>() << "\n"
      << "format:          " << info["format"].get<std::string>() << "\n"
      << "frames:          " << info["frames"].get<int>() << "\n"
      << "fps:             " << info["fps"].get<double>() << "\n"
      << "duration:        " << info["duration_s"].get<double>() << " s\n"
      << "joint set:       " << info["joint_set"].get<std::string>() << " ("
      << info["kinect_joints"].get<int>() << " of " << body::kNumKinectV2Joints
      << " Kinect v2 joints)\n";
  if (!info["joint_map"].is_null()) {
    out << "joint map:       " << info["joint_map"]["file"].get<std::string>() << " ("
        << info["joint_map"]["entries"].get<int>() << " entries)\n";
  }
  out << "metres per unit: " << info["metres_per_unit"].get<double>() << " ("
      << UnitExplanation(info) << ")\n"
      << "up axis:         "
      << (info["turned_from_z_up"].get<bool>() ? "+Z in the file, turned to +Y" : "+Y") << "\n"
      << "joints (" << info["joint_count"].get<int>() << "):";
  for (const auto& name : info["joints"]) out << " " << name.get<std::string>();
  out << "\n";
}

}  // namespace

int RunMotionInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  absl::StatusOr<Flags> flags =
      Flags::Parse(args, {"asf", "joint-map", "metres-per-unit"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  int exit_code = kExitOk;
  const std::optional<body::Motion> motion = LoadMotion(*flags, err, exit_code);
  if (!motion) return exit_code;
  const nlohmann::json info = InfoJson(*motion, *flags);
  if (flags->Has("json")) {
    out << info.dump(2) << "\n";
  } else {
    PrintInfoText(info, out);
  }
  return kExitOk;
}

int RunMotionJoints(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  absl::StatusOr<Flags> flags =
      Flags::Parse(args, {"asf", "frame", "joint-map", "metres-per-unit"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->Has("frame"))
    return ReportError(absl::InvalidArgumentError("--frame N is required"), err);
  absl::StatusOr<int> frame = flags->GetInt("frame", 0);
  if (!frame.ok()) return ReportError(frame.status(), err);
  int exit_code = kExitOk;
  const std::optional<body::Motion> motion = LoadMotion(*flags, err, exit_code);
  if (!motion) return exit_code;
  if (*frame < 0 || *frame >= motion->num_frames()) {
    return ReportError(absl::InvalidArgumentError(absl::StrCat(
                           "--frame ", *frame, " is out of range: ", motion->info().path, " has ",
                           motion->num_frames(), " frames (0 to ", motion->num_frames() - 1, ")")),
                       err);
  }
  const body::SkeletonPose pose = motion->CanonicalPose(*frame);
  nlohmann::json joints = nlohmann::json::object();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!pose.valid[static_cast<size_t>(j)]) continue;
    const Eigen::Vector3d& p = pose.position_m[static_cast<size_t>(j)];
    joints[std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)))] = {
        p.x(), p.y(), p.z()};
  }
  if (flags->Has("json")) {
    const nlohmann::json result = {
        {"file", motion->info().path}, {"frame", *frame}, {"units", "m"}, {"joints", joints}};
    out << result.dump(2) << "\n";
    return kExitOk;
  }
  out << "frame " << *frame << " of " << motion->info().path << " (metres, Kinect v2 joints)\n";
  out << std::fixed << std::setprecision(4);
  for (const auto& [name, xyz] : joints.items()) {
    out << std::left << std::setw(15) << name << std::right << std::setw(10) << xyz[0].get<double>()
        << std::setw(10) << xyz[1].get<double>() << std::setw(10) << xyz[2].get<double>() << "\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
