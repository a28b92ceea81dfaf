#include "clients/view/truth_reenactment.h"

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <set>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "absl/strings/str_cat.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/status_macros.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/reenactment_file.h"
#include "common/io/take_convert.h"
#include "common/render/mesh_data.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::view::testing {
namespace {

using body::KinectV2Joint;
using J = KinectV2Joint;
constexpr int kNumParts = 15;

constexpr std::array<const char*, kNumParts> kPartNames = {
    "head",      "chest",           "abdomen",       "upper_arm_left", "forearm_left",
    "hand_left", "upper_arm_right", "forearm_right", "hand_right",     "thigh_left",
    "shin_left", "foot_left",       "thigh_right",   "shin_right",     "foot_right"};

// Proximal and distal joint of each part.
constexpr std::array<std::pair<J, J>, kNumParts> kPartJoints = {{
    {J::kNeck, J::kHead},
    {J::kSpineMid, J::kSpineShoulder},
    {J::kSpineBase, J::kSpineMid},
    {J::kShoulderLeft, J::kElbowLeft},
    {J::kElbowLeft, J::kWristLeft},
    {J::kWristLeft, J::kHandTipLeft},
    {J::kShoulderRight, J::kElbowRight},
    {J::kElbowRight, J::kWristRight},
    {J::kWristRight, J::kHandTipRight},
    {J::kHipLeft, J::kKneeLeft},
    {J::kKneeLeft, J::kAnkleLeft},
    {J::kAnkleLeft, J::kFootLeft},
    {J::kHipRight, J::kKneeRight},
    {J::kKneeRight, J::kAnkleRight},
    {J::kAnkleRight, J::kFootRight},
}};

// The part a vertex belongs to, by the joint that moves it most (a joint
// moves the bones that leave it, so the part whose proximal joint it is).
constexpr std::array<int, body::kNumKinectV2Joints> kPartOfJoint = {
    2,  1,  0,  0,   // SpineBase, SpineMid, Neck, Head.
    3,  4,  5,  5,   // ShoulderLeft, ElbowLeft, WristLeft, HandLeft.
    6,  7,  8,  8,   // The same, right.
    9,  10, 11, 11,  // HipLeft, KneeLeft, AnkleLeft, FootLeft.
    12, 13, 14, 14,  // The same, right.
    1,               // SpineShoulder.
    5,  5,  8,  8};  // HandTipLeft, ThumbLeft, HandTipRight, ThumbRight.

body::BodyPose PoseFromProto(const v1::GroundTruthBody& message) {
  body::BodyPose pose;
  for (int j = 0; j < body::kNumKinectV2Joints && j < message.local_rotations_size(); ++j) {
    pose.local_rotation[j] = FromProto(message.local_rotations(j)).normalized();
  }
  pose.root_translation_m = FromProto(message.root_translation_in_world_m());
  return pose;
}

// Origin at the proximal joint, +Y toward the distal one, X and Z any
// orthonormal completion.
Eigen::Isometry3d PartFrame(const body::PosedBody& posed, int part) {
  const Eigen::Vector3d proximal = posed.joints_m[Index(kPartJoints[part].first)];
  const Eigen::Vector3d y =
      (posed.joints_m[Index(kPartJoints[part].second)] - proximal).normalized();
  const Eigen::Vector3d reference =
      std::abs(y.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d x = (reference - y * y.dot(reference)).normalized();
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear().col(0) = x;
  frame.linear().col(1) = y;
  frame.linear().col(2) = x.cross(y);
  frame.translation() = proximal;
  return frame;
}

struct Parts {
  std::vector<PartMesh> meshes;
  std::vector<Eigen::Matrix3Xd> positions;  // Part frame.
  std::vector<Eigen::Matrix3Xd> normals;    // Part frame.
  std::vector<std::vector<Eigen::Vector3i>> triangles;
  std::vector<Eigen::Isometry3d> part_from_joint;  // F_b(0)^-1 G_p(0).
};

Parts CutParts(const body::BodyModel& model, const body::PosedBody& posed0) {
  std::vector<int> part_of_vertex(model.num_vertices());
  for (int v = 0; v < model.num_vertices(); ++v) {
    int best = 0;
    for (int i = 1; i < body::kMaxInfluences; ++i) {
      if (model.skin_weights[v][i] > model.skin_weights[v][best]) best = i;
    }
    part_of_vertex[v] = kPartOfJoint[model.skin_joints[v][best]];
  }
  const Eigen::Matrix3Xf normals0 =
      render::ComputeVertexNormals(posed0.vertices_m.cast<float>(), model.triangles);
  Parts parts;
  parts.meshes.resize(kNumParts);
  parts.positions.resize(kNumParts);
  parts.normals.resize(kNumParts);
  parts.triangles.resize(kNumParts);
  std::vector<std::map<int, int>> local(kNumParts);
  std::vector<std::vector<int>> source(kNumParts);
  for (const Eigen::Vector3i& t : model.triangles) {
    // Majority vote of the corners; a tie goes to the first corner.
    int part = part_of_vertex[t[0]];
    if (part_of_vertex[t[1]] == part_of_vertex[t[2]]) part = part_of_vertex[t[1]];
    Eigen::Vector3i local_triangle;
    for (int c = 0; c < 3; ++c) {
      auto [it, inserted] = local[part].emplace(t[c], static_cast<int>(source[part].size()));
      if (inserted) source[part].push_back(t[c]);
      local_triangle[c] = it->second;
    }
    parts.triangles[part].push_back(local_triangle);
  }
  for (int b = 0; b < kNumParts; ++b) {
    const Eigen::Isometry3d frame0 = PartFrame(posed0, b);
    const Eigen::Isometry3d part_from_world = frame0.inverse();
    const int n = static_cast<int>(source[b].size());
    Eigen::Matrix3Xf positions(3, n), normals(3, n);
    for (int i = 0; i < n; ++i) {
      positions.col(i) = (part_from_world * posed0.vertices_m.col(source[b][i])).cast<float>();
      normals.col(i) =
          (part_from_world.linear() * normals0.col(source[b][i]).cast<double>()).cast<float>();
    }
    PartMesh& mesh = parts.meshes[b];
    mesh.part = b;
    mesh.name = kPartNames[b];
    mesh.positions_in_part_m = positions;
    mesh.normals_in_part = normals;
    mesh.uvs = Eigen::Matrix2Xf::Zero(2, n);  // No baked texture.
    mesh.triangles = parts.triangles[b];
    const J proximal = kPartJoints[b].first, distal = kPartJoints[b].second;
    mesh.reference_length_m = static_cast<float>(
        (posed0.joints_m[Index(distal)] - posed0.joints_m[Index(proximal)]).norm());
    parts.positions[b] = positions.cast<double>();
    parts.normals[b] = normals.cast<double>();
    parts.part_from_joint.push_back(frame0.inverse() * posed0.world_from_joint[Index(proximal)]);
  }
  return parts;
}

ReenactmentFrame MakeFrame(const Parts& parts, const body::PosedBody& posed, int frame_index,
                           int64_t stamp_ns) {
  ReenactmentFrame frame;
  frame.frame_index = frame_index;
  frame.stamp_ns = stamp_ns;
  for (int b = 0; b < kNumParts; ++b) {
    // F_b(n) = G_p(n) G_p(0)^-1 F_b(0): the part moves with its proximal joint.
    const Eigen::Isometry3d world_from_part =
        posed.world_from_joint[Index(kPartJoints[b].first)] * parts.part_from_joint[b].inverse();
    PartPose& pose = frame.parts.emplace_back();
    // The rotation re-orthonormalised through a unit quaternion, as a file
    // stores it.
    pose.world_from_part.linear() =
        Eigen::Quaterniond(world_from_part.linear()).normalized().toRotationMatrix();
    pose.world_from_part.translation() = world_from_part.translation();
    pose.scale = 1.0;
    pose.valid = true;
  }
  frame.joints_in_world_m.assign(posed.joints_m.begin(), posed.joints_m.end());
  return frame;
}

// Mask (truth silhouette) and vertex visibility of one colour camera.
absl::StatusOr<TextureKeyframe> MakeKeyframe(render::OffscreenRenderer* renderer,
                                             const Parts& parts, const ReenactmentFrame& frame,
                                             const body::PosedBody& posed,
                                             const std::vector<Eigen::Vector3i>& truth_triangles,
                                             const SensorCalibration& sensor,
                                             const v1::ColorImage& colour, double tolerance_m) {
  const CameraIntrinsics& intrinsics = sensor.color_intrinsics;
  RETURN_IF_ERROR(intrinsics.Validate());
  const int w = intrinsics.width, h = intrinsics.height;
  ASSIGN_OR_RETURN(render::RenderCamera camera, SensorRenderCamera(sensor, w, h));
  // Truth silhouette -> mask.
  render::MeshData truth_mesh;
  truth_mesh.positions_m = posed.vertices_m.cast<float>();
  truth_mesh.triangles = truth_triangles;
  ASSIGN_OR_RETURN(render::MeshId truth_id, renderer->UploadMesh(truth_mesh));
  render::DrawItem truth_item;
  truth_item.mesh = truth_id;
  render::RenderOutputs truth_out;
  truth_out.requested = render::kRenderLabel;
  RETURN_IF_ERROR(renderer->Render(camera, {truth_item}, &truth_out));
  RETURN_IF_ERROR(renderer->ReleaseMesh(truth_id));
  // Depth of all posed parts (Fig. 3.7).
  std::vector<render::DrawItem> items;
  std::vector<Eigen::Isometry3d> world_from_part(kNumParts);
  for (int b = 0; b < kNumParts; ++b) {
    world_from_part[b] = frame.parts[b].world_from_part;
    render::MeshData mesh;
    mesh.positions_m = parts.positions[b].cast<float>();
    mesh.triangles = parts.triangles[b];
    if (mesh.triangles.empty()) continue;
    render::DrawItem item;
    ASSIGN_OR_RETURN(item.mesh, renderer->UploadMesh(mesh));
    item.world_from_model = world_from_part[b];
    items.push_back(item);
  }
  render::RenderOutputs depth;
  depth.requested = render::kRenderDepth;
  const absl::Status rendered = renderer->Render(camera, items, &depth);
  for (const render::DrawItem& item : items) RETURN_IF_ERROR(renderer->ReleaseMesh(item.mesh));
  RETURN_IF_ERROR(rendered);
  TextureKeyframe keyframe;
  keyframe.frame_index = frame.frame_index;
  keyframe.sensor_id = sensor.sensor_id;
  keyframe.stamp_ns = colour.host_stamp_ns();
  keyframe.color_jpeg = colour.data();
  MaskImage mask(w, h);
  for (size_t i = 0; i < mask.data.size(); ++i) mask.data[i] = truth_out.label.data[i] > 0 ? 1 : 0;
  keyframe.mask_rle = EncodeMaskRle(mask);
  const Eigen::Isometry3d color_from_world = camera.world_from_camera.inverse();
  const Eigen::Vector3d centre = camera.world_from_camera.translation();
  for (int b = 0; b < kNumParts; ++b) {
    const int n = static_cast<int>(parts.positions[b].cols());
    std::string bits((n + 7) / 8, '\0');
    for (int v = 0; v < n; ++v) {
      const Eigen::Vector3d x = world_from_part[b] * parts.positions[b].col(v);
      const Eigen::Vector3d normal = world_from_part[b].linear() * parts.normals[b].col(v);
      const Eigen::Vector3d x_camera = color_from_world * x;
      const auto pixel = intrinsics.Project(x_camera);
      if (!pixel || !intrinsics.IsInside(*pixel) || normal.dot(x - centre) >= 0) continue;
      const int px = static_cast<int>(std::lround(pixel->x())),
                py = static_cast<int>(std::lround(pixel->y()));
      if (px < 0 || py < 0 || px >= w || py >= h) continue;
      const float z = depth.depth_m.at(px, py);
      if (z <= 0 || x_camera.z() - z > tolerance_m || mask.at(px, py) == 0) continue;
      bits[v / 8] = static_cast<char>(bits[v / 8] | (1 << (v % 8)));
    }
    keyframe.vertex_visible_bits.push_back(std::move(bits));
  }
  return keyframe;
}

// The truth's albedo (PNG) as a JPEG atlas.
absl::StatusOr<std::string> AlbedoJpeg(const std::string& png) {
  const cv::Mat encoded(1, static_cast<int>(png.size()), CV_8UC1, const_cast<char*>(png.data()));
  const cv::Mat bgr = cv::imdecode(encoded, cv::IMREAD_COLOR);
  std::vector<uint8_t> jpeg;
  if (bgr.empty() || !cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95})) {
    return absl::FailedPreconditionError("the take's albedo is not a decodable PNG");
  }
  return std::string(jpeg.begin(), jpeg.end());
}

