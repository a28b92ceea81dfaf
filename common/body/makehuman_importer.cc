#include "common/body/makehuman_importer.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::body {
namespace {

// Largest MakeHuman file read (base.obj is 1.7 MB; targets and JSON are
// smaller): a FIFO, a device or a runaway file is refused before it is read.
constexpr uint64_t kMaxMakeHumanFileBytes = uint64_t{256} << 20;

constexpr double kMetresPerDecimetre = 0.1;
constexpr char kBodyGroup[] = "body";

// ---- Text parsing. ----

std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

template <typename T>
bool ParseNumber(std::string_view token, T& value) {
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end;
}

// Calls `visit(line_number, line)` for every line of `text`.
template <typename Visit>
absl::Status ForEachLine(std::string_view text, Visit visit) {
  int line_number = 0;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    ++line_number;
    RETURN_IF_ERROR(visit(line_number, text.substr(start, end - start)));
    start = end + 1;
  }
  return absl::OkStatus();
}

absl::Status LineError(const std::string& path, int line, std::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat(path, ":", line, ": ", std::string(what)));
}

// ---- base.obj ----

struct ObjMesh {
  std::vector<Eigen::Vector3d> positions_dm;
  std::vector<Eigen::Vector2f> uvs;
  // Triangles of the kept group: original vertex and uv indices (0-based).
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Eigen::Vector3i> uv_triangles;
};

// Resolves one OBJ index (1-based, or negative relative to the end).
bool ResolveObjIndex(std::string_view token, size_t count, int& index) {
  int raw = 0;
  if (!ParseNumber(token, raw) || raw == 0) return false;
  index = raw > 0 ? raw - 1 : static_cast<int>(count) + raw;
  return index >= 0 && static_cast<size_t>(index) < count;
}

absl::Status ParseObjFace(const std::string& path, int line,
                          const std::vector<std::string_view>& tokens, ObjMesh& mesh) {
  if (tokens.size() < 4) return LineError(path, line, "face with fewer than 3 corners");
  std::vector<int> vertices, uvs;
  for (size_t c = 1; c < tokens.size(); ++c) {
    const std::string_view corner = tokens[c];
    const size_t slash = corner.find('/');
    int vertex = 0;
    if (!ResolveObjIndex(corner.substr(0, slash), mesh.positions_dm.size(), vertex)) {
      return LineError(path, line, absl::StrCat("bad vertex index in '", std::string(corner), "'"));
    }
    vertices.push_back(vertex);
    if (slash != std::string_view::npos) {
      std::string_view rest = corner.substr(slash + 1);
      rest = rest.substr(0, rest.find('/'));
      int uv = 0;
      if (!rest.empty()) {
        if (!ResolveObjIndex(rest, mesh.uvs.size(), uv)) {
          return LineError(path, line, absl::StrCat("bad uv index in '", std::string(corner), "'"));
        }
        uvs.push_back(uv);
      }
    }
  }
  const bool has_uvs = uvs.size() == vertices.size();
  // Fan triangulation: a quad (a, b, c, d) becomes (a, b, c) and (a, c, d).
  for (size_t k = 1; k + 1 < vertices.size(); ++k) {
    mesh.triangles.emplace_back(vertices[0], vertices[k], vertices[k + 1]);
    mesh.uv_triangles.push_back(has_uvs ? Eigen::Vector3i(uvs[0], uvs[k], uvs[k + 1])
                                        : Eigen::Vector3i(-1, -1, -1));
  }
  return absl::OkStatus();
}

