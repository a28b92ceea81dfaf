#include "common/io/gltf_export.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "common/base/files.h"
#include "common/io/body_reenactment.h"
#include "common/io/testing/small_reenactment.h"
#include "common/io/tinygltf_config.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

using testing::MakeTestReenactment;
using testing::TestReenactmentOptions;

// Position tolerance of float32 keys, metres (poses are within a few metres
// of the origin), and of quaternion components.
constexpr double kTolerance = 1e-5;

tinygltf::Model Load(const std::string& glb) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&KeepEncodedImage, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const bool ok = loader.LoadBinaryFromMemory(&model, &err, &warn,
                                              reinterpret_cast<const unsigned char*>(glb.data()),
                                              static_cast<unsigned int>(glb.size()));
  EXPECT_TRUE(ok) << err;
  EXPECT_TRUE(err.empty()) << err;
  EXPECT_TRUE(warn.empty()) << warn;
  return model;
}

// The floats of accessor `index`.
std::vector<float> Floats(const tinygltf::Model& model, int index) {
  const tinygltf::Accessor& accessor = model.accessors.at(index);
  EXPECT_EQ(accessor.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  const tinygltf::BufferView& view = model.bufferViews.at(accessor.bufferView);
  const int components = tinygltf::GetNumComponentsInType(accessor.type);
  std::vector<float> out(accessor.count * components);
  std::memcpy(out.data(),
              model.buffers.at(view.buffer).data.data() + view.byteOffset + accessor.byteOffset,
              out.size() * sizeof(float));
  return out;
}

// The sampler of `node`'s `path` channel in the first animation.
const tinygltf::AnimationSampler& SamplerOf(const tinygltf::Model& model, int node,
                                            const std::string& path) {
  for (const auto& channel : model.animations.at(0).channels) {
    if (channel.target_node == node && channel.target_path == path) {
      return model.animations[0].samplers.at(channel.sampler);
    }
  }
  ADD_FAILURE() << "no " << path << " channel for node " << node;
  static const tinygltf::AnimationSampler kNone;
  return kNone;
}

struct KeyValues {
  std::vector<float> times, translation, rotation, scale;
};

KeyValues KeysOf(const tinygltf::Model& model, int node) {
  KeyValues k;
  const auto& t = SamplerOf(model, node, "translation");
  k.times = Floats(model, t.input);
  k.translation = Floats(model, t.output);
  k.rotation = Floats(model, SamplerOf(model, node, "rotation").output);
  k.scale = Floats(model, SamplerOf(model, node, "scale").output);
  EXPECT_EQ(SamplerOf(model, node, "rotation").input, t.input);
  EXPECT_EQ(t.interpolation, "LINEAR");
  return k;
}

// Checks key `k` against `pose` (rotation up to sign).
void ExpectKeyIsPose(const KeyValues& keys, size_t k, const v1::PartPose& pose, float scale) {
  const auto& t = pose.world_from_part().translation_m();
  EXPECT_NEAR(keys.translation[3 * k + 0], t.x(), kTolerance);
  EXPECT_NEAR(keys.translation[3 * k + 1], t.y(), kTolerance);
  EXPECT_NEAR(keys.translation[3 * k + 2], t.z(), kTolerance);
  const auto& q = pose.world_from_part().rotation();
  const double sign =
      (keys.rotation[4 * k + 3] * q.w() < 0 || (q.w() == 0 && keys.rotation[4 * k + 1] * q.y() < 0))
          ? -1.0
          : 1.0;
  EXPECT_NEAR(keys.rotation[4 * k + 0], sign * q.x(), kTolerance);
  EXPECT_NEAR(keys.rotation[4 * k + 1], sign * q.y(), kTolerance);
  EXPECT_NEAR(keys.rotation[4 * k + 2], sign * q.z(), kTolerance);
  EXPECT_NEAR(keys.rotation[4 * k + 3], sign * q.w(), kTolerance);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(keys.scale[3 * k + c], scale, kTolerance);
}

double Seconds(const ReenactmentData& data, int frame) {
  return static_cast<double>(data.frames[frame].stamp_ns() - data.frames[0].stamp_ns()) * 1e-9;
}

TEST(ExportReenactmentGlb, WritesOneTexturedNodePerPartUnderARoot) {
  const ReenactmentData data = MakeTestReenactment();
  GltfExportSummary summary;
  auto glb = ExportReenactmentGlb(testing::ToPlain(data), {}, &summary);
  ASSERT_TRUE(glb.ok()) << glb.status();
  EXPECT_EQ(glb->substr(0, 4), "glTF");
  EXPECT_EQ(summary.bytes, static_cast<int64_t>(glb->size()));
  const tinygltf::Model model = Load(*glb);

  ASSERT_EQ(model.scenes.size(), 1u);
  ASSERT_EQ(model.scenes[0].nodes, std::vector<int>{0});
  ASSERT_EQ(model.nodes.size(), 4u);
  EXPECT_EQ(summary.nodes, 4);
  EXPECT_EQ(model.nodes[0].name, data.info.reenactment_id());
  EXPECT_EQ(model.nodes[0].children, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(model.nodes[0].extras.Get("take_id").Get<std::string>(), data.info.take_id());
  for (int p = 0; p < 3; ++p) {
    const tinygltf::Node& node = model.nodes[p + 1];
    EXPECT_EQ(node.name, data.info.part_names(p));
    ASSERT_EQ(node.mesh, p);
    const tinygltf::Primitive& primitive = model.meshes[p].primitives.at(0);
    ASSERT_EQ(model.accessors.at(primitive.indices).count, 36u);
    // POSITION carries its bounds: the box of part p.
    const tinygltf::Accessor& position = model.accessors.at(primitive.attributes.at("POSITION"));
    ASSERT_EQ(position.minValues.size(), 3u);
    ASSERT_EQ(position.maxValues.size(), 3u);
    EXPECT_NEAR(position.minValues[0], -(0.05 + 0.01 * p), 1e-6);
    EXPECT_NEAR(position.maxValues[1], 0.2, 1e-6);
    EXPECT_NEAR(position.minValues[1], 0.0, 1e-6);
    // Texture coordinates flipped in v.
    const std::vector<float> uvs = Floats(model, primitive.attributes.at("TEXCOORD_0"));
    const std::vector<float> source = *UnpackFloats(data.parts[p].uvs_f32());
    ASSERT_EQ(uvs.size(), source.size());
    for (size_t i = 0; i < uvs.size(); i += 2) {
      EXPECT_FLOAT_EQ(uvs[i], source[i]);
      EXPECT_FLOAT_EQ(uvs[i + 1], 1.0f - source[i + 1]);
    }
    // The baked JPEG, stored as is.
    const tinygltf::Material& material = model.materials.at(primitive.material);
    EXPECT_TRUE(material.extensions.count("KHR_materials_unlit"));
    const int texture = material.pbrMetallicRoughness.baseColorTexture.index;
    ASSERT_GE(texture, 0);
    const tinygltf::Image& image = model.images.at(model.textures.at(texture).source);
    EXPECT_EQ(image.mimeType, "image/jpeg");
    EXPECT_EQ(std::string(image.image.begin(), image.image.end()),
              data.parts[p].baked_texture_jpeg());
  }
  EXPECT_EQ(model.extensionsUsed, std::vector<std::string>{"KHR_materials_unlit"});
  ASSERT_EQ(model.animations.size(), 1u);
  EXPECT_EQ(model.animations[0].channels.size(), 9u);
  EXPECT_EQ(summary.animation_channels, 9);
  EXPECT_EQ(summary.textures, 3);
}

TEST(ExportReenactmentGlb, KeysEqualThePartPoses) {
  TestReenactmentOptions options;
  options.frames = 12;
  const ReenactmentData data = MakeTestReenactment(options);
  auto glb = ExportReenactmentGlb(testing::ToPlain(data));
  ASSERT_TRUE(glb.ok()) << glb.status();
  const tinygltf::Model model = Load(*glb);
  const KeyValues keys = KeysOf(model, /*node=*/1);  // Part 0, always valid.
  ASSERT_EQ(keys.times.size(), 12u);
  // The input accessor's bounds, which glTF requires.
  const tinygltf::Accessor& input = model.accessors.at(SamplerOf(model, 1, "translation").input);
  ASSERT_EQ(input.minValues.size(), 1u);
  EXPECT_DOUBLE_EQ(input.minValues[0], 0.0);
  EXPECT_NEAR(input.maxValues[0], Seconds(data, 11), 1e-6);
  for (int f = 0; f < 12; ++f) {
    EXPECT_NEAR(keys.times[f], Seconds(data, f), 1e-6) << f;
    ExpectKeyIsPose(keys, f, data.frames[f].parts(0), data.frames[f].parts(0).scale());
  }
  // The node's rest transform is the first pose.
  const tinygltf::Node& node = model.nodes[1];
  ASSERT_EQ(node.translation.size(), 3u);
  EXPECT_NEAR(node.translation[1], data.frames[0].parts(0).world_from_part().translation_m().y(),
              kTolerance);
}

TEST(ExportReenactmentGlb, InvalidPosesHideThePartWithSteps) {
  TestReenactmentOptions options;
  options.frames = 6;
  options.part1_invalid_before = 2;  // Part 1 appears at frame 2.
  ReenactmentData data = MakeTestReenactment(options);
  data.frames[4].mutable_parts(2)->set_valid(false);  // Part 2 blinks out at frame 4.
  GltfExportSummary summary;
  auto glb = ExportReenactmentGlb(testing::ToPlain(data), {}, &summary);
  ASSERT_TRUE(glb.ok()) << glb.status();
  const tinygltf::Model model = Load(*glb);

  // Part 1: hidden at frames 0, 1 (holding frame 2's pose), a step key just
  // before frame 2, then shown.
  const KeyValues one = KeysOf(model, 2);
  ASSERT_EQ(one.times.size(), 7u);
  ExpectKeyIsPose(one, 0, data.frames[2].parts(1), 0.0f);
  ExpectKeyIsPose(one, 1, data.frames[2].parts(1), 0.0f);
  EXPECT_LT(one.times[2], Seconds(data, 2));
  EXPECT_GT(one.times[2], Seconds(data, 2) - 1.01e-3);
  ExpectKeyIsPose(one, 2, data.frames[2].parts(1), 0.0f);
  ExpectKeyIsPose(one, 3, data.frames[2].parts(1), data.frames[2].parts(1).scale());
  const tinygltf::Accessor& input = model.accessors.at(SamplerOf(model, 2, "scale").input);
  ASSERT_EQ(input.maxValues.size(), 1u);
  EXPECT_NEAR(input.maxValues[0], Seconds(data, 5), 1e-6);

  // Part 2: shown to frame 3, still shown just before frame 4, hidden at
  // frame 4 (holding frame 3's pose), hidden just before frame 5, shown.
  const KeyValues two = KeysOf(model, 3);
  ASSERT_EQ(two.times.size(), 8u);
  ExpectKeyIsPose(two, 3, data.frames[3].parts(2), data.frames[3].parts(2).scale());
  ExpectKeyIsPose(two, 4, data.frames[3].parts(2), data.frames[3].parts(2).scale());
  ExpectKeyIsPose(two, 5, data.frames[3].parts(2), 0.0f);
  ExpectKeyIsPose(two, 6, data.frames[5].parts(2), 0.0f);
  ExpectKeyIsPose(two, 7, data.frames[5].parts(2), data.frames[5].parts(2).scale());
  for (size_t k = 1; k < two.times.size(); ++k) EXPECT_GT(two.times[k], two.times[k - 1]);
  EXPECT_EQ(summary.keys, 6 + 7 + 8);
}

TEST(ExportReenactmentGlb, OptionsAndFallbacks) {
  ReenactmentData data = MakeTestReenactment();
  GltfExportOptions options;
  options.textures = false;
  options.unlit = false;
  auto plain = ExportReenactmentGlb(testing::ToPlain(data), options);
  ASSERT_TRUE(plain.ok());
  const tinygltf::Model model = Load(*plain);
  EXPECT_TRUE(model.images.empty());
  EXPECT_FALSE(model.meshes[0].primitives[0].attributes.count("TEXCOORD_0"));
  EXPECT_TRUE(model.extensionsUsed.empty());
  EXPECT_EQ(model.materials.size(), 3u);

  // Stamps that repeat: key times from frame index / fps.
  for (auto& frame : data.frames) frame.set_stamp_ns(7);
  GltfExportSummary summary;
  auto glb = ExportReenactmentGlb(testing::ToPlain(data), {}, &summary);
  ASSERT_TRUE(glb.ok());
  EXPECT_TRUE(summary.stamps_fell_back);
  EXPECT_NEAR(summary.duration_s, 4.0 / 30.0, 1e-9);
  const KeyValues keys = KeysOf(Load(*glb), 1);
  EXPECT_NEAR(keys.times[3], 3.0 / 30.0, 1e-6);

  // A part without triangles: a node without a mesh.
  data.parts[2].clear_triangle_indices();
  auto meshless = ExportReenactmentGlb(testing::ToPlain(data));
  ASSERT_TRUE(meshless.ok());
  EXPECT_EQ(Load(*meshless).nodes[3].mesh, -1);
}

TEST(ExportReenactmentGlb, RejectsInvalidInput) {
  Reenactment data = testing::ToPlain(MakeTestReenactment());
  data.frames[1].parts.pop_back();
  EXPECT_EQ(ExportReenactmentGlb(data).status().code(), absl::StatusCode::kInvalidArgument);
  GltfExportOptions options;
  options.fallback_fps = -1;
  EXPECT_EQ(ExportReenactmentGlb(testing::ToPlain(MakeTestReenactment()), options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// The bytes of accessor `index` (tightly packed).
const unsigned char* AccessorBytes(const tinygltf::Model& model, int index) {
  const tinygltf::Accessor& accessor = model.accessors.at(index);
  const tinygltf::BufferView& view = model.bufferViews.at(accessor.bufferView);
  return model.buffers.at(view.buffer).data.data() + view.byteOffset + accessor.byteOffset;
}

// The local matrix of `node` with the first animation's outputs at key `k`
// in place of its rest TRS where a channel animates it.
Eigen::Matrix4d LocalAt(const tinygltf::Model& model, int node, size_t k) {
  const tinygltf::Node& n = model.nodes[node];
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond r = Eigen::Quaterniond::Identity();
  if (n.translation.size() == 3) t = {n.translation[0], n.translation[1], n.translation[2]};
  if (n.rotation.size() == 4) r = {n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]};
  EXPECT_TRUE(n.scale.empty() && n.matrix.empty());
  for (const auto& channel : model.animations.at(0).channels) {
    if (channel.target_node != node) continue;
    const std::vector<float> values =
        Floats(model, model.animations[0].samplers.at(channel.sampler).output);
    if (channel.target_path == "translation") {
      t = Eigen::Vector3f(values[3 * k], values[3 * k + 1], values[3 * k + 2]).cast<double>();
    } else if (channel.target_path == "rotation") {
      r = Eigen::Quaternionf(values[4 * k + 3], values[4 * k], values[4 * k + 1], values[4 * k + 2])
              .cast<double>()
              .normalized();
    }
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r.toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

// World matrices of all nodes at key `k`, down the tree from the scene.
std::vector<Eigen::Matrix4d> WorldAt(const tinygltf::Model& model, size_t k) {
  std::vector<Eigen::Matrix4d> world(model.nodes.size(), Eigen::Matrix4d::Identity());
  std::vector<std::pair<int, Eigen::Matrix4d>> stack;
  for (int root : model.scenes.at(0).nodes) stack.emplace_back(root, Eigen::Matrix4d::Identity());
  while (!stack.empty()) {
    const auto [node, parent] = stack.back();
    stack.pop_back();
    world[node] = parent * LocalAt(model, node, k);
    for (int child : model.nodes[node].children) stack.emplace_back(child, world[node]);
  }
  return world;
}

// Skins every vertex of the body primitive as a glTF viewer does at key k:
// sum_i w_i (world(joint_i) * inverse_bind_i) * position.
Eigen::Matrix3Xd SkinAt(const tinygltf::Model& model, size_t k) {
  const tinygltf::Node* mesh_node = nullptr;
  for (const auto& node : model.nodes) {
    if (node.skin >= 0) mesh_node = &node;
  }
  EXPECT_NE(mesh_node, nullptr);
  if (mesh_node == nullptr) return {};
  const tinygltf::Skin& skin = model.skins.at(mesh_node->skin);
  const tinygltf::Primitive& primitive = model.meshes.at(mesh_node->mesh).primitives.at(0);
  const std::vector<float> positions = Floats(model, primitive.attributes.at("POSITION"));
  const std::vector<float> weights = Floats(model, primitive.attributes.at("WEIGHTS_0"));
  const std::vector<float> inverse_binds = Floats(model, skin.inverseBindMatrices);
  const int joints_accessor = primitive.attributes.at("JOINTS_0");
  EXPECT_EQ(model.accessors[joints_accessor].componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  const unsigned char* joints = AccessorBytes(model, joints_accessor);
  const std::vector<Eigen::Matrix4d> world = WorldAt(model, k);
  std::vector<Eigen::Matrix4d> joint_matrix(skin.joints.size());
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    joint_matrix[j] = world[skin.joints[j]] *
                      Eigen::Map<const Eigen::Matrix4f>(&inverse_binds[16 * j]).cast<double>();
  }
  const size_t n = positions.size() / 3;
  Eigen::Matrix3Xd skinned = Eigen::Matrix3Xd::Zero(3, static_cast<Eigen::Index>(n));
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector4d p(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2], 1.0);
    for (int c = 0; c < 4; ++c) {
      skinned.col(i) += weights[4 * i + c] * (joint_matrix[joints[4 * i + c]] * p).head<3>();
    }
  }
  return skinned;
}

TEST(ExportReenactmentGlb, BodyIsOneSkinnedMeshOverTheKinectV2Tree) {
  const ReenactmentData data = testing::MakeTestBodyReenactment(5);
  GltfExportSummary summary;
  auto glb = ExportReenactmentGlb(testing::ToPlain(data), {}, &summary);
  ASSERT_TRUE(glb.ok()) << glb.status();
  std::printf("test body: %s\n", summary.BriefReport().c_str());
  const tinygltf::Model model = Load(*glb);
  auto body = DecodeBodyMesh(data.body[0]);
  ASSERT_TRUE(body.ok()) << body.status();
  EXPECT_EQ(summary.nodes, 1 + 25 + 1);
  EXPECT_EQ(summary.meshes, 1);
  EXPECT_EQ(summary.textures, 1);
  EXPECT_EQ(summary.joints, 25);
  EXPECT_EQ(summary.animation_channels, 26);
  EXPECT_EQ(summary.keys, 25 * 5);
  EXPECT_EQ(summary.frames_offsets_left_out, 1);
  ASSERT_EQ(model.nodes.size(), 27u);
  ASSERT_EQ(model.skins.size(), 1u);
  ASSERT_EQ(model.meshes.size(), 1u);
  EXPECT_EQ(model.scenes[0].nodes, (std::vector<int>{0, 26}));
  const tinygltf::Skin& skin = model.skins[0];
  ASSERT_EQ(skin.joints.size(), 25u);
  EXPECT_EQ(model.nodes[0].children, std::vector<int>{skin.joints[0]});
  for (int j = 0; j < 25; ++j) {
    const tinygltf::Node& node = model.nodes[skin.joints[j]];
    EXPECT_EQ(node.name, data.body[0].joint_names(j));
    const auto parent = body::KinectV2Parent(static_cast<body::KinectV2Joint>(j));
    const Eigen::Vector3d expected =
        body->rest_joints_m[j] -
        (parent ? body->rest_joints_m[Index(*parent)] : Eigen::Vector3d::Zero());
    ASSERT_EQ(node.translation.size(), 3u);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(node.translation[c], expected[c], 1e-9) << node.name;
    if (parent) {
      const auto& siblings = model.nodes[skin.joints[Index(*parent)]].children;
      EXPECT_NE(std::find(siblings.begin(), siblings.end(), skin.joints[j]), siblings.end());
    }
  }
  // The primitive: one vertex per texture vertex, uvs flipped, the atlas.
  const tinygltf::Primitive& primitive = model.meshes[0].primitives.at(0);
  const std::vector<float> uvs = Floats(model, primitive.attributes.at("TEXCOORD_0"));
  ASSERT_EQ(uvs.size(), 2 * body->texture_uvs.size());
  for (size_t i = 0; i < body->texture_uvs.size(); ++i) {
    EXPECT_FLOAT_EQ(uvs[2 * i], body->texture_uvs[i].x());
    EXPECT_FLOAT_EQ(uvs[2 * i + 1], 1.0f - body->texture_uvs[i].y());
  }
  EXPECT_EQ(model.accessors.at(primitive.indices).count, 3 * body->texture_triangles.size());
  const tinygltf::Material& material = model.materials.at(primitive.material);
  const tinygltf::Image& image = model.images.at(
      model.textures.at(material.pbrMetallicRoughness.baseColorTexture.index).source);
  EXPECT_EQ(std::string(image.image.begin(), image.image.end()), data.body[0].atlas_jpeg());
}

// What a viewer skins from the file at key k is PoseBodyMesh of frame k
// without the vertex offsets (which the file leaves out).
TEST(ExportReenactmentGlb, SkinningTheBodyReproducesPoseBodyMesh) {
  ReenactmentData data = testing::MakeTestBodyReenactment(4);
  testing::TurnEveryJoint(&data, 3);
  auto glb = ExportReenactmentGlb(testing::ToPlain(data));
  ASSERT_TRUE(glb.ok()) << glb.status();
  const tinygltf::Model model = Load(*glb);
  auto body = DecodeBodyMesh(data.body[0]);
  ASSERT_TRUE(body.ok()) << body.status();
  const Eigen::Matrix3Xd rest = SkinAt(model, 0);  // Frame 0: not the rest pose.
  ASSERT_EQ(rest.cols(), static_cast<Eigen::Index>(body->texture_vertex_source.size()));
  for (size_t k = 0; k < data.frames.size(); ++k) {
    v1::BodyPose pose = data.frames[k].body();
    pose.clear_vertex_offsets_50um_i16();
    auto posed = PoseBodyMesh(*body, pose);
    ASSERT_TRUE(posed.ok()) << posed.status();
    const Eigen::Matrix3Xd skinned = SkinAt(model, k);
    double worst_m = 0.0;
    for (Eigen::Index i = 0; i < skinned.cols(); ++i) {
      worst_m = std::max(
          worst_m, (skinned.col(i) - posed->vertices_m.col(body->texture_vertex_source[i])).norm());
    }
    std::printf("frame %zu: glTF skinning vs PoseBodyMesh, worst %.4f mm\n", k, 1e3 * worst_m);
    EXPECT_LT(worst_m, 0.01e-3) << "frame " << k;  // float32 rounding: about 0.3 um.
  }
}

TEST(WriteReenactmentGlb, WritesTheFile) {
  const std::string path = testing::MakeTempDir("glb_write") + "/r.glb";
  GltfExportSummary summary;
  ASSERT_TRUE(
      WriteReenactmentGlb(testing::ToPlain(MakeTestReenactment()), path, {}, &summary).ok());
  EXPECT_EQ(static_cast<int64_t>(std::filesystem::file_size(path)), summary.bytes);
  EXPECT_FALSE(summary.BriefReport().empty());
}

}  // namespace
}  // namespace reenact
