// The only translation unit that compiles tinygltf (see tinygltf_config.h).
#define TINYGLTF_IMPLEMENTATION
#include "common/io/tinygltf_config.h"

#include "common/io/gltf_export.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/body_reenactment.h"

namespace reenact {

bool KeepEncodedImage(tinygltf::Image* image, int image_index, std::string* err, std::string* warn,
                      int req_width, int req_height, const unsigned char* bytes, int size,
                      void* user_data) {
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

namespace {

// Key of a part's animation: time, translation, rotation (x, y, z, w as
// glTF orders it), uniform scale.
struct Key {
  double time_s = 0;
  std::array<float, 3> translation{};
  std::array<float, 4> rotation{0, 0, 0, 1};
  float scale = 0;
};

// Where a part appears or disappears, the extra key sits this long before
// the frame (at most a quarter of the frame interval).
constexpr double kStepLeadS = 1e-3;

// Collects the model and its one binary buffer.
class GlbBuilder {
 public:
  // A glTF 2.0 model with one (empty) buffer, naming its generator.
  GlbBuilder() {
    model_.asset.version = "2.0";
    model_.asset.generator = "reenact gltf_export (tinygltf)";
    model_.buffers.emplace_back();
  }
  tinygltf::Model& model() { return model_; }

  // A bufferView over `bytes`, 4-byte aligned.
  int AddView(const void* bytes, size_t size, int target) {
    std::vector<unsigned char>& data = model_.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4, 0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = size;
    view.target = target;
    const auto* begin = static_cast<const unsigned char*>(bytes);
    data.insert(data.end(), begin, begin + size);
    model_.bufferViews.push_back(std::move(view));
    return static_cast<int>(model_.bufferViews.size()) - 1;
  }

  // A float accessor of `components` per element (type TINYGLTF_TYPE_*), with
  // per-component min/max when `bounds`.
  int AddFloats(const std::vector<float>& values, int components, int type, int target,
                bool bounds) {
    tinygltf::Accessor accessor;
    accessor.bufferView = AddView(values.data(), values.size() * sizeof(float), target);
    accessor.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    accessor.count = values.size() / components;
    accessor.type = type;
    if (bounds) {
      accessor.minValues.assign(components, std::numeric_limits<double>::infinity());
      accessor.maxValues.assign(components, -std::numeric_limits<double>::infinity());
      for (size_t i = 0; i < values.size(); ++i) {
        const size_t c = i % components;
        accessor.minValues[c] = std::min<double>(accessor.minValues[c], values[i]);
        accessor.maxValues[c] = std::max<double>(accessor.maxValues[c], values[i]);
      }
    }
    model_.accessors.push_back(std::move(accessor));
    return static_cast<int>(model_.accessors.size()) - 1;
  }

  // An unsigned-byte VEC4 vertex attribute (e.g. JOINTS_0).
  int AddByteVec4s(const std::vector<uint8_t>& values) {
    tinygltf::Accessor accessor;
    accessor.bufferView = AddView(values.data(), values.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
    accessor.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    accessor.count = values.size() / 4;
    accessor.type = TINYGLTF_TYPE_VEC4;
    model_.accessors.push_back(std::move(accessor));
    return static_cast<int>(model_.accessors.size()) - 1;
  }

  // Triangle indices, as 16-bit integers when every index fits (65535 is
  // glTF's primitive restart value, so not an index), else 32-bit.
  int AddIndices(const std::vector<uint32_t>& indices) {
    tinygltf::Accessor accessor;
    const bool short_indices =
        std::all_of(indices.begin(), indices.end(), [](uint32_t i) { return i < 65535; });
    if (short_indices) {
      const std::vector<uint16_t> narrow(indices.begin(), indices.end());
      accessor.bufferView = AddView(narrow.data(), narrow.size() * sizeof(uint16_t),
                                    TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      accessor.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    } else {
      accessor.bufferView = AddView(indices.data(), indices.size() * sizeof(uint32_t),
                                    TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      accessor.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    }
    accessor.count = indices.size();
    accessor.type = TINYGLTF_TYPE_SCALAR;
    model_.accessors.push_back(std::move(accessor));
    return static_cast<int>(model_.accessors.size()) - 1;
  }

 private:
  tinygltf::Model model_;
};

bool IsJpeg(const std::string& bytes) {
  return bytes.size() > 3 && static_cast<uint8_t>(bytes[0]) == 0xFF &&
         static_cast<uint8_t>(bytes[1]) == 0xD8 && static_cast<uint8_t>(bytes[2]) == 0xFF;
}

// Unit normals (zero ones become +Y, which glTF requires to be unit too).
std::vector<float> UnitNormals(std::vector<float> normals) {
  for (size_t i = 0; i + 2 < normals.size(); i += 3) {
    const double n =
        std::sqrt(double{normals[i]} * normals[i] + double{normals[i + 1]} * normals[i + 1] +
                  double{normals[i + 2]} * normals[i + 2]);
    if (n < 1e-12) {
      normals[i] = 0, normals[i + 1] = 1, normals[i + 2] = 0;
      continue;
    }
    for (int c = 0; c < 3; ++c) normals[i + c] = static_cast<float>(normals[i + c] / n);
  }
  return normals;
}

// A material named `name` with `jpeg` (a part's baked texture, a body's
// atlas) as base colour, or plain grey.
int AddMaterial(GlbBuilder& b, const std::string& name, const std::string& jpeg,
                const GltfExportOptions& options, GltfExportSummary* summary) {
  tinygltf::Model& model = b.model();
  tinygltf::Material material;
  material.name = name;
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.pbrMetallicRoughness.roughnessFactor = 1.0;
  if (options.unlit) material.extensions["KHR_materials_unlit"] = tinygltf::Value();
  if (options.textures && IsJpeg(jpeg)) {
    if (model.samplers.empty()) {
      tinygltf::Sampler sampler;
      sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
      sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
      sampler.wrapS = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
      sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
      model.samplers.push_back(sampler);
    }
    tinygltf::Image image;
    image.name = name;
    image.mimeType = "image/jpeg";
    image.bufferView = b.AddView(jpeg.data(), jpeg.size(), 0);
    model.images.push_back(std::move(image));
    tinygltf::Texture texture;
    texture.name = name;
    texture.sampler = 0;
    texture.source = static_cast<int>(model.images.size()) - 1;
    model.textures.push_back(std::move(texture));
    material.pbrMetallicRoughness.baseColorTexture.index =
        static_cast<int>(model.textures.size()) - 1;
    ++summary->textures;
  } else {
    material.pbrMetallicRoughness.baseColorFactor = {0.6, 0.6, 0.6, 1.0};
  }
  model.materials.push_back(std::move(material));
  return static_cast<int>(model.materials.size()) - 1;
}

// The mesh of one part, or -1 when it has no triangles.
int AddMesh(GlbBuilder& b, const PartMesh& part, const GltfExportOptions& options,
            GltfExportSummary* summary) {
  if (part.triangles.empty()) return -1;
  const std::vector<float> positions(
      part.positions_in_part_m.data(),
      part.positions_in_part_m.data() + part.positions_in_part_m.size());
  std::vector<float> normals(part.normals_in_part.data(),
                             part.normals_in_part.data() + part.normals_in_part.size());
  std::vector<float> uvs(part.uvs.data(), part.uvs.data() + part.uvs.size());
  // glTF's texture origin is the top-left corner, the reenactment's the
  // bottom-left.
  for (size_t i = 1; i < uvs.size(); i += 2) uvs[i] = 1.0f - uvs[i];
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.attributes["POSITION"] =
      b.AddFloats(positions, 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
  primitive.attributes["NORMAL"] = b.AddFloats(
      UnitNormals(std::move(normals)), 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  primitive.material = AddMaterial(b, part.name, part.baked_texture_jpeg, options, summary);
  // Texture coordinates only where a texture uses them.
  if (b.model().materials[primitive.material].pbrMetallicRoughness.baseColorTexture.index >= 0) {
    primitive.attributes["TEXCOORD_0"] =
        b.AddFloats(uvs, 2, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  std::vector<uint32_t> indices;
  indices.reserve(3 * part.triangles.size());
  for (const Eigen::Vector3i& t : part.triangles) {
    for (int c = 0; c < 3; ++c) indices.push_back(static_cast<uint32_t>(t[c]));
  }
  primitive.indices = b.AddIndices(indices);
  tinygltf::Mesh mesh;
  mesh.name = part.name;
  mesh.primitives.push_back(std::move(primitive));
  b.model().meshes.push_back(std::move(mesh));
  ++summary->meshes;
  return static_cast<int>(b.model().meshes.size()) - 1;
}

// Seconds of every frame from the first one's stamp; frame_index / fps when
// the stamps (as float32, what the file stores) do not strictly increase.
std::vector<double> KeyTimes(const Reenactment& data, const GltfExportOptions& options,
                             bool* fell_back) {
  std::vector<double> times(data.frames.size());
  *fell_back = false;
  for (size_t i = 0; i < data.frames.size(); ++i) {
    times[i] = static_cast<double>(data.frames[i].stamp_ns - data.frames[0].stamp_ns) * 1e-9;
    if (i > 0 && !(static_cast<float>(times[i]) > static_cast<float>(times[i - 1]))) {
      *fell_back = true;
    }
  }
  if (!*fell_back) return times;
  double fps = options.fallback_fps > 0 ? options.fallback_fps : data.info.fps;
  if (!(fps > 0)) fps = 30.0;
  for (size_t i = 0; i < times.size(); ++i) times[i] = static_cast<double>(i) / fps;
  return times;
}

// Flips `q` into the hemisphere of `previous`, so that LINEAR slerps the
// short way in every viewer.
void KeepHemisphere(const std::array<float, 4>& previous, std::array<float, 4>* q) {
  const std::array<float, 4>& a = previous;
  std::array<float, 4>& b = *q;
  if (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] < 0) {
    for (float& c : b) c = -c;
  }
}

Key KeyOf(const PartPose& pose, double time_s, bool visible) {
  Key key;
  key.time_s = time_s;
  const Eigen::Vector3d t = pose.world_from_part.translation();
  key.translation = {static_cast<float>(t.x()), static_cast<float>(t.y()),
                     static_cast<float>(t.z())};
  const Eigen::Quaterniond q(pose.world_from_part.linear());
  key.rotation = {static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()),
                  static_cast<float>(q.w())};
  key.scale = visible ? static_cast<float>(pose.scale) : 0.0f;
  return key;
}

// The keys of part `p`: one per frame, plus a step key where it appears or
// disappears. Invalid poses hold the last (or else the next) valid pose,
// hidden by scale 0.
std::vector<Key> PartKeys(const Reenactment& data, int p, const std::vector<double>& times) {
  const size_t n = data.frames.size();
  std::vector<const PartPose*> held(n, nullptr);
  const PartPose* last = nullptr;
  for (size_t i = 0; i < n; ++i) {
    const PartPose& pose = data.frames[i].parts[p];
    if (pose.valid) last = &pose;
    held[i] = last;
  }
  const PartPose* next = nullptr;
  for (size_t i = n; i-- > 0;) {
    const PartPose& pose = data.frames[i].parts[p];
    if (pose.valid) next = &pose;
    if (held[i] == nullptr) held[i] = next;
  }
  const PartPose identity;
  std::vector<Key> keys;
  keys.reserve(n + 8);
  for (size_t i = 0; i < n; ++i) {
    const bool valid = data.frames[i].parts[p].valid;
    const PartPose& pose = held[i] != nullptr ? *held[i] : identity;
    if (i > 0 && valid != data.frames[i - 1].parts[p].valid) {
      const double lead = std::min(kStepLeadS, (times[i] - times[i - 1]) / 4);
      const double t = times[i] - lead;
      if (static_cast<float>(t) > static_cast<float>(times[i - 1]) &&
          static_cast<float>(t) < static_cast<float>(times[i])) {
        // Appearing: already at the new pose, still hidden. Disappearing:
        // still at the old pose, still shown.
        keys.push_back(valid ? KeyOf(pose, t, false) : KeyOf(*held[i - 1], t, true));
      }
    }
    keys.push_back(KeyOf(pose, times[i], valid));
  }
  for (size_t k = 1; k < keys.size(); ++k) KeepHemisphere(keys[k - 1].rotation, &keys[k].rotation);
  return keys;
}

// A LINEAR channel animating `path` of `node`: key times from accessor
// `input`, values from `output`.
void AddChannel(tinygltf::Animation& animation, int node, const char* path, int input, int output) {
  tinygltf::AnimationSampler sampler;
  sampler.input = input;
  sampler.output = output;
  sampler.interpolation = "LINEAR";
  animation.samplers.push_back(std::move(sampler));
  tinygltf::AnimationChannel channel;
  channel.sampler = static_cast<int>(animation.samplers.size()) - 1;
  channel.target_node = node;
  channel.target_path = path;
  animation.channels.push_back(std::move(channel));
}

// The animation channels of part node `node` from `keys`; `shared_input` is
// the accessor of the frame times, used when the keys are exactly the
// frames.
void AddPartChannels(GlbBuilder& b, tinygltf::Animation& animation, int node,
                     const std::vector<Key>& keys, size_t frame_count, int shared_input) {
  int input = shared_input;
  if (keys.size() != frame_count) {
    std::vector<float> times;
    times.reserve(keys.size());
    for (const Key& k : keys) times.push_back(static_cast<float>(k.time_s));
    input = b.AddFloats(times, 1, TINYGLTF_TYPE_SCALAR, 0, true);
  }
  std::vector<float> translation, rotation, scale;
  for (const Key& k : keys) {
    translation.insert(translation.end(), k.translation.begin(), k.translation.end());
    rotation.insert(rotation.end(), k.rotation.begin(), k.rotation.end());
    scale.insert(scale.end(), {k.scale, k.scale, k.scale});
  }
  AddChannel(animation, node, "translation", input,
             b.AddFloats(translation, 3, TINYGLTF_TYPE_VEC3, 0, false));
  AddChannel(animation, node, "rotation", input,
             b.AddFloats(rotation, 4, TINYGLTF_TYPE_VEC4, 0, false));
  AddChannel(animation, node, "scale", input, b.AddFloats(scale, 3, TINYGLTF_TYPE_VEC3, 0, false));
}

// The node's rest transform: its first key.
void SetRestTransform(tinygltf::Node& node, const Key& key) {
  node.translation.assign(key.translation.begin(), key.translation.end());
  node.rotation.assign(key.rotation.begin(), key.rotation.end());
  node.scale.assign(3, key.scale);
}

// ------------------------------------------------- body-model reenactments

// Area-weighted unit normals of the rest mesh, 3 floats per model vertex.
std::vector<float> RestNormals(const BodyMesh& body) {
  std::vector<float> normals(3 * body.num_vertices(), 0.0f);
  for (const Eigen::Vector3i& t : body.triangles) {
    const Eigen::Vector3d a = body.rest_vertices_m.col(t[0]);
    const Eigen::Vector3d n =
        (body.rest_vertices_m.col(t[1]) - a).cross(body.rest_vertices_m.col(t[2]) - a);
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) normals[3 * t[c] + k] += static_cast<float>(n[k]);
    }
  }
  return UnitNormals(std::move(normals));
}

// The skinned mesh over the texture vertices: rest positions, normals, uvs
// (v flipped), JOINTS_0 (joint ids are the skin's joint indices) and
// WEIGHTS_0 (renormalised in float32), with the atlas as material.
int AddBodyMesh(GlbBuilder& b, const BodyMesh& body, const GltfExportOptions& options,
                GltfExportSummary* summary) {
  const std::vector<float> model_normals = RestNormals(body);
  std::vector<float> positions, normals, uvs, weights;
  std::vector<uint8_t> joints;
  for (size_t i = 0; i < body.texture_vertex_source.size(); ++i) {
    const int v = static_cast<int>(body.texture_vertex_source[i]);
    for (int c = 0; c < 3; ++c) {
      positions.push_back(static_cast<float>(body.rest_vertices_m(c, v)));
      normals.push_back(model_normals[3 * v + c]);
    }
    uvs.insert(uvs.end(), {body.texture_uvs[i].x(), 1.0f - body.texture_uvs[i].y()});
    float sum = 0.0f;
    for (float w : body.skin_weights[v]) sum += w;
    for (int k = 0; k < body::kMaxInfluences; ++k) {
      const float w = body.skin_weights[v][k] / sum;
      joints.push_back(static_cast<uint8_t>(w > 0.0f ? body.skin_joints[v][k] : 0));
      weights.push_back(w);
    }
  }
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.attributes["POSITION"] =
      b.AddFloats(positions, 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
  primitive.attributes["NORMAL"] =
      b.AddFloats(normals, 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  primitive.attributes["JOINTS_0"] = b.AddByteVec4s(joints);
  primitive.attributes["WEIGHTS_0"] =
      b.AddFloats(weights, 4, TINYGLTF_TYPE_VEC4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  primitive.material = AddMaterial(b, "body", body.atlas_jpeg, options, summary);
  if (b.model().materials[primitive.material].pbrMetallicRoughness.baseColorTexture.index >= 0) {
    primitive.attributes["TEXCOORD_0"] =
        b.AddFloats(uvs, 2, TINYGLTF_TYPE_VEC2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  std::vector<uint32_t> indices;
  for (const Eigen::Vector3i& t : body.texture_triangles) {
    for (int c = 0; c < 3; ++c) indices.push_back(static_cast<uint32_t>(t[c]));
  }
  primitive.indices = b.AddIndices(indices);
  tinygltf::Mesh mesh;
  mesh.name = body.model_name.empty() ? "body" : body.model_name;
  mesh.primitives.push_back(std::move(primitive));
  b.model().meshes.push_back(std::move(mesh));
  ++summary->meshes;
  return static_cast<int>(b.model().meshes.size()) - 1;
}

// The 25 joint nodes (Kinect v2 order, from node index `first`) in the
// Kinect v2 tree under node 0, at their rest translations with no rotation,
// and the skin over them: inverse bind matrices translate by -J_j.
int AddSkeleton(GlbBuilder& b, const BodyMesh& body) {
  tinygltf::Model& model = b.model();
  const int first = static_cast<int>(model.nodes.size());
  std::vector<float> inverse_binds;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const auto joint = static_cast<body::KinectV2Joint>(j);
    const std::optional<body::KinectV2Joint> parent = body::KinectV2Parent(joint);
    const Eigen::Vector3d rest = body.rest_joints_m[j];
    const Eigen::Vector3d offset =
        parent.has_value() ? Eigen::Vector3d(rest - body.rest_joints_m[Index(*parent)]) : rest;
    tinygltf::Node node;
    node.name = std::string(body::KinectV2JointName(joint));
    node.translation = {offset.x(), offset.y(), offset.z()};
    model.nodes.push_back(std::move(node));
    Eigen::Matrix4f inverse_bind = Eigen::Matrix4f::Identity();  // Column-major, as glTF.
    inverse_bind.block<3, 1>(0, 3) = (-rest).cast<float>();
    inverse_binds.insert(inverse_binds.end(), inverse_bind.data(), inverse_bind.data() + 16);
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const std::optional<body::KinectV2Joint> parent =
        body::KinectV2Parent(static_cast<body::KinectV2Joint>(j));
    model.nodes[parent.has_value() ? first + Index(*parent) : 0].children.push_back(first + j);
  }
  tinygltf::Skin skin;
  skin.name = "kinect_v2";
  skin.skeleton = first + Index(body::KinectV2Joint::kSpineBase);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) skin.joints.push_back(first + j);
  skin.inverseBindMatrices = b.AddFloats(inverse_binds, 16, TINYGLTF_TYPE_MAT4, 0, false);
  model.skins.push_back(std::move(skin));
  return first;
}

// Per joint a rotation channel (the BodyPose's local rotation: in the
// joint's world-aligned rest frame, which is the node's rotation since the
// rest nodes carry none), and a translation channel on the root (its rest
// joint plus root_translation_m), keyed at every frame.
void AddBodyChannels(GlbBuilder& b, const Reenactment& data, int first_joint, int input,
                     tinygltf::Animation& animation) {
  const BodyMesh& body = *data.body;
  std::vector<std::vector<float>> rotations(body::kNumKinectV2Joints);
  std::vector<float> root_translations;
  std::vector<std::array<float, 4>> previous(body::kNumKinectV2Joints);
  for (size_t f = 0; f < data.frames.size(); ++f) {
    const body::BodyPose pose = data.frames[f].body ? data.frames[f].body->pose : body::BodyPose();
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      const Eigen::Quaterniond& q = pose.local_rotation[j];
      std::array<float, 4> key = {static_cast<float>(q.x()), static_cast<float>(q.y()),
                                  static_cast<float>(q.z()), static_cast<float>(q.w())};
      if (f > 0) KeepHemisphere(previous[j], &key);
      previous[j] = key;
      rotations[j].insert(rotations[j].end(), key.begin(), key.end());
    }
    const Eigen::Vector3d root =
        body.rest_joints_m[Index(body::KinectV2Joint::kSpineBase)] + pose.root_translation_m;
    for (int c = 0; c < 3; ++c) root_translations.push_back(static_cast<float>(root[c]));
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    AddChannel(animation, first_joint + j, "rotation", input,
               b.AddFloats(rotations[j], 4, TINYGLTF_TYPE_VEC4, 0, false));
  }
  AddChannel(animation, first_joint + Index(body::KinectV2Joint::kSpineBase), "translation", input,
             b.AddFloats(root_translations, 3, TINYGLTF_TYPE_VEC3, 0, false));
}

// The body of a body-model reenactment: skeleton and skin, the skinned mesh
// on its own scene node (returned; glTF ignores a skinned mesh node's own
// transform and its parents'), and the animation channels when there are
// frames (`input`: the frame times).
int AddBody(GlbBuilder& b, const Reenactment& data, const GltfExportOptions& options, int input,
            tinygltf::Animation& animation, GltfExportSummary* summary) {
  const int first_joint = AddSkeleton(b, *data.body);
  tinygltf::Node node;
  node.name = "body";
  node.mesh = AddBodyMesh(b, *data.body, options, summary);
  node.skin = 0;
  b.model().nodes.push_back(std::move(node));
  summary->joints = body::kNumKinectV2Joints;
  for (const ReenactmentFrame& frame : data.frames) {
    summary->frames_offsets_left_out += frame.body && frame.body->vertex_offsets_50um.cols() > 0;
  }
  if (input >= 0) {
    AddBodyChannels(b, data, first_joint, input, animation);
    summary->keys = body::kNumKinectV2Joints * static_cast<int>(data.frames.size());
  }
  return static_cast<int>(b.model().nodes.size()) - 1;
}

tinygltf::Value InfoExtras(const ReenactmentInfo& info) {
  tinygltf::Value::Object extras;
  extras["reenactment_id"] = tinygltf::Value(info.reenactment_id);
  extras["take_id"] = tinygltf::Value(info.take_id);
  extras["method"] = tinygltf::Value(info.method);
  extras["fps"] = tinygltf::Value(info.fps);
  extras["frame_count"] = tinygltf::Value(info.frame_count);
  return tinygltf::Value(std::move(extras));
}

// The scene of `b` as .glb bytes (the buffer padded to 4 bytes).
absl::StatusOr<std::string> WriteGlb(GlbBuilder& b, GltfExportSummary& s) {
  tinygltf::Model& model = b.model();
  model.defaultScene = 0;
  model.buffers[0].data.resize((model.buffers[0].data.size() + 3) / 4 * 4, 0);
  if (model.buffers[0].data.empty()) model.buffers.clear();
  tinygltf::TinyGLTF writer;
  std::ostringstream out;
  if (!writer.WriteGltfSceneToStream(&model, out, /*prettyPrint=*/false, /*writeBinary=*/true)) {
    return absl::InternalError("tinygltf failed to write the .glb");
  }
  std::string bytes = std::move(out).str();
  s.bytes = static_cast<int64_t>(bytes.size());
  return bytes;
}

}  // namespace

absl::Status GltfExportOptions::Validate() const {
  if (!std::isfinite(fallback_fps) || fallback_fps < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("GltfExportOptions.fallback_fps must be >= 0, got ", fallback_fps));
  }
  return absl::OkStatus();
}

std::string GltfExportSummary::BriefReport() const {
  std::string skin;
  if (joints > 0) {
    skin = absl::StrFormat(", skinned over %d joints", joints);
    if (frames_offsets_left_out > 0) {
      absl::StrAppendFormat(&skin, " (vertex offsets of %d frames left out)",
                            frames_offsets_left_out);
    }
  }
  return absl::StrFormat(
      "glb: %d nodes, %d meshes, %d textures%s, %d animation channels, %d keys over %.3f s%s, "
      "%d bytes",
      nodes, meshes, textures, skin, animation_channels, keys, duration_s,
      stamps_fell_back ? " (times from frame index / fps)" : "", bytes);
}

absl::StatusOr<std::string> ExportReenactmentGlb(const Reenactment& data,
                                                 const GltfExportOptions& options,
                                                 GltfExportSummary* summary) {
  RETURN_IF_ERROR(options.Validate());
  RETURN_IF_ERROR(ValidateReenactment(data));
  GltfExportSummary local;
  GltfExportSummary& s = summary != nullptr ? *summary : local;
  s = GltfExportSummary();
  GlbBuilder b;
  tinygltf::Model& model = b.model();

  tinygltf::Node root;
  root.name = data.info.reenactment_id.empty() ? "reenactment" : data.info.reenactment_id;
  root.extras = InfoExtras(data.info);
  model.nodes.push_back(std::move(root));

  const std::vector<double> times = KeyTimes(data, options, &s.stamps_fell_back);
  s.duration_s = times.empty() ? 0.0 : times.back();
  int shared_input = -1;
  if (!times.empty()) {
    std::vector<float> seconds(times.begin(), times.end());
    shared_input = b.AddFloats(seconds, 1, TINYGLTF_TYPE_SCALAR, 0, true);
  }
  tinygltf::Animation animation;
  animation.name = model.nodes[0].name;
  tinygltf::Scene scene;
  scene.name = model.nodes[0].name;
  scene.nodes.push_back(0);
  if (data.is_body()) {
    scene.nodes.push_back(AddBody(b, data, options, shared_input, animation, &s));
  }
  for (int p = 0; p < static_cast<int>(data.parts.size()); ++p) {
    tinygltf::Node node;
    node.name = data.parts[p].name;
    node.mesh = AddMesh(b, data.parts[p], options, &s);
    if (!times.empty()) {
      const std::vector<Key> keys = PartKeys(data, p, times);
      SetRestTransform(node, keys.front());
      const int index = static_cast<int>(model.nodes.size());
      AddPartChannels(b, animation, index, keys, times.size(), shared_input);
      s.keys += static_cast<int>(keys.size());
    }
    model.nodes.push_back(std::move(node));
    model.nodes[0].children.push_back(static_cast<int>(model.nodes.size()) - 1);
  }
  s.animation_channels = static_cast<int>(animation.channels.size());
  if (!animation.channels.empty()) model.animations.push_back(std::move(animation));
  s.nodes = static_cast<int>(model.nodes.size());
  if (options.unlit && !model.materials.empty()) {
    model.extensionsUsed.push_back("KHR_materials_unlit");
  }

  model.scenes.push_back(std::move(scene));
  return WriteGlb(b, s);
}

absl::StatusOr<std::string> ExportBodyMeshGlb(const v1::BodyMesh& mesh,
                                              const GltfExportOptions& options,
                                              GltfExportSummary* summary) {
  ASSIGN_OR_RETURN(const BodyMesh body, DecodeBodyMesh(mesh));
  return ExportBodyMeshGlb(body, options, summary);
}

absl::StatusOr<std::string> ExportBodyMeshGlb(const BodyMesh& body,
                                              const GltfExportOptions& options,
                                              GltfExportSummary* summary) {
  RETURN_IF_ERROR(options.Validate());
  GltfExportSummary local;
  GltfExportSummary& s = summary != nullptr ? *summary : local;
  s = GltfExportSummary();
  GlbBuilder b;
  tinygltf::Model& model = b.model();
  tinygltf::Node root;
  root.name = body.model_name.empty() ? "body" : body.model_name;
  model.nodes.push_back(std::move(root));
  AddSkeleton(b, body);
  tinygltf::Node node;
  node.name = "body";
  node.mesh = AddBodyMesh(b, body, options, &s);
  node.skin = 0;
  model.nodes.push_back(std::move(node));
  s.joints = body::kNumKinectV2Joints;
  s.nodes = static_cast<int>(model.nodes.size());
  tinygltf::Scene scene;
  scene.name = model.nodes[0].name;
  scene.nodes = {0, static_cast<int>(model.nodes.size()) - 1};
  if (options.unlit && !model.materials.empty()) {
    model.extensionsUsed.push_back("KHR_materials_unlit");
  }
  model.scenes.push_back(std::move(scene));
  return WriteGlb(b, s);
}

absl::Status WriteReenactmentGlb(const Reenactment& data, const std::string& path,
                                 const GltfExportOptions& options, GltfExportSummary* summary) {
  ASSIGN_OR_RETURN(const std::string bytes, ExportReenactmentGlb(data, options, summary));
  return WriteFileAtomically(path, bytes);
}

}  // namespace reenact
