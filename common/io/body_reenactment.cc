#include "common/io/body_reenactment.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_file.h"

namespace reenact {
namespace {

// BodyPose.vertex_offsets_50um_i16 holds 3 int16 per vertex, or nothing.
absl::Status CheckOffsetBytes(const std::string& bytes, int num_vertices) {
  if (!bytes.empty() && bytes.size() != 6 * static_cast<size_t>(num_vertices)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "vertex offsets hold ", bytes.size(), " bytes for ", num_vertices, " vertices (6 each)"));
  }
  return absl::OkStatus();
}

absl::Status Invalid(const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat("invalid body mesh: ", what));
}

bool FiniteVector(const v1::Vector3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

absl::StatusOr<std::vector<float>> UnpackCount(const std::string& bytes, size_t per_item,
                                               size_t items, const std::string& what) {
  ASSIGN_OR_RETURN(std::vector<float> values, UnpackFloats(bytes));
  if (values.size() != per_item * items) {
    return Invalid(
        absl::StrCat(what, " holds ", values.size(), " floats, expected ", per_item * items));
  }
  for (float v : values) {
    if (!std::isfinite(v)) return Invalid(what + " holds a non-finite number");
  }
  return values;
}

absl::StatusOr<std::vector<Eigen::Vector3i>> Triangles(
    const google::protobuf::RepeatedField<uint32_t>& indices, size_t vertex_count,
    const std::string& what) {
  if (indices.size() % 3 != 0) {
    return Invalid(absl::StrCat(what, " has ", indices.size(), " indices, not a multiple of 3"));
  }
  std::vector<Eigen::Vector3i> out(indices.size() / 3);
  for (int i = 0; i < indices.size(); ++i) {
    if (indices[i] >= vertex_count) {
      return Invalid(absl::StrCat(what, " index ", i, " = ", indices[i], " is out of range (",
                                  vertex_count, " vertices)"));
    }
    out[i / 3][i % 3] = static_cast<int>(indices[i]);
  }
  return out;
}

}  // namespace

absl::StatusOr<v1::BodyMesh> MakeBodyMesh(const body::BodyModel& model,
                                          const Eigen::VectorXd& shape, std::string atlas_jpeg) {
  ASSIGN_OR_RETURN(const BodyMesh mesh, BuildBodyMesh(model, shape, std::move(atlas_jpeg)));
  return BodyMeshToProto(mesh);
}

