// BVH writer (the format ReadBvh reads; see bvh_reader.cc for the grammar).
//
// Layout written: one ROOT with six channels "Xposition Yposition Zposition
// Zrotation Xrotation Yrotation", every other joint three channels
// "Zrotation Xrotation Yrotation" (parent_from_joint R = Rz * Rx * Ry, the
// order CMU's files use), angles in degrees. The root's OFFSET is zero and
// its position channels carry Motion::root_translation_m. A joint named
// "<parent>_end" without children (how ReadBvh names an End Site) is written
// back as that parent's End Site; any other joint without children gets an
// End Site along its own bone (EndSiteOffset), so that no bone of the file
// has zero length: importers that make a bone per joint (Blender) give the
// leaf a bone from the joint to its End Site.
//
// Angles are continuous from frame to frame: of the two Z-X-Y triples of a
// rotation, (a, b, c) and (a + 180, 180 - b, c + 180), and of their turns by
// whole multiples of 360 degrees, each frame writes the one nearest to the
// previous frame's, so that a player interpolating channels linearly
// between frames turns the short way.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/body/motion.h"

namespace reenact::body {
namespace {

bool IsEndSite(const Motion& motion, const std::vector<std::vector<int>>& children, int joint) {
  const MotionJoint& j = motion.joints()[joint];
  return j.parent >= 0 && children[joint].empty() &&
         j.name == motion.joints()[j.parent].name + "_end";
}

// The offset of the End Site of a leaf joint whose own offset from its
// parent is `offset_m`: half the leaf's bone onward, at least 2 cm; 5 cm up
// for a leaf that sits on its parent.
Eigen::Vector3d EndSiteOffset(const Eigen::Vector3d& offset_m) {
  constexpr double kMinLengthM = 0.02;
  const double length = offset_m.norm();
  if (!(length > 1e-9)) return Eigen::Vector3d(0.0, 0.05, 0.0);
  return offset_m * (std::max(0.5 * length, kMinLengthM) / length);
}

// Z-X-Y Euler angles (radians) of `rotation`, the triple nearest `previous`
// (see the file comment); `previous` null: Eigen's principal triple.
Eigen::Vector3d ContinuousZxy(const Eigen::Matrix3d& rotation, const Eigen::Vector3d* previous) {
  Eigen::Vector3d principal = rotation.eulerAngles(2, 0, 1);
  if (previous == nullptr) return principal;
  constexpr double kPi = std::numbers::pi;
  const std::array<Eigen::Vector3d, 2> candidates = {
      principal, Eigen::Vector3d(principal[0] + kPi, kPi - principal[1], principal[2] + kPi)};
  Eigen::Vector3d best = principal;
  double best_distance = std::numeric_limits<double>::infinity();
  for (Eigen::Vector3d candidate : candidates) {
    for (int k = 0; k < 3; ++k) {
      candidate[k] += 2.0 * kPi * std::round(((*previous)[k] - candidate[k]) / (2.0 * kPi));
    }
    const double distance = (candidate - *previous).cwiseAbs().sum();
    if (distance < best_distance) {
      best_distance = distance;
      best = candidate;
    }
  }
  return best;
}

class Writer {
 public:
  Writer(const Motion& motion, const BvhWriteOptions& options)
      : motion_(motion), options_(options), children_(motion.joints().size()) {
    for (size_t j = 0; j < motion.joints().size(); ++j) {
      if (motion.joints()[j].parent >= 0) children_[motion.joints()[j].parent].push_back(j);
    }
  }

  absl::StatusOr<std::string> Write() {
    int root = -1;
    for (size_t j = 0; j < motion_.joints().size(); ++j) {
      const MotionJoint& joint = motion_.joints()[j];
      if (joint.name.empty() || joint.name.find_first_of(" \t\r\n{}") != std::string::npos) {
        return absl::InvalidArgumentError(
            absl::StrCat("WriteBvh: joint ", j, " has a name BVH cannot hold: '", joint.name, "'"));
      }
      if (joint.parent >= static_cast<int>(j)) {
        return absl::InvalidArgumentError(
            absl::StrCat("WriteBvh: joint '", joint.name, "' comes before its parent"));
      }
      if (!joint.offset_m.allFinite()) {
        return absl::InvalidArgumentError(
            absl::StrCat("WriteBvh: joint '", joint.name, "' has a non-finite offset"));
      }
      if (joint.parent < 0) {
        if (root >= 0) return absl::InvalidArgumentError("WriteBvh: more than one root joint");
        root = static_cast<int>(j);
      }
    }
    if (root < 0) return absl::InvalidArgumentError("WriteBvh: no joints");
    if (!(motion_.fps() > 0.0) || !std::isfinite(motion_.fps())) {
      return absl::InvalidArgumentError(absl::StrCat("WriteBvh: bad frame rate ", motion_.fps()));
    }
    out_ = "HIERARCHY\n";
    WriteJoint(root, 0);
    absl::StrAppend(&out_, "MOTION\nFrames: ", motion_.num_frames(), "\n");
    absl::StrAppendFormat(&out_, "Frame Time: %.9g\n", 1.0 / motion_.fps());
    for (int f = 0; f < motion_.num_frames(); ++f) RETURN_IF_ERROR(WriteFrame(f));
    return std::move(out_);
  }

