#include "common/io/reenactment_convert.h"

#include <cmath>
#include <cstdint>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/body_reenactment.h"
#include "common/io/proto_convert.h"

namespace reenact {
namespace {

absl::Status Invalid(const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat("invalid reenactment: ", what));
}

// A transform the message leaves unset reads as the identity.
absl::StatusOr<Rigid3d> TransformFromProto(const v1::SensorCalibration& message,
                                           const v1::Rigid3& transform, const char* name) {
  if (!transform.has_rotation() && !transform.has_translation_m()) return Rigid3d();
  absl::StatusOr<Rigid3d> out = FromProto(transform);
  if (!out.ok()) {
    return Invalid(
        absl::StrCat("sensor \"", message.sensor_id(), "\" ", name, ": ", out.status().message()));
  }
  return out;
}

std::vector<float> FlatFloats(const float* data, Eigen::Index count) {
  return std::vector<float>(data, data + count);
}

std::optional<methods::TextureMode> TextureModeFromProto(v1::TextureMode mode) {
  switch (mode) {
    case v1::TEXTURE_MODE_POSE_CLOSEST:
      return methods::TextureMode::kPoseClosest;
    case v1::TEXTURE_MODE_ROTATION_CLOSEST:
      return methods::TextureMode::kRotationClosest;
    case v1::TEXTURE_MODE_BODY_ATLAS:
      return methods::TextureMode::kBodyAtlas;
    default:
      return std::nullopt;
  }
}

absl::StatusOr<ReenactmentInfo> InfoFromProto(const v1::ReenactmentInfo& m) {
  ReenactmentInfo info;
  info.reenactment_id = m.reenactment_id();
  info.take_id = m.take_id();
  info.job_id = m.job_id();
  info.method = m.method();
  info.options.insert(m.options().begin(), m.options().end());
  info.created_unix_ns = m.created_unix_ns();
  info.generator = m.generator();
  info.frame_count = m.frame_count();
  info.fps = m.fps();
  info.part_names.assign(m.part_names().begin(), m.part_names().end());
  for (const v1::SensorCalibration& s : m.sensors()) {
    ASSIGN_OR_RETURN(SensorCalibration sensor, SensorCalibrationFromProto(s));
    info.sensors.push_back(std::move(sensor));
  }
  info.figures.insert(m.figures().begin(), m.figures().end());
  info.texture_mode = TextureModeFromProto(m.texture_mode());
  info.doubtful_spans.reserve(static_cast<size_t>(m.doubtful_spans_size()));
  for (const v1::DoubtfulSpan& span : m.doubtful_spans()) {
    info.doubtful_spans.push_back(
        {span.first_frame(), span.last_frame(), span.start_s(), span.end_s(), span.reason()});
  }
  return info;
}

v1::ReenactmentInfo InfoToProto(const ReenactmentInfo& info) {
  v1::ReenactmentInfo m;
  m.set_reenactment_id(info.reenactment_id);
  m.set_take_id(info.take_id);
  m.set_job_id(info.job_id);
  m.set_method(info.method);
  m.mutable_options()->insert(info.options.begin(), info.options.end());
  m.set_created_unix_ns(info.created_unix_ns);
  m.set_generator(info.generator);
  m.set_frame_count(info.frame_count);
  m.set_fps(info.fps);
  for (const std::string& name : info.part_names) m.add_part_names(name);
  for (const SensorCalibration& s : info.sensors) *m.add_sensors() = SensorCalibrationToProto(s);
  m.mutable_figures()->insert(info.figures.begin(), info.figures.end());
  m.set_texture_mode(info.texture_mode ? ToProto(*info.texture_mode)
                                       : v1::TEXTURE_MODE_UNSPECIFIED);
  for (const DoubtfulSpan& span : info.doubtful_spans) {
    v1::DoubtfulSpan* out = m.add_doubtful_spans();
    out->set_first_frame(span.first_frame);
    out->set_last_frame(span.last_frame);
    out->set_start_s(span.start_s);
    out->set_end_s(span.end_s);
    out->set_reason(span.reason);
  }
  return m;
}

}  // namespace