absl::StatusOr<DecodedBodyMesh> DecodeBodyMesh(const v1::BodyMesh& mesh) {
  DecodedBodyMesh out;
  ASSIGN_OR_RETURN(const std::vector<float> positions, UnpackFloats(mesh.rest_positions_m_f32()));
  if (positions.empty() || positions.size() % 3 != 0) {
    return Invalid(absl::StrCat("rest positions hold ", positions.size(), " floats"));
  }
  const size_t vertex_count = positions.size() / 3;
  out.rest_vertices_m.resize(3, static_cast<Eigen::Index>(vertex_count));
  for (size_t v = 0; v < vertex_count; ++v) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(positions[3 * v + c])) return Invalid("a rest position is not finite");
      out.rest_vertices_m(c, static_cast<Eigen::Index>(v)) = positions[3 * v + c];
    }
  }
  ASSIGN_OR_RETURN(out.triangles, Triangles(mesh.triangle_indices(), vertex_count, "triangles"));
  if (out.triangles.empty()) return Invalid("no triangles");
  if (mesh.rest_joints_m_size() != body::kNumKinectV2Joints) {
    return Invalid(absl::StrCat(mesh.rest_joints_m_size(), " rest joints, expected ",
                                body::kNumKinectV2Joints));
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const v1::Vector3& p = mesh.rest_joints_m(j);
    if (!FiniteVector(p)) return Invalid(absl::StrCat("rest joint ", j, " is not finite"));
    out.rest_joints_m[j] = Eigen::Vector3d(p.x(), p.y(), p.z());
  }
  if (mesh.skin_joints_u8().size() != body::kMaxInfluences * vertex_count) {
    return Invalid(absl::StrCat("skin joints hold ", mesh.skin_joints_u8().size(),
                                " bytes, expected ", body::kMaxInfluences * vertex_count));
  }
  ASSIGN_OR_RETURN(
      const std::vector<float> weights,
      UnpackCount(mesh.skin_weights_f32(), body::kMaxInfluences, vertex_count, "skin weights"));
  out.skin_joints.resize(vertex_count);
  out.skin_weights.resize(vertex_count);
  for (size_t v = 0; v < vertex_count; ++v) {
    float sum = 0.0f;
    for (int k = 0; k < body::kMaxInfluences; ++k) {
      const int joint = static_cast<uint8_t>(mesh.skin_joints_u8()[body::kMaxInfluences * v + k]);
      const float weight = weights[body::kMaxInfluences * v + k];
      if (joint >= body::kNumKinectV2Joints || weight < 0.0f) {
        return Invalid(absl::StrCat("vertex ", v, " has a bad skin joint or weight"));
      }
      out.skin_joints[v][k] = joint;
      out.skin_weights[v][k] = weight;
      sum += weight;
    }
    if (std::abs(sum - 1.0f) > 1e-3f) {
      return Invalid(absl::StrCat("skin weights of vertex ", v, " sum to ", sum));
    }
  }
  const size_t texture_count = static_cast<size_t>(mesh.texture_vertex_source_size());
  for (uint32_t source : mesh.texture_vertex_source()) {
    if (source >= vertex_count) return Invalid("a texture vertex names a missing vertex");
    out.texture_vertex_source.push_back(source);
  }
  ASSIGN_OR_RETURN(const std::vector<float> uvs,
                   UnpackCount(mesh.texture_uvs_f32(), 2, texture_count, "texture uvs"));
  for (size_t i = 0; i < texture_count; ++i)
    out.texture_uvs.emplace_back(uvs[2 * i], uvs[2 * i + 1]);
  ASSIGN_OR_RETURN(out.texture_triangles,
                   Triangles(mesh.texture_triangle_indices(), texture_count, "texture triangles"));
  if (out.texture_triangles.size() != out.triangles.size()) {
    return Invalid(absl::StrCat(out.texture_triangles.size(), " texture triangles for ",
                                out.triangles.size(), " triangles"));
  }
  for (size_t t = 0; t < out.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      if (static_cast<int>(out.texture_vertex_source[out.texture_triangles[t][c]]) !=
          out.triangles[t][c]) {
        return Invalid(absl::StrCat("texture triangle ", t, " does not sit on triangle ", t));
      }
    }
  }
  for (double s : mesh.shape()) {
    if (!std::isfinite(s)) return Invalid("a shape coefficient is not finite");
  }
  out.model_name = mesh.model_name();
  out.shape.assign(mesh.shape().begin(), mesh.shape().end());
  out.shape_names.assign(mesh.shape_names().begin(), mesh.shape_names().end());
  out.joint_names.assign(mesh.joint_names().begin(), mesh.joint_names().end());
  out.atlas_jpeg = mesh.atlas_jpeg();
  // The appearance video is kept as it is: a video that does not decode, or
  // does not match the frames, is the viewers' to report (they fall back to
  // the static atlas), not a reason to refuse the reenactment.
  if (mesh.has_appearance()) {
    const v1::AppearanceVideo& video = mesh.appearance();
    out.appearance_mp4 = video.mp4();
    out.appearance_size_px = video.size_px();
    out.appearance_frame_count = video.frame_count();
    out.appearance_codec = video.codec();
  }
  return out;
}

absl::Status ValidateBodyPose(const v1::BodyPose& pose, int num_vertices, const std::string& what) {
  if (pose.local_rotations_size() != body::kNumKinectV2Joints) {
    return absl::InvalidArgumentError(absl::StrCat(what, " has ", pose.local_rotations_size(),
                                                   " rotations, expected ",
                                                   body::kNumKinectV2Joints));
  }
  for (const v1::Quaternion& q : pose.local_rotations()) {
    const double norm2 = q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z();
    if (!std::isfinite(norm2) || norm2 < 1e-12) {
      return absl::InvalidArgumentError(absl::StrCat(what, " has a bad rotation"));
    }
  }
  if (!FiniteVector(pose.root_translation_m())) {
    return absl::InvalidArgumentError(absl::StrCat(what, " has a non-finite root translation"));
  }
  if (!std::isfinite(pose.point_rms_mm())) {
    return absl::InvalidArgumentError(absl::StrCat(what, " has a non-finite point_rms_mm"));
  }
  if (absl::Status status = CheckOffsetBytes(pose.vertex_offsets_50um_i16(), num_vertices);
      !status.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": ", status.message()));
  }
  return absl::OkStatus();
}

