// Imports MakeHuman's CC0 base mesh, default skeleton, skin weights and macro
// targets (http://www.makehumancommunity.org, "hm08" base mesh) into a
// BodyModel on the canonical Kinect v2 skeleton.
//
// Files read under `dir`:
//   3dobjs/base.obj            mesh, decimetres, Y up, +Z forward, quads
//   rigs/default.mhskel        JSON: joints = lists of base-mesh vertex
//                              indices (a joint is their mean); bones with
//                              head/tail joint names and parents
//   rigs/default_weights.mhw   JSON: per bone, [vertex, weight] pairs
//   targets/macrodetails/*.target (and height/*.target): sparse
//                              "vertex dx dy dz" lines, decimetres
// Conversion: only the "body" group is kept (helper geometry and joint cubes
// are dropped and the vertices renumbered); lengths x 0.1 to metres; the mesh
// is lifted so that its lowest body vertex is on y = 0; quads are split along
// their first diagonal.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/body/body_model.h"

namespace reenact::body {

struct MakeHumanImportOptions {
  // Also read targets/macrodetails/height/*.target as shape directions.
  bool include_height_targets = true;
  // Where a canonical joint's vertex group lies partly off the body (on the
  // dropped joint cubes), its regressor row is rebuilt from body vertices
  // around it: those within this factor of the nearest body vertex's
  // distance, at most `max_fallback_vertices` of them (>= 4).
  double fallback_radius_factor = 2.0;
  int max_fallback_vertices = 64;
};

// What the import produced besides the model.
struct MakeHumanImport {
  BodyModel model;
  // Per model vertex, its 0-based index in base.obj.
  std::vector<int> original_vertex_index;
  // The mhskel joint of each canonical joint (head of the mapped bone) as the
  // mean of its vertex group on the full mesh, metres, model frame.
  std::array<Eigen::Vector3d, kNumKinectV2Joints> skeleton_joints_m;
  // Added to every y after scaling, so the feet stand on y = 0, metres.
  double floor_offset_m = 0.0;
};

// Reads the MakeHuman asset folder `dir` (see the file comment). The shape
// directions are the macro targets at full weight (beta_k = 1 applies the whole
// target), named after their files without the extension. Errors (NotFound,
// InvalidArgument, DataLoss) name the offending file and, for text formats,
// the line.
absl::StatusOr<MakeHumanImport> ImportMakeHumanDetailed(const std::string& dir,
                                                        const MakeHumanImportOptions& options = {});

// As ImportMakeHumanDetailed, the model only.
absl::StatusOr<BodyModel> ImportMakeHuman(const std::string& dir,
                                          const MakeHumanImportOptions& options = {});

}  // namespace reenact::body