absl::StatusOr<PartMesh> PartMeshFromProto(const v1::PartMesh& m) {
  PartMesh mesh;
  mesh.part = m.part();
  mesh.name = m.name();
  ASSIGN_OR_RETURN(const std::vector<float> positions, UnpackFloats(m.positions_in_part_m_f32()));
  ASSIGN_OR_RETURN(const std::vector<float> normals, UnpackFloats(m.normals_in_part_f32()));
  ASSIGN_OR_RETURN(const std::vector<float> uvs, UnpackFloats(m.uvs_f32()));
  const auto n = static_cast<Eigen::Index>(positions.size() / 3);
  mesh.positions_in_part_m = Eigen::Map<const Eigen::Matrix3Xf>(positions.data(), 3, n);
  if (!normals.empty()) {
    mesh.normals_in_part = Eigen::Map<const Eigen::Matrix3Xf>(normals.data(), 3, n);
  }
  if (!uvs.empty()) mesh.uvs = Eigen::Map<const Eigen::Matrix2Xf>(uvs.data(), 2, n);
  mesh.triangles.reserve(static_cast<size_t>(m.triangle_indices_size() / 3));
  for (int i = 0; i + 2 < m.triangle_indices_size(); i += 3) {
    mesh.triangles.emplace_back(static_cast<int>(m.triangle_indices(i)),
                                static_cast<int>(m.triangle_indices(i + 1)),
                                static_cast<int>(m.triangle_indices(i + 2)));
  }
  mesh.baked_texture_jpeg = m.baked_texture_jpeg();
  mesh.radius_rate = m.radius_rate();
  mesh.reference_length_m = m.reference_length_m();
  return mesh;
}

v1::PartMesh PartMeshToProto(const PartMesh& mesh) {
  v1::PartMesh m;
  m.set_part(mesh.part);
  m.set_name(mesh.name);
  m.set_positions_in_part_m_f32(
      PackFloats(FlatFloats(mesh.positions_in_part_m.data(), mesh.positions_in_part_m.size())));
  m.set_normals_in_part_f32(
      PackFloats(FlatFloats(mesh.normals_in_part.data(), mesh.normals_in_part.size())));
  m.set_uvs_f32(PackFloats(FlatFloats(mesh.uvs.data(), mesh.uvs.size())));
  m.mutable_triangle_indices()->Reserve(static_cast<int>(3 * mesh.triangles.size()));
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) m.add_triangle_indices(static_cast<uint32_t>(t[c]));
  }
  m.set_baked_texture_jpeg(mesh.baked_texture_jpeg);
  m.set_radius_rate(mesh.radius_rate);
  m.set_reference_length_m(mesh.reference_length_m);
  return m;
}

namespace {

PartPose PartPoseFromProto(const v1::PartPose& m) {
  // A hidden part keeps the pose it was given where that pose is a rigid
  // transform (a method may hide a part it did pose).
  PartPose pose;
  const Eigen::Quaterniond q = FromProto(m.world_from_part().rotation());
  const Eigen::Vector3d t = FromProto(m.world_from_part().translation_m());
  if (!(q.norm() > 1e-9) || !std::isfinite(q.norm()) || !t.allFinite()) return pose;
  pose.world_from_part.linear() = q.normalized().toRotationMatrix();
  pose.world_from_part.translation() = t;
  pose.scale = m.scale() > 0 ? m.scale() : 1.0;
  pose.valid = m.valid();
  return pose;
}

v1::PartPose PartPoseToProto(const PartPose& pose) {
  v1::PartPose m;
  *m.mutable_world_from_part()->mutable_rotation() =
      ToProto(Eigen::Quaterniond(pose.world_from_part.linear()));
  *m.mutable_world_from_part()->mutable_translation_m() =
      ToProto(Eigen::Vector3d(pose.world_from_part.translation()));
  m.set_scale(static_cast<float>(pose.scale));
  m.set_valid(pose.valid);
  return m;
}

}  // namespace