v1::BodyPose BodyPoseToProto(const body::BodyPose& pose) {
  v1::BodyPose out;
  for (const Eigen::Quaterniond& q : pose.local_rotation) {
    v1::Quaternion* r = out.add_local_rotations();
    r->set_w(q.w());
    r->set_x(q.x());
    r->set_y(q.y());
    r->set_z(q.z());
  }
  out.mutable_root_translation_m()->set_x(pose.root_translation_m.x());
  out.mutable_root_translation_m()->set_y(pose.root_translation_m.y());
  out.mutable_root_translation_m()->set_z(pose.root_translation_m.z());
  out.set_valid(true);
  return out;
}

absl::StatusOr<body::BodyPose> BodyPoseFromProto(const v1::BodyPose& pose) {
  if (pose.local_rotations_size() != body::kNumKinectV2Joints) {
    return absl::InvalidArgumentError(absl::StrCat("body pose has ", pose.local_rotations_size(),
                                                   " rotations, expected ",
                                                   body::kNumKinectV2Joints));
  }
  body::BodyPose out;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const v1::Quaternion& q = pose.local_rotations(j);
    out.local_rotation[j] = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());
    const double norm = out.local_rotation[j].norm();
    if (!std::isfinite(norm) || norm < 1e-6) {
      return absl::InvalidArgumentError(absl::StrCat("body pose rotation ", j, " is invalid"));
    }
    out.local_rotation[j].normalize();
  }
  const v1::Vector3& t = pose.root_translation_m();
  out.root_translation_m = Eigen::Vector3d(t.x(), t.y(), t.z());
  if (!out.root_translation_m.allFinite()) {
    return absl::InvalidArgumentError("body pose root translation is not finite");
  }
  return out;
}

absl::StatusOr<VertexOffsets50um> BodyPoseOffsets(const v1::BodyPose& pose, int num_vertices) {
  const std::string& bytes = pose.vertex_offsets_50um_i16();
  RETURN_IF_ERROR(CheckOffsetBytes(bytes, num_vertices));
  if (bytes.empty()) return VertexOffsets50um();
  VertexOffsets50um out(3, num_vertices);
  for (size_t i = 0; i < 3 * static_cast<size_t>(num_vertices); ++i) {
    const auto lo = static_cast<uint16_t>(static_cast<uint8_t>(bytes[2 * i]));
    const auto hi = static_cast<uint16_t>(static_cast<uint8_t>(bytes[2 * i + 1]));
    out(static_cast<Eigen::Index>(i % 3), static_cast<Eigen::Index>(i / 3)) =
        static_cast<int16_t>(static_cast<uint16_t>(lo | (hi << 8)));
  }
  return out;
}

void SetBodyPoseOffsets(const VertexOffsets50um& offsets, v1::BodyPose* pose) {
  std::string bytes(6 * static_cast<size_t>(offsets.cols()), '\0');
  for (Eigen::Index v = 0; v < offsets.cols(); ++v) {
    for (int c = 0; c < 3; ++c) {
      const auto bits = static_cast<uint16_t>(offsets(c, v));
      const size_t i = 3 * static_cast<size_t>(v) + c;
      bytes[2 * i] = static_cast<char>(bits & 0xFF);
      bytes[2 * i + 1] = static_cast<char>(bits >> 8);
    }
  }
  pose->set_vertex_offsets_50um_i16(std::move(bytes));
}

absl::StatusOr<body::PosedBody> PoseBodyMesh(const DecodedBodyMesh& mesh,
                                             const v1::BodyPose& pose) {
  BodyFramePose plain;
  ASSIGN_OR_RETURN(plain.pose, BodyPoseFromProto(pose));
  ASSIGN_OR_RETURN(plain.vertex_offsets_50um, BodyPoseOffsets(pose, mesh.num_vertices()));
  return PoseBodyMesh(mesh, plain);
}

}  // namespace reenact