// The true meshes by frame index (3 x V each, model vertex order).
absl::StatusOr<std::map<int64_t, Eigen::Matrix3Xd>> TruthMeshes(const TakeReader& take,
                                                                int vertex_count) {
  std::map<int64_t, Eigen::Matrix3Xd> meshes;
  RETURN_IF_ERROR(take.ForEach<v1::GroundTruthMesh>(
      kGroundTruthMeshTopic, [&](const v1::GroundTruthMesh& mesh) -> absl::Status {
        ASSIGN_OR_RETURN(const std::vector<float> values,
                         UnpackFloats(mesh.positions_in_world_m_f32()));
        if (mesh.vertex_count() != vertex_count || values.size() != 3u * vertex_count) {
          return absl::FailedPreconditionError(
              absl::StrCat("ground truth mesh of frame ", mesh.frame_index(), " has ",
                           mesh.vertex_count(), " vertices, the model ", vertex_count));
        }
        meshes[mesh.frame_index()] =
            Eigen::Map<const Eigen::Matrix3Xf>(values.data(), 3, vertex_count).cast<double>();
        return absl::OkStatus();
      }));
  return meshes;
}

}  // namespace

absl::StatusOr<Reenactment> MakeTruthBodyReenactment(const TakeReader& take,
                                                     const body::BodyModel& model) {
  ASSIGN_OR_RETURN(auto bodies, take.ReadAll<v1::GroundTruthBody>(kGroundTruthBodyTopic));
  ASSIGN_OR_RETURN(auto topologies,
                   take.ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic));
  if (bodies.empty() || topologies.empty()) {
    return absl::FailedPreconditionError("take has no /ground_truth/body or topology");
  }
  ASSIGN_OR_RETURN(const auto meshes, TruthMeshes(take, model.num_vertices()));
  Eigen::VectorXd shape(bodies[0].shape_coefficients_size());
  for (int k = 0; k < shape.size(); ++k) shape[k] = bodies[0].shape_coefficients(k);
  ASSIGN_OR_RETURN(std::string atlas, AlbedoJpeg(topologies[0].albedo_png()));
  Reenactment data;
  ReenactmentInfo& info = data.info;
  info.reenactment_id = "r-truth-body";
  info.take_id = take.info().name();
  info.method = "body";
  info.frame_count = static_cast<int>(bodies.size());
  info.fps = take.info().fps();
  info.generator = "truth_reenactment (test)";
  ASSIGN_OR_RETURN(info.sensors, TakeSensorCalibrations(take));
  ASSIGN_OR_RETURN(data.body, BuildBodyMesh(model, shape, std::move(atlas)));
  for (size_t f = 0; f < bodies.size(); ++f) {
    const auto truth = meshes.find(static_cast<int64_t>(f));
    if (truth == meshes.end()) {
      return absl::FailedPreconditionError(absl::StrCat("no ground truth mesh for frame ", f));
    }
    ReenactmentFrame& frame = data.frames.emplace_back();
    frame.frame_index = static_cast<int>(f);
    frame.stamp_ns = bodies[f].stamp_ns();
    BodyFramePose& pose = frame.body.emplace();
    pose.pose = PoseFromProto(bodies[f]);
    pose.valid = true;
    ASSIGN_OR_RETURN(const body::PosedBody skinned, PoseBodyMesh(*data.body, pose));
    pose.SetOffsetsMetres(truth->second - skinned.vertices_m);
    frame.joints_in_world_m.assign(skinned.joints_m.begin(), skinned.joints_m.end());
  }
  return data;
}

