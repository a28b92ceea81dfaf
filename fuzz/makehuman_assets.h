// A small synthetic MakeHuman asset folder (common/body/makehuman_importer.h)
// that ImportMakeHuman reads: a body of stacked rings of quads in group
// "body" plus a helper cube, a skeleton naming every bone of the MakeHuman
// joint table with a ring of vertices as its head joint, skin weights and
// two targets. The MakeHuman fuzz targets replace one or two of its files by
// the input; the seed maker writes the same files as seeds.
#pragma once

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/body/joint_set.h"
#include "fuzz/fuzz_util.h"

namespace reenact::fuzz {

// Rings of the synthetic body and vertices per ring.
inline constexpr int kMakeHumanRings = 6;
inline constexpr int kMakeHumanRingVertices = 8;
inline constexpr int kMakeHumanBodyVertices = kMakeHumanRings * kMakeHumanRingVertices;

struct MakeHumanFiles {
  std::string obj;       // 3dobjs/base.obj
  std::string skeleton;  // rigs/default.mhskel
  std::string weights;   // rigs/default_weights.mhw
  std::string target;    // targets/macrodetails/*.target and height/*.target
};

inline MakeHumanFiles SmallMakeHumanFiles() {
  MakeHumanFiles files;
  // Rings from the floor to 17 dm, radius 1.5 dm; then a helper cube.
  std::string& obj = files.obj;
  obj = "# small synthetic MakeHuman mesh\n";
  for (int r = 0; r < kMakeHumanRings; ++r) {
    for (int k = 0; k < kMakeHumanRingVertices; ++k) {
      const double angle = 2 * M_PI * k / kMakeHumanRingVertices;
      absl::StrAppend(&obj, "v ", 1.5 * std::cos(angle), " ", 17.0 * r / (kMakeHumanRings - 1), " ",
                      1.5 * std::sin(angle), "\n");
    }
  }
  for (int c = 0; c < 8; ++c) {
    absl::StrAppend(&obj, "v ", c & 1, " ", 20 + ((c >> 1) & 1), " ", (c >> 2) & 1, "\n");
  }
  for (int k = 0; k <= kMakeHumanRingVertices; ++k) {
    for (int r = 0; r < kMakeHumanRings; ++r) {
      absl::StrAppend(&obj, "vt ", static_cast<double>(k) / kMakeHumanRingVertices, " ",
                      static_cast<double>(r) / (kMakeHumanRings - 1), "\n");
    }
  }
  obj += "g body\n";
  const auto vertex = [](int r, int k) {
    return r * kMakeHumanRingVertices + k % kMakeHumanRingVertices + 1;
  };
  const auto uv = [](int r, int k) { return k * kMakeHumanRings + r + 1; };
  for (int r = 0; r + 1 < kMakeHumanRings; ++r) {
    for (int k = 0; k < kMakeHumanRingVertices; ++k) {
      absl::StrAppend(&obj, "f ", vertex(r, k), "/", uv(r, k), " ", vertex(r, k + 1), "/",
                      uv(r, k + 1), " ", vertex(r + 1, k + 1), "/", uv(r + 1, k + 1), " ",
                      vertex(r + 1, k), "/", uv(r + 1, k), "\n");
    }
  }
  absl::StrAppend(&obj, "g joint-cube\nf ", kMakeHumanBodyVertices + 1, " ",
                  kMakeHumanBodyVertices + 2, " ", kMakeHumanBodyVertices + 4, " ",
                  kMakeHumanBodyVertices + 3, "\n");

  // One joint per bone of the table, on the rings from the feet up.
  nlohmann::json skeleton = {{"joints", nlohmann::json::object()},
                             {"bones", nlohmann::json::object()}};
  nlohmann::json weights = {{"weights", nlohmann::json::object()}};
  const auto& table = body::JointMappingTable(body::JointSetId::kMakeHuman);
  std::string parent;
  for (size_t b = 0; b < table.size(); ++b) {
    const std::string& bone = table[b].source_name;
    if (skeleton["bones"].contains(bone)) continue;
    const int ring = static_cast<int>(b % kMakeHumanRings);
    nlohmann::json group = nlohmann::json::array();
    nlohmann::json pairs = nlohmann::json::array();
    for (int k = 0; k < kMakeHumanRingVertices; ++k) {
      group.push_back(ring * kMakeHumanRingVertices + k);
      pairs.push_back({ring * kMakeHumanRingVertices + k, 0.5});
    }
    skeleton["joints"][bone + "____head"] = group;
    skeleton["bones"][bone] = {{"head", bone + "____head"}, {"parent", parent}};
    weights["weights"][bone] = pairs;
    parent = bone;
  }
  files.skeleton = skeleton.dump(1) + "\n";
  files.weights = weights.dump(1) + "\n";
  files.target = "# vertex dx dy dz, decimetres\n0 0.1 0 0\n9 0 0.05 0\n47 0 0 -0.02\n";
  return files;
}

// Writes `files` as a MakeHuman asset folder under `dir`.
inline void WriteMakeHumanFiles(const std::string& dir, const MakeHumanFiles& files) {
  const std::string prefix = dir + "/";
  WriteFile(prefix + "3dobjs/base.obj", files.obj);
  WriteFile(prefix + "rigs/default.mhskel", files.skeleton);
  WriteFile(prefix + "rigs/default_weights.mhw", files.weights);
  WriteFile(prefix + "targets/macrodetails/synthetic.target", files.target);
  WriteFile(prefix + "targets/macrodetails/height/synthetic-height.target", files.target);
}

}  // namespace reenact::fuzz
