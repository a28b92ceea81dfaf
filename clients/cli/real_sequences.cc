#include "clients/cli/real_sequences.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/commands.h"
#include "common/base/image.h"
#include "common/base/status_macros.h"
#include "common/geometry/camera.h"

namespace reenact::cli {

namespace fs = std::filesystem;
using body::KinectV2Joint;

namespace {
constexpr int kJoints = body::kNumKinectV2Joints;
// meta.json files above this are refused before they are read.
constexpr uintmax_t kMaxMetaBytes = 256u << 20;
}  // namespace

std::optional<int> RefJointIndex(const std::string& name) {
  // Kinect v1 names that differ from Kinect v2's.
  static const std::map<std::string, std::string> kV1 = {
      {"ShoulderCenter", "SpineShoulder"}, {"Spine", "SpineMid"}, {"HipCenter", "SpineBase"}};
  const auto v1 = kV1.find(name);
  const std::string& v2 = v1 == kV1.end() ? name : v1->second;
  for (int j = 0; j < kJoints; ++j) {
    if (body::KinectV2JointName(static_cast<KinectV2Joint>(j)) == v2) return j;
  }
  return std::nullopt;
}

namespace {

absl::StatusOr<std::array<double, 4>> ReadIntrinsics(const nlohmann::json& j,
                                                     const std::string& where) {
  if (!j.is_array() || j.size() != 4) {
    return absl::InvalidArgumentError(where + ": intrinsics must be [fx, fy, cx, cy]");
  }
  std::array<double, 4> k{};
  for (int i = 0; i < 4; ++i) {
    if (!j[i].is_number()) return absl::InvalidArgumentError(where + ": intrinsics not numbers");
    k[i] = j[i].get<double>();
    if (!std::isfinite(k[i])) return absl::InvalidArgumentError(where + ": intrinsics not finite");
  }
  if (!(k[0] > 0 && k[1] > 0)) {
    return absl::InvalidArgumentError(where + ": focal lengths must be positive");
  }
  return k;
}

std::optional<Eigen::Vector3d> ReadPoint(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 3) return std::nullopt;
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) {
    if (!j[i].is_number()) return std::nullopt;
    p[i] = j[i].get<double>();
  }
  if (!p.allFinite() || !(p.z() > 0.05)) return std::nullopt;
  return p;
}

}  // namespace

absl::StatusOr<RefSequence> ReadRefSequence(const fs::path& folder) {
  const fs::path meta_path = folder / "meta.json";
  std::error_code ec;
  const uintmax_t size = fs::file_size(meta_path, ec);
  if (ec) return absl::NotFoundError(absl::StrCat("no ", meta_path.string()));
  if (size > kMaxMetaBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat(meta_path.string(), " is larger than ", kMaxMetaBytes >> 20, " MiB"));
  }
  std::ifstream in(meta_path);
  nlohmann::json meta = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (meta.is_discarded() || !meta.is_object()) {
    return absl::DataLossError(absl::StrCat(meta_path.string(), " is not JSON"));
  }
  RefSequence seq;
  seq.folder = folder.string();
  seq.name = folder.filename().string();
  if (seq.name.empty()) seq.name = folder.parent_path().filename().string();
  if (meta.contains("intrinsics")) {
    ASSIGN_OR_RETURN(seq.intrinsics, ReadIntrinsics(meta["intrinsics"], meta_path.string()));
  }
  const nlohmann::json& frames = meta["frames"];
  if (!frames.is_array()) {
    return absl::InvalidArgumentError(absl::StrCat(meta_path.string(), " has no frames"));
  }
  std::vector<std::string> names;
  if (meta.contains("joint_names") && meta["joint_names"].is_array()) {
    for (const auto& n : meta["joint_names"])
      names.push_back(n.is_string() ? n.get<std::string>() : "");
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    const nlohmann::json& f = frames[i];
    const std::string where = absl::StrCat(meta_path.string(), " frame ", i);
    if (!f.is_object() || !f.contains("depth") || !f["depth"].is_string()) {
      return absl::InvalidArgumentError(where + ": no depth file");
    }
    RefFrame frame;
    frame.index = static_cast<int>(i);
    const std::string rel = f["depth"].get<std::string>();
    if (rel.empty() || fs::path(rel).is_absolute() || rel.find("..") != std::string::npos) {
      return absl::InvalidArgumentError(where + ": depth must be a path inside the folder");
    }
    frame.depth_path = (folder / rel).string();
    if (f.contains("intrinsics")) {
      ASSIGN_OR_RETURN(frame.intrinsics, ReadIntrinsics(f["intrinsics"], where));
    } else if (!seq.intrinsics) {
      return absl::InvalidArgumentError(where + ": no intrinsics for the frame or the sequence");
    }
    if (f.contains("joints_m")) {
      const nlohmann::json& jm = f["joints_m"];
      if (jm.is_object()) {
        for (const auto& [name, value] : jm.items()) {
          if (const auto j = RefJointIndex(name)) frame.joints[*j] = ReadPoint(value);
        }
      } else if (jm.is_array()) {
        for (size_t k = 0; k < jm.size() && k < names.size(); ++k) {
          if (const auto j = RefJointIndex(names[k])) frame.joints[*j] = ReadPoint(jm[k]);
        }
      }
    }
    seq.frames.push_back(std::move(frame));
  }
  const auto text = [&](const char* key) {
    return meta.contains(key) && meta[key].is_string() ? meta[key].get<std::string>() : "";
  };
  const auto integer = [&](const char* key) {
    return meta.contains(key) && meta[key].is_number_integer() ? meta[key].get<int>() : 0;
  };
  seq.dataset = text("dataset");
  seq.action = text("action");
  seq.action_id = integer("action_id");
  seq.subject = integer("subject");
  seq.trial = integer("trial");
  if (meta.contains("fps_nominal") && meta["fps_nominal"].is_number()) {
    const double fps = meta["fps_nominal"].get<double>();
    if (std::isfinite(fps) && fps > 0 && fps <= 1000) seq.fps = fps;
  }
  return seq;
}