absl::StatusOr<ObjMesh> ReadObj(const std::string& path) {
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, kMaxMakeHumanFileBytes));
  ObjMesh mesh;
  std::string group;
  RETURN_IF_ERROR(ForEachLine(text, [&](int line, std::string_view content) -> absl::Status {
    const std::vector<std::string_view> tokens = SplitWhitespace(content);
    if (tokens.empty() || tokens[0][0] == '#') return absl::OkStatus();
    if (tokens[0] == "v" || tokens[0] == "vt") {
      const size_t n = tokens[0] == "v" ? 3 : 2;
      if (tokens.size() < n + 1) return LineError(path, line, "too few coordinates");
      double xyz[3] = {0, 0, 0};
      for (size_t k = 0; k < n; ++k) {
        if (!ParseNumber(tokens[k + 1], xyz[k]) || !std::isfinite(xyz[k])) {
          return LineError(path, line,
                           absl::StrCat("bad number '", std::string(tokens[k + 1]), "'"));
        }
      }
      if (n == 3) {
        mesh.positions_dm.emplace_back(xyz[0], xyz[1], xyz[2]);
      } else {
        mesh.uvs.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]));
      }
    } else if (tokens[0] == "g") {
      group = tokens.size() > 1 ? std::string(tokens[1]) : "";
    } else if (tokens[0] == "f" && group == kBodyGroup) {
      return ParseObjFace(path, line, tokens, mesh);
    }
    return absl::OkStatus();
  }));
  if (mesh.triangles.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": no faces in group '", kBodyGroup, "'"));
  }
  return mesh;
}

// ---- JSON files. ----

absl::StatusOr<nlohmann::json> ReadJson(const std::string& path) {
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, kMaxMakeHumanFileBytes));
  nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded() || !json.is_object()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": not a valid JSON object"));
  }
  return json;
}

struct Skeleton {
  std::map<std::string, std::vector<int>> joint_vertices;  // Joint name -> vertex group.
  std::map<std::string, std::string> bone_head;            // Bone -> head joint name.
  std::map<std::string, std::string> bone_parent;          // Bone -> parent ("" for roots).
};

absl::StatusOr<Skeleton> ReadSkeleton(const std::string& path, size_t num_vertices) {
  ASSIGN_OR_RETURN(const nlohmann::json json, ReadJson(path));
  Skeleton skeleton;
  if (!json.contains("joints") || !json["joints"].is_object() || !json.contains("bones") ||
      !json["bones"].is_object()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": missing 'joints' or 'bones'"));
  }
  for (const auto& [name, group] : json["joints"].items()) {
    if (!group.is_array() || group.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": joint '", name, "' has no vertices"));
    }
    std::vector<int>& vertices = skeleton.joint_vertices[name];
    for (const auto& v : group) {
      if (!v.is_number_integer() || v.get<int64_t>() < 0 ||
          v.get<int64_t>() >= static_cast<int64_t>(num_vertices)) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": joint '", name, "' has a bad vertex index"));
      }
      vertices.push_back(v.get<int>());
    }
  }
  for (const auto& [name, bone] : json["bones"].items()) {
    if (!bone.is_object() || !bone.contains("head") || !bone["head"].is_string()) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": bone '", name, "' has no head"));
    }
    skeleton.bone_head[name] = bone["head"].get<std::string>();
    if (!skeleton.joint_vertices.contains(skeleton.bone_head[name])) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": bone '", name, "' names an unknown head joint"));
    }
    const auto parent = bone.find("parent");
    skeleton.bone_parent[name] =
        parent != bone.end() && parent->is_string() ? parent->get<std::string>() : "";
  }
  return skeleton;
}

// ---- Joint regressor. ----

// Convex weights over `candidates` (body vertex ids) whose weighted mean is
// as near `point_m` as the candidates allow: min ||X w - p||^2 on the simplex,
// by Frank-Wolfe with exact line search, started from the uniform mean.
Eigen::VectorXd SimplexWeights(const Eigen::Matrix3Xd& positions_m,
                               const Eigen::Vector3d& point_m) {
  const Eigen::Index k = positions_m.cols();
  Eigen::VectorXd weights = Eigen::VectorXd::Constant(k, 1.0 / k);
  for (int iteration = 0; iteration < 2000; ++iteration) {
    const Eigen::Vector3d residual_m = positions_m * weights - point_m;
    if (residual_m.norm() < 1e-7) break;
    Eigen::Index best = 0;
    (positions_m.transpose() * residual_m).minCoeff(&best);
    // Move towards vertex `best`: w <- w + gamma (e_best - w).
    const Eigen::Vector3d step_m = positions_m.col(best) - positions_m * weights;
    const double step_norm2 = step_m.squaredNorm();
    if (step_norm2 < 1e-20) break;
    const double gamma = std::clamp(-residual_m.dot(step_m) / step_norm2, 0.0, 1.0);
    if (gamma <= 0.0) break;
    weights *= 1.0 - gamma;
    weights[best] += gamma;
  }
  return weights;
}