TextureKeyframe KeyframeFromProto(const v1::TextureKeyframe& m) {
  TextureKeyframe k;
  k.frame_index = m.frame_index();
  k.sensor_id = m.sensor_id();
  k.stamp_ns = m.stamp_ns();
  k.color_jpeg = m.color_jpeg();
  k.crop_x_px = m.crop_x_px();
  k.crop_y_px = m.crop_y_px();
  k.mask_rle = m.mask_rle();
  k.vertex_visible_bits.assign(m.vertex_visible_bits().begin(), m.vertex_visible_bits().end());
  k.crop_scale = m.crop_scale();
  return k;
}

v1::TextureKeyframe KeyframeToProto(const TextureKeyframe& k) {
  v1::TextureKeyframe m;
  m.set_frame_index(k.frame_index);
  m.set_sensor_id(k.sensor_id);
  m.set_stamp_ns(k.stamp_ns);
  m.set_color_jpeg(k.color_jpeg);
  m.set_crop_x_px(k.crop_x_px);
  m.set_crop_y_px(k.crop_y_px);
  m.set_mask_rle(k.mask_rle);
  for (const std::string& bits : k.vertex_visible_bits) m.add_vertex_visible_bits(bits);
  m.set_crop_scale(k.crop_scale);
  return m;
}

absl::StatusOr<SensorCalibration> SensorCalibrationFromProto(const v1::SensorCalibration& m) {
  SensorCalibration s;
  s.sensor_id = m.sensor_id();
  s.model = m.model();
  s.serial = m.serial();
  s.depth_intrinsics = IntrinsicsAsStored(m.depth_intrinsics());
  s.color_intrinsics = IntrinsicsAsStored(m.color_intrinsics());
  ASSIGN_OR_RETURN(s.color_from_depth,
                   TransformFromProto(m, m.color_from_depth(), "color_from_depth"));
  ASSIGN_OR_RETURN(s.world_from_depth,
                   TransformFromProto(m, m.world_from_depth(), "world_from_depth"));
  s.clock_offset_ns = m.clock_offset_ns();
  s.depth_scale_m_per_unit = m.depth_scale_m_per_unit();
  s.nominal_fps = m.nominal_fps();
  s.world_anchor = m.world_anchor();
  s.world_anchor_rms_px = m.world_anchor_rms_px();
  return s;
}

v1::SensorCalibration SensorCalibrationToProto(const SensorCalibration& s) {
  v1::SensorCalibration m;
  m.set_sensor_id(s.sensor_id);
  m.set_model(s.model);
  m.set_serial(s.serial);
  *m.mutable_depth_intrinsics() = ToProto(s.depth_intrinsics);
  *m.mutable_color_intrinsics() = ToProto(s.color_intrinsics);
  *m.mutable_color_from_depth() = ToProto(s.color_from_depth);
  *m.mutable_world_from_depth() = ToProto(s.world_from_depth);
  m.set_clock_offset_ns(s.clock_offset_ns);
  m.set_depth_scale_m_per_unit(s.depth_scale_m_per_unit);
  m.set_nominal_fps(s.nominal_fps);
  m.set_world_anchor(s.world_anchor);
  m.set_world_anchor_rms_px(s.world_anchor_rms_px);
  return m;
}

absl::StatusOr<BodyMesh> BodyMeshFromProto(const v1::BodyMesh& message) {
  return DecodeBodyMesh(message);
}

