#include "common/model/reenactment.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"

namespace reenact {
namespace {

// One step of BodyFramePose::vertex_offsets_50um, metres.
constexpr double kOffsetUnitM = 50e-6;

absl::Status Invalid(const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat("invalid reenactment: ", what));
}

absl::Status CheckTriangles(const std::vector<Eigen::Vector3i>& triangles, int vertices,
                            const std::string& what) {
  for (size_t t = 0; t < triangles.size(); ++t) {
    if ((triangles[t].array() < 0).any() || (triangles[t].array() >= vertices).any()) {
      return Invalid(absl::StrCat(what, " triangle ", t, " has an index out of range (", vertices,
                                  " vertices)"));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckPart(const PartMesh& mesh, int part, const std::string& name) {
  const std::string what = absl::StrCat("part mesh ", part, " (", name, ")");
  if (mesh.part != part || mesh.name != name) {
    return Invalid(absl::StrCat(what, " is part ", mesh.part, " \"", mesh.name, "\""));
  }
  const Eigen::Index n = mesh.positions_in_part_m.cols();
  if ((mesh.normals_in_part.cols() != 0 && mesh.normals_in_part.cols() != n) ||
      (mesh.uvs.cols() != 0 && mesh.uvs.cols() != n)) {
    return Invalid(absl::StrCat(what, ": normals or uvs do not match its ", n, " positions"));
  }
  if (!mesh.positions_in_part_m.allFinite() || !mesh.normals_in_part.allFinite() ||
      !mesh.uvs.allFinite()) {
    return Invalid(absl::StrCat(what, " holds a non-finite number"));
  }
  return CheckTriangles(mesh.triangles, static_cast<int>(n), what);
}

absl::Status CheckBody(const Reenactment& data) {
  const BodyMesh& body = *data.body;
  const int n = body.num_vertices();
  if (n == 0 || body.triangles.empty()) return Invalid("the body mesh is empty");
  if (body.skin_joints.size() != static_cast<size_t>(n) ||
      body.skin_weights.size() != static_cast<size_t>(n)) {
    return Invalid("the body mesh's skinning does not match its vertices");
  }
  for (const auto& joints : body.skin_joints) {
    for (int j : joints) {
      if (j < 0 || j >= body::kNumKinectV2Joints) return Invalid("a skin joint is out of range");
    }
  }
  RETURN_IF_ERROR(CheckTriangles(body.triangles, n, "body mesh"));
  if (body.texture_uvs.size() != body.texture_vertex_source.size() ||
      body.texture_triangles.size() != body.triangles.size()) {
    return Invalid("the body mesh's texture vertices or triangles do not match");
  }
  for (uint32_t source : body.texture_vertex_source) {
    if (source >= static_cast<uint32_t>(n))
      return Invalid("a texture vertex names a missing vertex");
  }
  RETURN_IF_ERROR(CheckTriangles(
      body.texture_triangles, static_cast<int>(body.texture_vertex_source.size()), "body texture"));
  if (!data.parts.empty() || !data.keyframes.empty()) {
    return Invalid("a body-model reenactment with parts or keyframes");
  }
  for (size_t f = 0; f < data.frames.size(); ++f) {
    const std::optional<BodyFramePose>& pose = data.frames[f].body;
    if (!pose) return Invalid(absl::StrCat("frame ", f, " has no body pose"));
    const Eigen::Index offsets = pose->vertex_offsets_50um.cols();
    if (offsets != 0 && offsets != n) {
      return Invalid(
          absl::StrCat("frame ", f, " has offsets of ", offsets, " vertices, the mesh ", n));
    }
  }
  return absl::OkStatus();
}

bool IsFraction(float x) { return x >= 0.0f && x <= 1.0f; }

absl::Status CheckSensorFits(const std::vector<SensorFit>& fits, size_t sensors, size_t frame) {
  for (const SensorFit& fit : fits) {
    if (fit.sensor < 0 || static_cast<size_t>(fit.sensor) >= sensors) {
      return Invalid(
          absl::StrCat("frame ", frame, " has the fit of sensor ", fit.sensor, " of ", sensors));
    }
    if (fit.points < 0 || !IsFraction(fit.explained_fraction) ||
        !IsFraction(fit.surface_seen_fraction) || !(fit.rms_mm >= 0.0f) ||
        !std::isfinite(fit.rms_mm)) {
      return Invalid(absl::StrCat("frame ", frame, " has a sensor fit out of range"));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckDoubtfulSpans(const std::vector<DoubtfulSpan>& spans, size_t frames) {
  int after = 0;  // The first frame a span may start at.
  for (size_t k = 0; k < spans.size(); ++k) {
    const DoubtfulSpan& span = spans[k];
    if (span.first_frame < after || span.last_frame < span.first_frame ||
        static_cast<size_t>(span.last_frame) >= frames) {
      return Invalid(absl::StrCat("doubtful span ", k, " (frames ", span.first_frame, "..",
                                  span.last_frame, ") is out of order or past the ", frames,
                                  " frames"));
    }
    if (!std::isfinite(span.start_s) || !std::isfinite(span.end_s) || span.end_s < span.start_s) {
      return Invalid(absl::StrCat("doubtful span ", k, " has bad times"));
    }
    after = span.last_frame + 1;
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateReenactment(const Reenactment& data) {
  if (data.info.frame_count != static_cast<int64_t>(data.frames.size())) {
    return Invalid(absl::StrCat("frame_count is ", data.info.frame_count, " but there are ",
                                data.frames.size(), " frames"));
  }
  for (size_t f = 0; f < data.frames.size(); ++f) {
    const ReenactmentFrame& frame = data.frames[f];
    if (frame.parts.size() != data.parts.size()) {
      return Invalid(absl::StrCat("frame ", f, " has ", frame.parts.size(),
                                  " part poses, expected ", data.parts.size()));
    }
    if (!frame.joints_in_world_m.empty() &&
        frame.joints_in_world_m.size() != static_cast<size_t>(body::kNumKinectV2Joints)) {
      return Invalid(absl::StrCat("frame ", f, " has ", frame.joints_in_world_m.size(),
                                  " joints, expected 0 or 25"));
    }
    if (frame.body.has_value()) {
      RETURN_IF_ERROR(CheckSensorFits(frame.body->sensor_fits, data.info.sensors.size(), f));
    }
  }
  RETURN_IF_ERROR(CheckDoubtfulSpans(data.info.doubtful_spans, data.frames.size()));
  if (data.is_body()) return CheckBody(data);
  const size_t part_count = data.info.part_names.size();
  if (part_count == 0) return Invalid("no part names");
  if (data.parts.size() != part_count) {
    return Invalid(absl::StrCat(data.parts.size(), " part meshes for ", part_count, " part names"));
  }
  for (size_t p = 0; p < part_count; ++p) {
    RETURN_IF_ERROR(CheckPart(data.parts[p], static_cast<int>(p), data.info.part_names[p]));
  }
  for (size_t k = 0; k < data.keyframes.size(); ++k) {
    const TextureKeyframe& keyframe = data.keyframes[k];
    const std::string what = absl::StrCat("keyframe ", k);
    if (keyframe.frame_index < 0 ||
        keyframe.frame_index >= static_cast<int64_t>(data.frames.size())) {
      return Invalid(
          absl::StrCat(what, " names frame ", keyframe.frame_index, " of ", data.frames.size()));
    }
    const bool known =
        std::any_of(data.info.sensors.begin(), data.info.sensors.end(),
                    [&](const SensorCalibration& s) { return s.sensor_id == keyframe.sensor_id; });
    if (!known) {
      return Invalid(absl::StrCat(what, " names unknown sensor \"", keyframe.sensor_id, "\""));
    }
    if (keyframe.vertex_visible_bits.empty()) continue;
    if (keyframe.vertex_visible_bits.size() != part_count) {
      return Invalid(absl::StrCat(what, " has visibility of ", keyframe.vertex_visible_bits.size(),
                                  " parts, expected ", part_count));
    }
    for (size_t p = 0; p < part_count; ++p) {
      const auto expected = static_cast<size_t>((data.parts[p].num_vertices() + 7) / 8);
      if (keyframe.vertex_visible_bits[p].size() != expected) {
        return Invalid(absl::StrCat(what, " visibility of part ", p, " has ",
                                    keyframe.vertex_visible_bits[p].size(), " bytes, expected ",
                                    expected));
      }
    }
  }
  return absl::OkStatus();
}

Eigen::Affine3d PartPose::WorldFromPartScaled() const {
  Eigen::Affine3d out = Eigen::Affine3d::Identity();
  out.linear() = world_from_part.linear() * scale;
  out.translation() = world_from_part.translation();
  return out;
}

Eigen::Matrix3Xd BodyFramePose::OffsetsMetres() const {
  return vertex_offsets_50um.cast<double>() * kOffsetUnitM;
}

void BodyFramePose::SetOffsetsMetres(const Eigen::Matrix3Xd& offsets_m) {
  vertex_offsets_50um.resize(3, offsets_m.cols());
  for (Eigen::Index v = 0; v < offsets_m.cols(); ++v) {
    for (int c = 0; c < 3; ++c) {
      const double units = std::round(offsets_m(c, v) / kOffsetUnitM);
      vertex_offsets_50um(c, v) = static_cast<int16_t>(std::clamp(units, -32767.0, 32767.0));
    }
  }
}

absl::StatusOr<BodyMesh> BuildBodyMesh(const body::BodyModel& model, const Eigen::VectorXd& shape,
                                       std::string atlas_jpeg) {
  RETURN_IF_ERROR(body::ValidateBodyModel(model));
  ASSIGN_OR_RETURN(const Eigen::Matrix3Xd rest, body::ShapedRestVertices(model, shape));
  BodyMesh mesh;
  ASSIGN_OR_RETURN(mesh.rest_joints_m, body::RestJointPositions(model, shape));
  mesh.model_name = model.name;
  for (int k = 0; k < model.num_shape_components(); ++k) {
    mesh.shape.push_back(k < shape.size() ? shape[k] : 0.0);
    mesh.shape_names.push_back(k < static_cast<int>(model.shape_names.size())
                                   ? model.shape_names[k]
                                   : absl::StrCat("pc", k));
  }
  mesh.rest_vertices_m = rest.cast<float>().cast<double>();
  mesh.triangles = model.triangles;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    mesh.joint_names.emplace_back(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)));
  }
  mesh.skin_joints.resize(model.skin_joints.size());
  mesh.skin_weights.resize(model.skin_weights.size());
  for (size_t v = 0; v < model.skin_joints.size(); ++v) {
    for (int k = 0; k < body::kMaxInfluences; ++k) {
      const bool used = model.skin_weights[v][k] != 0.0f;
      mesh.skin_joints[v][k] = used ? model.skin_joints[v][k] : 0;
      mesh.skin_weights[v][k] = used ? model.skin_weights[v][k] : 0.0f;
    }
  }
  // Texture vertices: distinct (vertex, uv) pairs of the triangle corners.
  const bool has_uvs = !model.uv_triangles.empty();
  std::map<std::pair<int, int>, int> texture_vertex;
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    Eigen::Vector3i corners;
    for (int c = 0; c < 3; ++c) {
      const int vertex = model.triangles[t][c];
      const int uv = has_uvs ? model.uv_triangles[t][c] : -1;
      auto [it, inserted] = texture_vertex.emplace(std::make_pair(vertex, uv),
                                                   static_cast<int>(texture_vertex.size()));
      if (inserted) {
        mesh.texture_vertex_source.push_back(static_cast<uint32_t>(vertex));
        mesh.texture_uvs.push_back(has_uvs ? model.uvs[uv] : Eigen::Vector2f::Zero());
      }
      corners[c] = it->second;
    }
    mesh.texture_triangles.push_back(corners);
  }
  mesh.atlas_jpeg = std::move(atlas_jpeg);
  return mesh;
}

absl::StatusOr<body::PosedBody> PoseBodyMesh(const BodyMesh& mesh, const BodyFramePose& pose) {
  const Eigen::Index offsets = pose.vertex_offsets_50um.cols();
  if (offsets != 0 && offsets != mesh.num_vertices()) {
    return absl::InvalidArgumentError(absl::StrCat("the pose has offsets of ", offsets,
                                                   " vertices, the mesh ", mesh.num_vertices()));
  }
  absl::StatusOr<body::PosedBody> posed = body::SkinRestVertices(
      mesh.skin_joints, mesh.skin_weights, mesh.rest_vertices_m, mesh.rest_joints_m, pose.pose);
  if (posed.ok() && offsets > 0) posed->vertices_m += pose.OffsetsMetres();
  return posed;
}

}  // namespace reenact