// Weights over `candidates` summing to 1 whose weighted mean is exactly
// `point_m`: the convex fit above, then the minimum-norm affine correction
// w += A^T (A A^T)^-1 (b - A w), A = [positions; 1^T], b = [p; 1], which is
// tiny when the candidates surround the point.
std::vector<std::pair<int, double>> AffineWeights(const Eigen::Matrix3Xd& vertices_m,
                                                  const std::vector<int>& candidates,
                                                  const Eigen::Vector3d& point_m) {
  const int k = static_cast<int>(candidates.size());
  Eigen::MatrixXd a(4, k);
  for (int i = 0; i < k; ++i) {
    a.block<3, 1>(0, i) = vertices_m.col(candidates[i]);
    a(3, i) = 1.0;
  }
  Eigen::VectorXd weights = SimplexWeights(a.topRows<3>(), point_m);
  Eigen::Vector4d residual;
  residual << point_m - a.topRows<3>() * weights, 1.0 - weights.sum();
  const Eigen::Matrix4d gram = a * a.transpose();
  weights += a.transpose() * gram.completeOrthogonalDecomposition().solve(residual);
  std::vector<std::pair<int, double>> row;
  row.reserve(k);
  for (int i = 0; i < k; ++i) row.emplace_back(candidates[i], weights[i]);
  return row;
}

// Body vertices around `point_m` (see MakeHumanImportOptions).
std::vector<int> RingAround(const Eigen::Matrix3Xd& vertices_m, const Eigen::Vector3d& point_m,
                            const MakeHumanImportOptions& options) {
  std::vector<std::pair<double, int>> by_distance(vertices_m.cols());
  for (Eigen::Index v = 0; v < vertices_m.cols(); ++v) {
    by_distance[v] = {(vertices_m.col(v) - point_m).norm(), static_cast<int>(v)};
  }
  std::sort(by_distance.begin(), by_distance.end());
  const double radius_m = options.fallback_radius_factor * by_distance.front().first;
  size_t within = 0;
  while (within < by_distance.size() && by_distance[within].first <= radius_m) ++within;
  const size_t wanted = static_cast<size_t>(std::max(4, options.max_fallback_vertices));
  within = std::clamp(within, std::min<size_t>(8, by_distance.size()), by_distance.size());
  // Spread the picks over the whole radius rather than its nearest side.
  const size_t step = std::max<size_t>(1, within / wanted);
  std::vector<int> ring;
  for (size_t i = 0; i < within && ring.size() < wanted; i += step) {
    ring.push_back(by_distance[i].second);
  }
  return ring;
}

Eigen::Vector3d GroupMean(const std::vector<Eigen::Vector3d>& positions_m,
                          const std::vector<int>& group) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int v : group) sum += positions_m[v];
  return sum / static_cast<double>(group.size());
}

struct RegressorResult {
  Eigen::SparseMatrix<double, Eigen::RowMajor> regressor;
  std::array<Eigen::Vector3d, kNumKinectV2Joints> skeleton_joints_m;
};

absl::StatusOr<RegressorResult> BuildRegressor(const std::string& skel_path,
                                               const Skeleton& skeleton,
                                               const std::vector<Eigen::Vector3d>& all_m,
                                               const std::vector<int>& body_from_original,
                                               const Eigen::Matrix3Xd& body_m,
                                               const MakeHumanImportOptions& options) {
  RegressorResult result;
  std::vector<Eigen::Triplet<double>> triplets;
  std::array<bool, kNumKinectV2Joints> covered{};
  for (const JointMapping& mapping : JointMappingTable(JointSetId::kMakeHuman)) {
    const auto head = skeleton.bone_head.find(mapping.source_name);
    if (head == skeleton.bone_head.end()) {
      return absl::InvalidArgumentError(
          absl::StrCat(skel_path, ": no bone '", mapping.source_name, "'"));
    }
    const std::vector<int>& group = skeleton.joint_vertices.at(head->second);
    const int row = Index(mapping.target);
    covered[row] = true;
    result.skeleton_joints_m[row] = GroupMean(all_m, group);
    const bool on_body =
        std::all_of(group.begin(), group.end(), [&](int v) { return body_from_original[v] >= 0; });
    if (on_body) {
      for (int v : group) triplets.emplace_back(row, body_from_original[v], 1.0 / group.size());
      continue;
    }
    const std::vector<int> ring = RingAround(body_m, result.skeleton_joints_m[row], options);
    for (const auto& [v, w] : AffineWeights(body_m, ring, result.skeleton_joints_m[row])) {
      triplets.emplace_back(row, v, w);
    }
  }
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    if (!covered[j]) {
      return absl::InternalError(absl::StrCat("the MakeHuman joint table lacks ",
                                              std::string(KinectV2JointName(KinectV2Joint(j)))));
    }
  }
  result.regressor.resize(kNumKinectV2Joints, body_m.cols());
  result.regressor.setFromTriplets(triplets.begin(), triplets.end());
  return result;
}

