// Test-only: a small, valid, hand-built reenactment (box-shaped parts, a
// turning and travelling pose per frame, JPEG textures and keyframes), shared
// by the tests of the reenactment file, store, service, client and glTF
// export.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/body/procedural_body.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "common/io/reenactment_file.h"

namespace reenact::testing {

// The plain values of a test reenactment (ReenactmentFromProto); an empty
// reenactment after a test failure.
inline Reenactment ToPlain(const ReenactmentData& data) {
  absl::StatusOr<Reenactment> plain = ReenactmentFromProto(data);
  if (!plain.ok()) {
    ADD_FAILURE() << plain.status();
    return {};
  }
  return *std::move(plain);
}

// What MakeTestReenactment builds.
struct TestReenactmentOptions {
  int parts = 3;
  int frames = 5;
  // Keyframes at frames 0, 2, 4, ... of sensor "k0".
  int keyframes = 2;
  // Side of the square baked textures and keyframe images, pixels.
  int texture_px = 16;
  // Keyframe images of noise (big JPEGs, for tests of streaming limits).
  bool noisy_keyframes = false;
  // Part 1 is invalid (not posed) at frames below this.
  int part1_invalid_before = 1;
  std::string id = "r-20260101-120000-test";
};

// A JPEG of a w x h gradient tinted by `seed`, or of noise.
inline std::string TestJpeg(int w, int h, int seed, bool noise = false) {
  RgbImage image(w, h);
  uint32_t state = 2463534242u + static_cast<uint32_t>(seed);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      image.at(x, y, 0) = static_cast<uint8_t>((x * 255) / std::max(1, w - 1));
      image.at(x, y, 1) = static_cast<uint8_t>((y * 255) / std::max(1, h - 1));
      image.at(x, y, 2) = static_cast<uint8_t>((seed * 67) % 256);
      if (!noise) continue;
      for (int c = 0; c < 3; ++c) {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        image.at(x, y, c) = static_cast<uint8_t>(state);
      }
    }
  }
  auto jpeg = EncodeJpeg(image, 90);
  EXPECT_TRUE(jpeg.ok()) << jpeg.status();
  return jpeg.ok() ? *jpeg : std::string();
}

// An axis-aligned box from (-hx, 0, -hz) to (hx, 2 hy, hz) in the part frame,
// 24 vertices (4 per face, so normals and uvs are per face), 12 triangles
// counter-clockwise seen from outside.
inline v1::PartMesh TestBoxMesh(int part, const std::string& name, float hx, float hy, float hz) {
  std::vector<float> positions, normals, uvs;
  std::vector<uint32_t> indices;
  // For each face: normal n, and axes u, v with u x v = n.
  const float faces[6][9] = {{1, 0, 0, 0, 0, -1, 0, 1, 0}, {-1, 0, 0, 0, 0, 1, 0, 1, 0},
                             {0, 1, 0, 1, 0, 0, 0, 0, -1}, {0, -1, 0, 1, 0, 0, 0, 0, 1},
                             {0, 0, 1, 1, 0, 0, 0, 1, 0},  {0, 0, -1, -1, 0, 0, 0, 1, 0}};
  const float half[3] = {hx, hy, hz};
  for (int f = 0; f < 6; ++f) {
    const float* n = faces[f];
    const float* u = faces[f] + 3;
    const float* v = faces[f] + 6;
    const auto base = static_cast<uint32_t>(positions.size() / 3);
    for (int corner = 0; corner < 4; ++corner) {
      const float su = (corner == 1 || corner == 2) ? 1.f : -1.f;
      const float sv = (corner >= 2) ? 1.f : -1.f;
      for (int a = 0; a < 3; ++a) {
        const float p = (n[a] + su * u[a] + sv * v[a]) * half[a];
        positions.push_back(a == 1 ? p + hy : p);
        normals.push_back(n[a]);
      }
      uvs.push_back((f + (su + 1) / 2) / 6.f);
      uvs.push_back((sv + 1) / 2);
    }
    for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) indices.push_back(base + i);
  }
  v1::PartMesh mesh;
  mesh.set_part(part);
  mesh.set_name(name);
  mesh.set_positions_in_part_m_f32(PackFloats(positions));
  mesh.set_normals_in_part_f32(PackFloats(normals));
  mesh.set_uvs_f32(PackFloats(uvs));
  for (uint32_t i : indices) mesh.add_triangle_indices(i);
  mesh.set_radius_rate(0.f);
  mesh.set_reference_length_m(2 * hy);
  return mesh;
}