v1::BodyMesh BodyMeshToProto(const BodyMesh& mesh) {
  v1::BodyMesh m;
  m.set_model_name(mesh.model_name);
  for (double s : mesh.shape) m.add_shape(s);
  for (const std::string& name : mesh.shape_names) m.add_shape_names(name);
  std::vector<float> positions(static_cast<size_t>(mesh.rest_vertices_m.size()));
  for (Eigen::Index v = 0; v < mesh.rest_vertices_m.cols(); ++v) {
    for (int c = 0; c < 3; ++c)
      positions[3 * v + c] = static_cast<float>(mesh.rest_vertices_m(c, v));
  }
  m.set_rest_positions_m_f32(PackFloats(positions));
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) m.add_triangle_indices(static_cast<uint32_t>(t[c]));
  }
  for (const Eigen::Vector3d& joint : mesh.rest_joints_m) *m.add_rest_joints_m() = ToProto(joint);
  for (const std::string& name : mesh.joint_names) m.add_joint_names(name);
  std::string skin_joints(body::kMaxInfluences * mesh.skin_joints.size(), '\0');
  for (size_t v = 0; v < mesh.skin_joints.size(); ++v) {
    for (int k = 0; k < body::kMaxInfluences; ++k) {
      skin_joints[body::kMaxInfluences * v + k] = static_cast<char>(mesh.skin_joints[v][k]);
    }
  }
  m.set_skin_joints_u8(std::move(skin_joints));
  std::vector<float> weights;
  weights.reserve(body::kMaxInfluences * mesh.skin_weights.size());
  for (const auto& w : mesh.skin_weights) weights.insert(weights.end(), w.begin(), w.end());
  m.set_skin_weights_f32(PackFloats(weights));
  for (uint32_t source : mesh.texture_vertex_source) m.add_texture_vertex_source(source);
  std::vector<float> uvs;
  uvs.reserve(2 * mesh.texture_uvs.size());
  for (const Eigen::Vector2f& uv : mesh.texture_uvs) {
    uvs.push_back(uv.x());
    uvs.push_back(uv.y());
  }
  m.set_texture_uvs_f32(PackFloats(uvs));
  for (const Eigen::Vector3i& t : mesh.texture_triangles) {
    for (int c = 0; c < 3; ++c) m.add_texture_triangle_indices(static_cast<uint32_t>(t[c]));
  }
  m.set_atlas_jpeg(mesh.atlas_jpeg);
  if (!mesh.appearance_mp4.empty()) {
    v1::AppearanceVideo& video = *m.mutable_appearance();
    video.set_mp4(mesh.appearance_mp4);
    video.set_size_px(mesh.appearance_size_px);
    video.set_frame_count(mesh.appearance_frame_count);
    video.set_codec(mesh.appearance_codec);
  }
  return m;
}

absl::StatusOr<BodyFramePose> BodyFramePoseFromProto(const v1::BodyPose& message,
                                                     int num_vertices) {
  RETURN_IF_ERROR(ValidateBodyPose(message, num_vertices, "body pose"));
  BodyFramePose pose;
  ASSIGN_OR_RETURN(pose.pose, BodyPoseFromProto(message));
  ASSIGN_OR_RETURN(pose.vertex_offsets_50um, BodyPoseOffsets(message, num_vertices));
  pose.valid = message.valid();
  pose.point_rms_mm = message.point_rms_mm();
  pose.sensor_fits.reserve(static_cast<size_t>(message.sensor_fits_size()));
  for (const v1::SensorFit& fit : message.sensor_fits()) {
    pose.sensor_fits.push_back({fit.sensor(), fit.points(), fit.explained_fraction(), fit.rms_mm(),
                                fit.surface_seen_fraction()});
  }
  return pose;
}

v1::BodyPose BodyFramePoseToProto(const BodyFramePose& pose) {
  v1::BodyPose m = BodyPoseToProto(pose.pose);
  if (pose.vertex_offsets_50um.cols() > 0) SetBodyPoseOffsets(pose.vertex_offsets_50um, &m);
  m.set_valid(pose.valid);
  m.set_point_rms_mm(pose.point_rms_mm);
  for (const SensorFit& fit : pose.sensor_fits) {
    v1::SensorFit* out = m.add_sensor_fits();
    out->set_sensor(fit.sensor);
    out->set_points(fit.points);
    out->set_explained_fraction(fit.explained_fraction);
    out->set_rms_mm(fit.rms_mm);
    out->set_surface_seen_fraction(fit.surface_seen_fraction);
  }
  return m;
}