absl::StatusOr<Reenactment> MakeTruthReenactment(const TakeReader& take,
                                                 const body::BodyModel& model,
                                                 const TruthReenactmentOptions& options) {
  ASSIGN_OR_RETURN(auto bodies, take.ReadAll<v1::GroundTruthBody>(kGroundTruthBodyTopic));
  if (bodies.empty()) return absl::FailedPreconditionError("take has no /ground_truth/body");
  std::vector<body::PosedBody> posed;
  for (const v1::GroundTruthBody& message : bodies) {
    Eigen::VectorXd shape(message.shape_coefficients_size());
    for (int k = 0; k < shape.size(); ++k) shape[k] = message.shape_coefficients(k);
    ASSIGN_OR_RETURN(body::PosedBody p, body::PoseBody(model, PoseFromProto(message), shape));
    posed.push_back(std::move(p));
  }
  Reenactment data;
  ReenactmentInfo& info = data.info;
  info.reenactment_id = "r-truth";
  info.take_id = take.info().name();
  info.method = options.method;
  info.frame_count = static_cast<int>(bodies.size());
  info.fps = take.info().fps();
  info.generator = "truth_reenactment (test)";
  info.part_names.assign(kPartNames.begin(), kPartNames.end());
  ASSIGN_OR_RETURN(info.sensors, TakeSensorCalibrations(take));
  Parts parts = CutParts(model, posed[0]);
  data.parts = parts.meshes;
  for (size_t f = 0; f < bodies.size(); ++f) {
    data.frames.push_back(MakeFrame(parts, posed[f], static_cast<int>(f), bodies[f].stamp_ns()));
  }
  // Keyframes: colour images of every k-th instant, every sensor.
  int max_w = 16, max_h = 16;
  for (const SensorCalibration& sensor : info.sensors) {
    max_w = std::max(max_w, sensor.color_intrinsics.width);
    max_h = std::max(max_h, sensor.color_intrinsics.height);
  }
  render::RendererOptions renderer_options;
  renderer_options.max_width = max_w;
  renderer_options.max_height = max_h;
  ASSIGN_OR_RETURN(auto renderer, render::OffscreenRenderer::Create(renderer_options));
  for (const SensorCalibration& sensor : info.sensors) {
    RETURN_IF_ERROR(take.ForEach<v1::ColorImage>(
        SensorTopic(sensor.sensor_id, "color"), [&](const v1::ColorImage& colour) -> absl::Status {
          const int64_t f = colour.frame_index();
          if (f < 0 || f >= static_cast<int64_t>(posed.size()) || f % options.keyframe_every != 0) {
            return absl::OkStatus();
          }
          ASSIGN_OR_RETURN(
              TextureKeyframe keyframe,
              MakeKeyframe(renderer.get(), parts, data.frames[f], posed[f], model.triangles, sensor,
                           colour, options.visibility_tolerance_m));
          data.keyframes.push_back(std::move(keyframe));
          return absl::OkStatus();
        }));
  }
  RETURN_IF_ERROR(ValidateReenactment(data));
  return data;
}

void PerturbPoses(Reenactment* data, const Eigen::Vector3d& offset_m, double angle_deg) {
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX())
          .toRotationMatrix();
  for (ReenactmentFrame& frame : data->frames) {
    for (PartPose& pose : frame.parts) {
      pose.world_from_part.linear() = pose.world_from_part.linear() * turn;
      pose.world_from_part.translation() += offset_m;
    }
  }
}

}  // namespace reenact::view::testing