// The pose of `part` at `frame`: turning about +Y by 10 degrees per frame
// (plus 20 degrees per part), travelling along +X by 5 cm per frame.
inline v1::PartPose TestPose(int part, int frame) {
  v1::PartPose pose;
  const double angle = (10.0 * frame + 20.0 * part) * M_PI / 180.0;
  auto* r = pose.mutable_world_from_part()->mutable_rotation();
  r->set_w(std::cos(angle / 2));
  r->set_y(std::sin(angle / 2));
  auto* t = pose.mutable_world_from_part()->mutable_translation_m();
  t->set_x(0.05 * frame + 0.1 * part);
  t->set_y(1.0 - 0.2 * part);
  t->set_z(-0.01 * part);
  pose.set_scale(1.0f + 0.01f * part);
  pose.set_valid(true);
  return pose;
}

inline ReenactmentData MakeTestReenactment(const TestReenactmentOptions& o = {}) {
  ReenactmentData data;
  v1::ReenactmentInfo& info = data.info;
  info.set_reenactment_id(o.id);
  info.set_take_id("t-20260101-110000-abcd");
  info.set_job_id("j-1");
  info.set_method("rigid-carved");
  (*info.mutable_options())["mu_mm"] = "20";
  info.set_created_unix_ns(1767268800000000000);
  info.set_generator("testing/small_reenactment");
  info.set_frame_count(o.frames);
  info.set_fps(30.0);
  (*info.mutable_figures())["registration_rms_mm"] = 3.5;
  v1::SensorCalibration* sensor = info.add_sensors();
  sensor->set_sensor_id("k0");
  sensor->set_model("kinect_v2_synthetic");
  sensor->mutable_color_intrinsics()->set_width_px(64);
  sensor->mutable_color_intrinsics()->set_height_px(48);
  const char* names[] = {"head",         "chest",      "abdomen",         "upper_arm_left",
                         "forearm_left", "hand_left",  "upper_arm_right", "forearm_right",
                         "hand_right",   "thigh_left", "shin_left",       "foot_left",
                         "thigh_right",  "shin_right", "foot_right"};
  for (int p = 0; p < o.parts; ++p) {
    const std::string name = p < 15 ? names[p] : "part_" + std::to_string(p);
    info.add_part_names(name);
    v1::PartMesh mesh = TestBoxMesh(p, name, 0.05f + 0.01f * p, 0.1f, 0.04f);
    mesh.set_baked_texture_jpeg(TestJpeg(o.texture_px, o.texture_px, p));
    data.parts.push_back(std::move(mesh));
  }
  const int64_t start_ns = 5'000'000'000;
  const int64_t period_ns = 33'333'333;
  for (int f = 0; f < o.frames; ++f) {
    v1::PartFrame frame;
    frame.set_frame_index(f);
    frame.set_stamp_ns(start_ns + f * period_ns);
    for (int p = 0; p < o.parts; ++p) {
      v1::PartPose pose = TestPose(p, f);
      if (p == 1 && f < o.part1_invalid_before) pose.set_valid(false);
      *frame.add_parts() = pose;
    }
    for (int j = 0; j < 25; ++j) {
      v1::Vector3* joint = frame.add_joints_in_world_m();
      joint->set_x(0.01 * j + 0.05 * f);
      joint->set_y(0.05 * j);
      joint->set_z(0.0);
    }
    data.frames.push_back(std::move(frame));
  }
  for (int k = 0; k < o.keyframes && o.frames > 0; ++k) {
    v1::TextureKeyframe keyframe;
    keyframe.set_frame_index((2 * k) % o.frames);
    keyframe.set_sensor_id("k0");
    keyframe.set_stamp_ns(data.frames[keyframe.frame_index()].stamp_ns());
    keyframe.set_color_jpeg(TestJpeg(o.texture_px, o.texture_px, 100 + k, o.noisy_keyframes));
    keyframe.set_crop_x_px(8);
    keyframe.set_crop_y_px(4);
    for (int p = 0; p < o.parts; ++p) {
      // 24 vertices: 3 bytes; every other vertex visible.
      keyframe.add_vertex_visible_bits(std::string(3, '\x55'));
    }
    data.keyframes.push_back(std::move(keyframe));
  }
  return data;
}