// ---- Skin weights. ----

// Canonical joint of every MakeHuman bone: its own mapping, else that of its
// nearest mapped ancestor, else SpineBase (bones above the pelvis).
std::map<std::string, int> BoneToCanonical(const Skeleton& skeleton) {
  std::map<std::string, int> mapped;
  for (const JointMapping& m : JointMappingTable(JointSetId::kMakeHuman)) {
    mapped[m.source_name] = Index(m.target);
  }
  std::map<std::string, int> result;
  for (const auto& [bone, parent] : skeleton.bone_parent) {
    std::string at = bone;
    int canonical = Index(KinectV2Joint::kSpineBase);
    for (size_t depth = 0; !at.empty() && depth <= skeleton.bone_parent.size(); ++depth) {
      if (const auto it = mapped.find(at); it != mapped.end()) {
        canonical = it->second;
        break;
      }
      const auto up = skeleton.bone_parent.find(at);
      at = up == skeleton.bone_parent.end() ? "" : up->second;
    }
    result[bone] = canonical;
  }
  return result;
}

absl::Status ReadSkinWeights(const std::string& path, const Skeleton& skeleton,
                             const std::vector<int>& body_from_original,
                             const std::array<Eigen::Vector3d, kNumKinectV2Joints>& joints_m,
                             const Eigen::Matrix3Xd& body_m, BodyModel& model) {
  ASSIGN_OR_RETURN(const nlohmann::json json, ReadJson(path));
  if (!json.contains("weights") || !json["weights"].is_object()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": missing 'weights'"));
  }
  const std::map<std::string, int> canonical_of = BoneToCanonical(skeleton);
  const Eigen::Index num_vertices = body_m.cols();
  Eigen::MatrixXd accumulated = Eigen::MatrixXd::Zero(kNumKinectV2Joints, num_vertices);
  for (const auto& [bone, pairs] : json["weights"].items()) {
    const auto canonical = canonical_of.find(bone);
    if (canonical == canonical_of.end()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": weights for unknown bone '", bone, "'"));
    }
    if (!pairs.is_array())
      return absl::InvalidArgumentError(absl::StrCat(path, ": bad '", bone, "'"));
    for (const auto& pair : pairs) {
      if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_integer() ||
          !pair[1].is_number() || pair[0].get<int64_t>() < 0 ||
          pair[0].get<int64_t>() >= static_cast<int64_t>(body_from_original.size()) ||
          !std::isfinite(pair[1].get<double>()) || pair[1].get<double>() < 0.0) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": bad [vertex, weight] pair for bone '", bone, "'"));
      }
      const int body_vertex = body_from_original[pair[0].get<int>()];
      if (body_vertex >= 0) accumulated(canonical->second, body_vertex) += pair[1].get<double>();
    }
  }
  model.skin_joints.assign(num_vertices, {0, 0, 0, 0});
  model.skin_weights.assign(num_vertices, {0.f, 0.f, 0.f, 0.f});
  for (Eigen::Index v = 0; v < num_vertices; ++v) {
    std::array<int, kNumKinectV2Joints> order;
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + kMaxInfluences, order.end(),
                      [&](int a, int b) { return accumulated(a, v) > accumulated(b, v); });
    double total = 0.0;
    for (int k = 0; k < kMaxInfluences; ++k) total += accumulated(order[k], v);
    if (total <= 0.0) {
      // Unweighted vertex: follow the nearest joint.
      int nearest = 0;
      for (int j = 1; j < kNumKinectV2Joints; ++j) {
        if ((joints_m[j] - body_m.col(v)).norm() < (joints_m[nearest] - body_m.col(v)).norm()) {
          nearest = j;
        }
      }
      model.skin_joints[v][0] = nearest;
      model.skin_weights[v][0] = 1.0f;
      continue;
    }
    float sum = 0.0f;
    for (int k = 0; k < kMaxInfluences; ++k) {
      model.skin_joints[v][k] = order[k];
      model.skin_weights[v][k] = static_cast<float>(accumulated(order[k], v) / total);
      if (k > 0) sum += model.skin_weights[v][k];
    }
    model.skin_weights[v][0] = 1.0f - sum;  // Exact float sum of 1.
  }
  return absl::OkStatus();
}