 private:
  double Units(double metres) const { return metres / options_.metres_per_unit; }

  void AppendOffset(const std::string& indent, const Eigen::Vector3d& offset_m) {
    absl::StrAppendFormat(&out_, "%sOFFSET %.*f %.*f %.*f\n", indent, options_.decimals,
                          Units(offset_m.x()), options_.decimals, Units(offset_m.y()),
                          options_.decimals, Units(offset_m.z()));
  }

  void WriteJoint(int j, int depth) {
    const std::string indent(2 * depth, ' ');
    const MotionJoint& joint = motion_.joints()[j];
    const bool root = joint.parent < 0;
    absl::StrAppend(&out_, indent, root ? "ROOT " : "JOINT ", joint.name, "\n", indent, "{\n");
    AppendOffset(indent + "  ", root ? Eigen::Vector3d::Zero() : joint.offset_m);
    absl::StrAppend(&out_, indent, "  CHANNELS ", root ? "6 Xposition Yposition Zposition " : "3 ",
                    "Zrotation Xrotation Yrotation\n");
    order_.push_back(j);
    bool has_end_site = false;
    for (int child : children_[j]) {
      if (IsEndSite(motion_, children_, child)) {
        if (has_end_site) continue;  // BVH holds one End Site per joint.
        has_end_site = true;
        absl::StrAppend(&out_, indent, "  End Site\n", indent, "  {\n");
        AppendOffset(indent + "    ", motion_.joints()[child].offset_m);
        absl::StrAppend(&out_, indent, "  }\n");
      } else {
        WriteJoint(child, depth + 1);
      }
    }
    if (children_[j].empty()) {
      absl::StrAppend(&out_, indent, "  End Site\n", indent, "  {\n");
      AppendOffset(indent + "    ", EndSiteOffset(joint.offset_m));
      absl::StrAppend(&out_, indent, "  }\n");
    }
    absl::StrAppend(&out_, indent, "}\n");
  }

  absl::Status WriteFrame(int f) {
    const std::vector<Eigen::Quaterniond>& rotations = motion_.local_rotations(f);
    const Eigen::Vector3d& root_m = motion_.root_translation_m(f);
    if (!root_m.allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("WriteBvh: frame ", f, ": root not finite"));
    }
    std::string line;
    absl::StrAppendFormat(&line, "%.*f %.*f %.*f", options_.decimals, Units(root_m.x()),
                          options_.decimals, Units(root_m.y()), options_.decimals,
                          Units(root_m.z()));
    const bool first = previous_.size() != order_.size();
    if (first) previous_.assign(order_.size(), Eigen::Vector3d::Zero());
    for (size_t slot = 0; slot < order_.size(); ++slot) {
      const int j = order_[slot];
      const Eigen::Quaterniond& q = rotations[j];
      if (!q.coeffs().allFinite() || !(q.norm() > 1e-9)) {
        return absl::InvalidArgumentError(absl::StrCat(
            "WriteBvh: frame ", f, ": joint '", motion_.joints()[j].name, "' rotation not valid"));
      }
      // R = Rz(a) * Rx(b) * Ry(c).
      Eigen::Vector3d& zxy = previous_[slot];
      zxy = ContinuousZxy(q.normalized().toRotationMatrix(), first ? nullptr : &zxy);
      for (int k = 0; k < 3; ++k) {
        absl::StrAppendFormat(&line, " %.*f", options_.decimals, zxy[k] * 180.0 / M_PI);
      }
    }
    absl::StrAppend(&out_, line, "\n");
    return absl::OkStatus();
  }

  const Motion& motion_;
  const BvhWriteOptions& options_;
  std::vector<std::vector<int>> children_;
  std::vector<int> order_;  // Joints in channel order (depth first).
  // The angles last written per joint of order_, radians (empty before the
  // first frame).
  std::vector<Eigen::Vector3d> previous_;
  std::string out_;
};

}  // namespace

absl::Status WriteBvh(const Motion& motion, const std::string& path,
                      const BvhWriteOptions& options) {
  if (!(options.metres_per_unit > 0.0) || !std::isfinite(options.metres_per_unit)) {
    return absl::InvalidArgumentError("WriteBvh: metres_per_unit must be > 0");
  }
  if (options.decimals < 1 || options.decimals > 12) {
    return absl::InvalidArgumentError("WriteBvh: decimals must lie in [1, 12]");
  }
  Writer writer(motion, options);
  ASSIGN_OR_RETURN(std::string text, writer.Write());
  return WriteFileAtomically(path, text);
}

}  // namespace reenact::body