// A coarse procedural body model (about 3,000 vertices; fast to build).
inline const body::BodyModel& TestBodyModel() {
  static const body::BodyModel* model = [] {
    body::ProceduralBodyOptions options;
    options.grid_spacing_m = 0.03;
    options.smoothing_iterations = 3;
    options.population_size = 40;
    options.num_held_out = 0;
    auto built = body::BuildProceduralBody(options);
    EXPECT_TRUE(built.ok()) << built.status();
    return new body::BodyModel(std::move(*built));
  }();
  return *model;
}

// The pose of frame `frame` of the test body reenactment: the right elbow
// bends, the body turns about +Y and walks along +X.
inline body::BodyPose TestBodyPose(int frame) {
  body::BodyPose pose;
  const double t = 0.1 * frame;
  pose.local_rotation[static_cast<int>(body::KinectV2Joint::kSpineBase)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * t, Eigen::Vector3d::UnitY()));
  pose.local_rotation[static_cast<int>(body::KinectV2Joint::kElbowRight)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.8 * t, Eigen::Vector3d::UnitX()));
  pose.root_translation_m = Eigen::Vector3d(0.05 * frame, 0.0, 0.0);
  return pose;
}

// A valid body-model reenactment of TestBodyModel() with shape (0.5, -0.5)
// and `frames` TestBodyPose frames; frame 1 carries vertex offsets of 5 mm
// along +Z when there is one.
inline ReenactmentData MakeTestBodyReenactment(int frames = 5,
                                               const std::string& id = "r-20260101-120000-body") {
  ReenactmentData data;
  v1::ReenactmentInfo& info = data.info;
  info.set_reenactment_id(id);
  info.set_take_id("t-20260101-110000-test");
  info.set_job_id("j-20260101-115900-test");
  info.set_method("body");
  info.set_created_unix_ns(1767268800000000000);
  info.set_generator("reenact test");
  info.set_frame_count(frames);
  info.set_fps(30.0);
  Eigen::VectorXd shape(2);
  shape << 0.5, -0.5;
  auto mesh = MakeBodyMesh(TestBodyModel(), shape, TestJpeg(64, 64, 7));
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  data.body.push_back(std::move(*mesh));
  const int vertices = TestBodyModel().num_vertices();
  for (int f = 0; f < frames; ++f) {
    v1::PartFrame frame;
    frame.set_frame_index(f);
    frame.set_stamp_ns(1000000000LL + f * 33333333LL);
    *frame.mutable_body() = BodyPoseToProto(TestBodyPose(f));
    if (f == 1) {
      VertexOffsets50um offsets = VertexOffsets50um::Zero(3, vertices);
      offsets.row(2).setConstant(100);  // 5 mm.
      SetBodyPoseOffsets(offsets, frame.mutable_body());
    }
    frame.mutable_body()->set_point_rms_mm(3.0f);
    auto posed = body::PoseBody(TestBodyModel(), TestBodyPose(f), shape);
    EXPECT_TRUE(posed.ok()) << posed.status();
    for (const Eigen::Vector3d& j : posed->joints_m) {
      v1::Vector3* p = frame.add_joints_in_world_m();
      p->set_x(j.x());
      p->set_y(j.y());
      p->set_z(j.z());
    }
    data.frames.push_back(std::move(frame));
  }
  return data;
}

// Replaces the pose of `frame` of a body reenactment by one that turns every
// joint (0.15 to 1.35 rad about axes that differ per joint), keeping its root
// translation, so tests of pose conventions see every joint move.
inline void TurnEveryJoint(ReenactmentData* data, int frame) {
  v1::BodyPose* message = data->frames[frame].mutable_body();
  auto pose = BodyPoseFromProto(*message);
  ASSERT_TRUE(pose.ok()) << pose.status();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    pose->local_rotation[j] = Eigen::AngleAxisd(
        0.05 * (j + 3), Eigen::Vector3d(std::sin(j), std::cos(2.0 * j), 0.5).normalized());
  }
  *message = BodyPoseToProto(*pose);
}

}  // namespace reenact::testing