// ---- Targets. ----

absl::StatusOr<Eigen::Matrix3Xd> ReadTarget(const std::string& path,
                                            const std::vector<int>& body_from_original,
                                            Eigen::Index num_body_vertices) {
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, kMaxMakeHumanFileBytes));
  Eigen::Matrix3Xd direction_m = Eigen::Matrix3Xd::Zero(3, num_body_vertices);
  RETURN_IF_ERROR(ForEachLine(text, [&](int line, std::string_view content) -> absl::Status {
    const std::vector<std::string_view> tokens = SplitWhitespace(content);
    if (tokens.empty() || tokens[0][0] == '#') return absl::OkStatus();
    int vertex = -1;
    Eigen::Vector3d delta_dm;
    if (tokens.size() != 4 || !ParseNumber(tokens[0], vertex) ||
        !ParseNumber(tokens[1], delta_dm.x()) || !ParseNumber(tokens[2], delta_dm.y()) ||
        !ParseNumber(tokens[3], delta_dm.z()) || !delta_dm.allFinite()) {
      return LineError(path, line, "expected 'vertex dx dy dz'");
    }
    if (vertex < 0 || static_cast<size_t>(vertex) >= body_from_original.size()) {
      return LineError(path, line, absl::StrCat("vertex ", vertex, " is not in the base mesh"));
    }
    if (body_from_original[vertex] >= 0) {
      direction_m.col(body_from_original[vertex]) = kMetresPerDecimetre * delta_dm;
    }
    return absl::OkStatus();
  }));
  return direction_m;
}

absl::StatusOr<std::vector<std::string>> ListTargets(const std::string& folder) {
  std::error_code ec;
  std::vector<std::string> paths;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
    if (entry.is_regular_file() && entry.path().extension() == ".target") {
      paths.push_back(entry.path().string());
    }
  }
  if (ec) return absl::NotFoundError(absl::StrCat(folder, ": ", ec.message()));
  std::sort(paths.begin(), paths.end());
  return paths;
}

absl::Status ReadShapeSpace(const std::string& dir, const MakeHumanImportOptions& options,
                            const std::vector<int>& body_from_original, BodyModel& model) {
  const std::string macro = dir + "/targets/macrodetails";
  ASSIGN_OR_RETURN(std::vector<std::string> paths, ListTargets(macro));
  if (options.include_height_targets) {
    ASSIGN_OR_RETURN(const std::vector<std::string> height, ListTargets(macro + "/height"));
    paths.insert(paths.end(), height.begin(), height.end());
  }
  if (paths.empty()) return absl::NotFoundError(absl::StrCat(macro, ": no .target files"));
  for (const std::string& path : paths) {
    ASSIGN_OR_RETURN(Eigen::Matrix3Xd direction,
                     ReadTarget(path, body_from_original, model.num_vertices()));
    model.shape_directions_m.push_back(std::move(direction));
    model.shape_names.push_back(std::filesystem::path(path).stem().string());
  }
  return absl::OkStatus();
}

// ---- Mesh conversion. ----