// The sequences under `dir`: `dir` itself when it holds meta.json, else its
// sub-folders that do (sorted by name), kept when their name contains one
// of `filters` (all when empty).
std::vector<fs::path> RefSequenceFolders(const fs::path& dir,
                                         const std::vector<std::string>& filters) {
  std::error_code ec;
  if (fs::is_regular_file(dir / "meta.json", ec)) return {dir};
  std::vector<fs::path> folders;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (!entry.is_directory(ec) || !fs::is_regular_file(entry.path() / "meta.json", ec)) continue;
    const std::string name = entry.path().filename().string();
    bool keep = filters.empty();
    for (const std::string& f : filters) keep |= name.find(f) != std::string::npos;
    if (keep) folders.push_back(entry.path());
  }
  std::sort(folders.begin(), folders.end());
  return folders;
}

absl::StatusOr<std::vector<TrackedRefFrame>> TrackRefSequence(tracking::BodyTracker& tracker,
                                                              const RefSequence& seq, bool history,
                                                              bool own_segmentation) {
  std::vector<TrackedRefFrame> tracked;
  tracked.reserve(seq.frames.size());
  tracker.Reset();
  for (const RefFrame& frame : seq.frames) {
    absl::StatusOr<DepthImageMm> depth = ReadPngDepth(frame.depth_path);
    if (!depth.ok()) return depth.status();
    const std::array<double, 4> kv = frame.intrinsics ? *frame.intrinsics : *seq.intrinsics;
    CameraIntrinsics k;
    k.width = depth->width, k.height = depth->height;
    k.fx = kv[0], k.fy = kv[1], k.cx = kv[2], k.cy = kv[3];
    // The folder's own background removal marks the person, unless the
    // tracker is asked to find people itself.
    MaskImage labels(depth->width, depth->height);
    for (size_t i = 0; i < labels.data.size(); ++i) labels.data[i] = depth->data[i] != 0;
    if (!history) tracker.Reset();
    const auto start = std::chrono::steady_clock::now();
    absl::StatusOr<std::vector<tracking::TrackedPerson>> people =
        tracker.Track(*depth, k, own_segmentation ? nullptr : &labels);
    TrackedRefFrame out;
    out.track_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (!people.ok()) {
      return absl::Status(people.status().code(),
                          absl::StrCat(frame.depth_path, ": ", people.status().message()));
    }
    for (tracking::TrackedPerson& p : *people) {
      if (!out.person || p.num_pixels > out.person->num_pixels) out.person = std::move(p);
    }
    tracked.push_back(std::move(out));
  }
  return tracked;
}

std::vector<mirror::GradeFrame> SdkGradeFrames(const RefSequence& seq) {
  std::vector<mirror::GradeFrame> frames;
  for (size_t i = 0; i < seq.frames.size(); ++i) {
    mirror::GradeFrame f;
    f.time_s = static_cast<double>(i) / seq.fps;
    body::SkeletonPose pose;
    int any = 0;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      pose.position_m[j] = Eigen::Vector3d::Zero();
      if (const auto& p = seq.frames[i].joints[j])
        pose.position_m[j] = *p, pose.valid[j] = true, ++any;
    }
    if (any > 0) f.pose = pose;
    mirror::MarkValidJointsSeen(f);
    frames.push_back(std::move(f));
  }
  return frames;
}

std::vector<mirror::GradeFrame> TrackedGradeFrames(const RefSequence& seq,
                                                   const std::vector<TrackedRefFrame>& tracked) {
  std::vector<mirror::GradeFrame> frames;
  for (size_t i = 0; i < tracked.size(); ++i) {
    mirror::GradeFrame f;
    f.time_s = static_cast<double>(i) / seq.fps;
    if (const auto& person = tracked[i].person) {
      body::SkeletonPose pose;
      int any = 0;
      for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
        const tracking::TrackedJoint& joint = person->joints[j];
        pose.position_m[j] = Eigen::Vector3d::Zero();
        if (joint.state == tracking::JointState::kNotTracked ||
            !joint.position_in_camera_m.allFinite()) {
          continue;
        }
        pose.position_m[j] = joint.position_in_camera_m;
        pose.valid[j] = true;
        f.seen[j] = joint.state == tracking::JointState::kTracked;
        ++any;
      }
      if (any > 0) f.pose = pose;
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

}  // namespace reenact::cli