absl::StatusOr<ReenactmentFrame> FrameFromProto(const v1::PartFrame& m, int num_vertices) {
  ReenactmentFrame frame;
  frame.frame_index = m.frame_index();
  frame.stamp_ns = m.stamp_ns();
  frame.parts.reserve(static_cast<size_t>(m.parts_size()));
  for (const v1::PartPose& pose : m.parts()) frame.parts.push_back(PartPoseFromProto(pose));
  frame.joints_in_world_m.reserve(static_cast<size_t>(m.joints_in_world_m_size()));
  for (const v1::Vector3& joint : m.joints_in_world_m()) {
    frame.joints_in_world_m.push_back(FromProto(joint));
  }
  if (m.has_body()) {
    ASSIGN_OR_RETURN(frame.body, BodyFramePoseFromProto(m.body(), num_vertices));
  }
  return frame;
}

v1::PartFrame FrameToProto(const ReenactmentFrame& frame) {
  v1::PartFrame m;
  m.set_frame_index(frame.frame_index);
  m.set_stamp_ns(frame.stamp_ns);
  for (const PartPose& pose : frame.parts) *m.add_parts() = PartPoseToProto(pose);
  for (const Eigen::Vector3d& joint : frame.joints_in_world_m) {
    *m.add_joints_in_world_m() = ToProto(joint);
  }
  if (frame.body) *m.mutable_body() = BodyFramePoseToProto(*frame.body);
  return m;
}

absl::StatusOr<Reenactment> ReenactmentFromProto(const ReenactmentData& data) {
  RETURN_IF_ERROR(ValidateReenactment(data));
  Reenactment out;
  ASSIGN_OR_RETURN(out.info, InfoFromProto(data.info));
  int num_vertices = 0;
  if (data.is_body()) {
    ASSIGN_OR_RETURN(out.body, BodyMeshFromProto(data.body.front()));
    num_vertices = out.body->num_vertices();
  }
  out.parts.reserve(data.parts.size());
  for (const v1::PartMesh& m : data.parts) {
    ASSIGN_OR_RETURN(PartMesh mesh, PartMeshFromProto(m));
    out.parts.push_back(std::move(mesh));
  }
  out.frames.reserve(data.frames.size());
  for (const v1::PartFrame& m : data.frames) {
    ASSIGN_OR_RETURN(ReenactmentFrame frame, FrameFromProto(m, num_vertices));
    out.frames.push_back(std::move(frame));
  }
  out.keyframes.reserve(data.keyframes.size());
  for (const v1::TextureKeyframe& k : data.keyframes) out.keyframes.push_back(KeyframeFromProto(k));
  return out;
}

ReenactmentData ReenactmentToProto(const Reenactment& reenactment) {
  ReenactmentData data;
  data.info = InfoToProto(reenactment.info);
  for (const PartMesh& mesh : reenactment.parts) data.parts.push_back(PartMeshToProto(mesh));
  for (const ReenactmentFrame& frame : reenactment.frames) {
    data.frames.push_back(FrameToProto(frame));
  }
  for (const TextureKeyframe& k : reenactment.keyframes) {
    data.keyframes.push_back(KeyframeToProto(k));
  }
  if (reenactment.body) data.body.push_back(BodyMeshToProto(*reenactment.body));
  return data;
}

absl::StatusOr<Reenactment> ReadReenactment(const std::string& path, bool skip_keyframes) {
  ASSIGN_OR_RETURN(const ReenactmentData data, ReadReenactmentFile(path, skip_keyframes));
  absl::StatusOr<Reenactment> out = ReenactmentFromProto(data);
  if (!out.ok()) {
    return absl::Status(out.status().code(), absl::StrCat(path, ": ", out.status().message()));
  }
  return out;
}

absl::Status WriteReenactment(const Reenactment& reenactment, const std::string& path) {
  return WriteReenactmentFile(ReenactmentToProto(reenactment), path);
}

}  // namespace reenact