// Keeps the vertices and uvs the body triangles use, renumbered in file order.
void BuildBodyMesh(const ObjMesh& obj, double floor_offset_m, std::vector<int>& body_from_original,
                   MakeHumanImport& out) {
  body_from_original.assign(obj.positions_dm.size(), -1);
  std::vector<int> uv_map(obj.uvs.size(), -1);
  for (size_t t = 0; t < obj.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      body_from_original[obj.triangles[t][c]] = 0;
      if (obj.uv_triangles[t][c] >= 0) uv_map[obj.uv_triangles[t][c]] = 0;
    }
  }
  BodyModel& model = out.model;
  for (size_t v = 0; v < body_from_original.size(); ++v) {
    if (body_from_original[v] < 0) continue;
    body_from_original[v] = static_cast<int>(out.original_vertex_index.size());
    out.original_vertex_index.push_back(static_cast<int>(v));
  }
  model.template_vertices_m.resize(3, out.original_vertex_index.size());
  for (size_t i = 0; i < out.original_vertex_index.size(); ++i) {
    model.template_vertices_m.col(i) =
        kMetresPerDecimetre * obj.positions_dm[out.original_vertex_index[i]] +
        Eigen::Vector3d(0, floor_offset_m, 0);
  }
  for (size_t u = 0; u < uv_map.size(); ++u) {
    if (uv_map[u] < 0) continue;
    uv_map[u] = static_cast<int>(model.uvs.size());
    model.uvs.push_back(obj.uvs[u]);
  }
  const bool all_uvs = std::all_of(obj.uv_triangles.begin(), obj.uv_triangles.end(),
                                   [](const Eigen::Vector3i& t) { return t[0] >= 0; });
  for (size_t t = 0; t < obj.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = obj.triangles[t];
    model.triangles.emplace_back(body_from_original[tri[0]], body_from_original[tri[1]],
                                 body_from_original[tri[2]]);
    if (all_uvs) {
      const Eigen::Vector3i& uv = obj.uv_triangles[t];
      model.uv_triangles.emplace_back(uv_map[uv[0]], uv_map[uv[1]], uv_map[uv[2]]);
    }
  }
  if (!all_uvs) model.uvs.clear();
}

}  // namespace

absl::StatusOr<MakeHumanImport> ImportMakeHumanDetailed(const std::string& dir,
                                                        const MakeHumanImportOptions& options) {
  if (!std::filesystem::is_directory(dir)) {
    return absl::NotFoundError(absl::StrCat(dir, ": no such MakeHuman asset folder"));
  }
  const std::string obj_path = dir + "/3dobjs/base.obj";
  ASSIGN_OR_RETURN(const ObjMesh obj, ReadObj(obj_path));

  double min_y_dm = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3i& tri : obj.triangles) {
    for (int c = 0; c < 3; ++c) min_y_dm = std::min(min_y_dm, obj.positions_dm[tri[c]].y());
  }
  MakeHumanImport out;
  out.floor_offset_m = -kMetresPerDecimetre * min_y_dm;  // Lowest body vertex -> y = 0.
  out.model.name = "makehuman";
  std::vector<int> body_from_original;
  BuildBodyMesh(obj, out.floor_offset_m, body_from_original, out);

  std::vector<Eigen::Vector3d> all_m(obj.positions_dm.size());
  for (size_t v = 0; v < all_m.size(); ++v) {
    all_m[v] =
        kMetresPerDecimetre * obj.positions_dm[v] + Eigen::Vector3d(0, out.floor_offset_m, 0);
  }
  const std::string skel_path = dir + "/rigs/default.mhskel";
  ASSIGN_OR_RETURN(const Skeleton skeleton, ReadSkeleton(skel_path, all_m.size()));
  ASSIGN_OR_RETURN(RegressorResult regressor,
                   BuildRegressor(skel_path, skeleton, all_m, body_from_original,
                                  out.model.template_vertices_m, options));
  // Eigen 3.4's SparseMatrix has no move assignment; swap hands the storage over.
  out.model.joint_regressor.swap(regressor.regressor);
  out.skeleton_joints_m = regressor.skeleton_joints_m;

  RETURN_IF_ERROR(ReadSkinWeights(dir + "/rigs/default_weights.mhw", skeleton, body_from_original,
                                  out.skeleton_joints_m, out.model.template_vertices_m, out.model));
  RETURN_IF_ERROR(ReadShapeSpace(dir, options, body_from_original, out.model));
  if (absl::Status status = ValidateBodyModel(out.model); !status.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat(dir, ": imported model is invalid: ", status.message()));
  }
  return out;
}

absl::StatusOr<BodyModel> ImportMakeHuman(const std::string& dir,
                                          const MakeHumanImportOptions& options) {
  ASSIGN_OR_RETURN(MakeHumanImport imported, ImportMakeHumanDetailed(dir, options));
  return std::move(imported.model);
}

}  // namespace reenact::body
