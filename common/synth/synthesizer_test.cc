#include "common/synth/synthesizer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>

#include "common/board/board_detector.h"
#include "common/board/board_spec.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/geometry/surface_distance.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact::synth {
namespace {

using body::KinectV2Joint;

constexpr double kFps = 30.0;
constexpr int kColorWidth = 480;
constexpr int kColorHeight = 270;

// A short two-sensor take at reduced colour resolution.
SynthOptions ShortTakeOptions() {
  SynthOptions options;
  // The sensors carry the jittered true skeleton (a device SDK stand-in).
  options.sensor_skeleton = SynthOptions::SensorSkeleton::kTruth;
  options.motion = "builtin:arm-raise";
  options.num_sensors = 2;
  options.seconds = 0.4;
  options.fps = kFps;
  options.color_width = kColorWidth;
  options.color_height = kColorHeight;
  return options;
}

struct SharedTake {
  SynthSummary summary;
  std::unique_ptr<TakeReader> reader;
};

// Synthesises the short take once per test process.
const SharedTake& Take() {
  static const SharedTake* take = [] {
    auto* t = new SharedTake;
    const std::string path = testing::MakeTempDir("synth_shared") + "/take.mcap";
    auto summary = SynthesizeTake(ShortTakeOptions(), path);
    if (!summary.ok()) {
      ADD_FAILURE() << summary.status();
      return t;
    }
    t->summary = *summary;
    auto reader = TakeReader::Open(path);
    if (!reader.ok()) {
      ADD_FAILURE() << reader.status();
      return t;
    }
    t->reader = std::move(*reader);
    return t;
  }();
  return *take;
}

template <typename Message>
Message MessageAt(const TakeReader& take, const std::string& topic, int64_t frame) {
  Message found;
  EXPECT_TRUE(take.ForEach<Message>(topic,
                                    [&](const Message& m) {
                                      if (m.frame_index() == frame) found = m;
                                      return absl::OkStatus();
                                    })
                  .ok());
  return found;
}

DepthImageMm DepthAt(const TakeReader& take, const std::string& topic, int64_t frame) {
  auto depth = DecodeDepth(MessageAt<v1::DepthImage>(take, topic, frame).data());
  EXPECT_TRUE(depth.ok()) << depth.status();
  return depth.ok() ? *depth : DepthImageMm();
}

MaskImage MaskAt(const TakeReader& take, const std::string& sensor_id, int64_t frame) {
  auto mask =
      DecodeMaskRle(MessageAt<v1::ActorMask>(take, SensorTopic(sensor_id, "mask"), frame).data());
  EXPECT_TRUE(mask.ok()) << mask.status();
  return mask.ok() ? *mask : MaskImage();
}

struct SensorGeometry {
  CameraIntrinsics depth, color;
  Rigid3d world_from_depth, color_from_depth;
};

SensorGeometry GeometryOf(const v1::SensorCalibration& calibration) {
  SensorGeometry g;
  g.depth = *FromProto(calibration.depth_intrinsics());
  g.color = *FromProto(calibration.color_intrinsics());
  g.world_from_depth = *FromProto(calibration.world_from_depth());
  g.color_from_depth = *FromProto(calibration.color_from_depth());
  return g;
}

std::map<std::string, Eigen::Vector3d> JointsByName(const v1::GroundTruthJoints& joints) {
  std::map<std::string, Eigen::Vector3d> by_name;
  for (int j = 0; j < joints.joint_names_size(); ++j) {
    by_name[joints.joint_names(j)] = FromProto(joints.positions_in_world_m(j));
  }
  return by_name;
}

std::string JointName(KinectV2Joint joint) { return std::string(body::KinectV2JointName(joint)); }

double Median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

double Percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  return values[static_cast<size_t>(fraction * (values.size() - 1))];
}

// The ground-truth surface of one frame, with the triangles round each vertex.
struct Surface {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<std::vector<int>> triangles_of_vertex;
};

Surface SurfaceAt(const TakeReader& take, int64_t frame) {
  Surface s;
  const auto mesh = MessageAt<v1::GroundTruthMesh>(take, std::string(kGroundTruthMeshTopic), frame);
  const std::string& bytes = mesh.positions_in_world_m_f32();
  std::vector<float> xyz(bytes.size() / sizeof(float));
  std::memcpy(xyz.data(), bytes.data(), xyz.size() * sizeof(float));
  for (size_t i = 0; i + 2 < xyz.size(); i += 3)
    s.vertices.emplace_back(xyz[i], xyz[i + 1], xyz[i + 2]);
  auto topology = take.ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic);
  EXPECT_TRUE(topology.ok() && topology->size() == 1u);
  if (!topology.ok() || topology->empty()) return s;
  const auto& indices = topology->front().triangle_indices();
  s.triangles_of_vertex.resize(s.vertices.size());
  for (int t = 0; t + 2 < indices.size(); t += 3) {
    s.triangles.push_back({indices[t], indices[t + 1], indices[t + 2]});
    for (int k = 0; k < 3; ++k) s.triangles_of_vertex[indices[t + k]].push_back(t / 3);
  }
  return s;
}

// Distance (metres) from p to the nearest vertex and to the triangles round it.
std::pair<double, double> DistanceToSurface(const Surface& s, const Eigen::Vector3d& p) {
  int nearest = 0;
  double best = std::numeric_limits<double>::max();
  for (size_t v = 0; v < s.vertices.size(); ++v) {
    const double d = (s.vertices[v] - p).squaredNorm();
    if (d < best) best = d, nearest = static_cast<int>(v);
  }
  double surface = std::sqrt(best);
  for (int t : s.triangles_of_vertex[nearest]) {
    const auto& tri = s.triangles[t];
    surface = std::min(surface, PointTriangleDistance(p, s.vertices[tri[0]], s.vertices[tri[1]],
                                                      s.vertices[tri[2]]));
  }
  return {std::sqrt(best), surface};
}

std::map<std::string, uint64_t> ChannelCounts(const TakeReader& take) {
  std::map<std::string, uint64_t> counts;
  for (const TakeChannel& c : take.channels()) counts[c.topic] = c.message_count;
  return counts;
}

bool NothingAt(const std::string& path) {
  return !std::filesystem::exists(path) && !std::filesystem::exists(path + ".partial");
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(SynthesizeTake, WritesEveryChannelOncePerFrame) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const int frames = take.summary.frames;
  ASSERT_GE(frames, 10);
  EXPECT_EQ(take.reader->frame_count(), frames);
  ASSERT_EQ(take.reader->sensors().size(), 2u);
  const auto counts = ChannelCounts(*take.reader);
  for (const auto& [id, calibration] : take.reader->sensors()) {
    for (const char* stream : {"color", "depth", "mask", "skeleton"}) {
      EXPECT_EQ(counts.at(SensorTopic(id, stream)), static_cast<uint64_t>(frames)) << id << stream;
    }
    EXPECT_EQ(counts.at(GroundTruthDepthTopic(id)), static_cast<uint64_t>(frames)) << id;
    EXPECT_EQ(counts.at(SensorTopic(id, "calibration")), 1u) << id;
  }
  for (std::string_view topic :
       {kGroundTruthJointsTopic, kGroundTruthBodyTopic, kGroundTruthMeshTopic}) {
    EXPECT_EQ(counts.at(std::string(topic)), static_cast<uint64_t>(frames)) << topic;
  }
  EXPECT_EQ(counts.at(std::string(kGroundTruthTopologyTopic)), 1u);
  EXPECT_EQ(counts.at(std::string(kTakeInfoTopic)), 1u);
}

// Back-projects the noise-free depth of the actor through the calibrated lens
// and pose, and measures how far those points lie from the ground-truth mesh.
TEST(SynthesizeTake, GroundTruthDepthLiesOnGroundTruthMesh) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const SensorGeometry g = GeometryOf(take.reader->sensors().at("k0"));
  const DepthImageMm depth = DepthAt(*take.reader, GroundTruthDepthTopic("k0"), 0);
  const MaskImage mask = MaskAt(*take.reader, "k0", 0);
  const Surface surface = SurfaceAt(*take.reader, 0);
  ASSERT_FALSE(surface.vertices.empty());
  ASSERT_EQ(depth.width, mask.width);
  std::vector<double> vertex_mm, surface_mm;
  for (int y = 0; y < depth.height; y += 2) {
    for (int x = 0; x < depth.width; x += 2) {
      if (mask.at(x, y) == 0 || depth.at(x, y) == 0) continue;
      auto p = g.depth.Unproject(Eigen::Vector2d(x, y), depth.at(x, y) * 1e-3);
      if (!p) continue;
      const auto [to_vertex, to_surface] = DistanceToSurface(surface, g.world_from_depth * *p);
      vertex_mm.push_back(to_vertex * 1e3);
      surface_mm.push_back(to_surface * 1e3);
    }
  }
  ASSERT_GT(surface_mm.size(), 500u);
  const double median_surface = Median(surface_mm);
  std::cout << "actor pixels " << surface_mm.size() << ": distance to GT mesh surface median "
            << median_surface << " mm, p90 " << Percentile(surface_mm, 0.9)
            << " mm; to nearest vertex median " << Median(vertex_mm) << " mm\n";
  EXPECT_LT(median_surface, 10.0);  // mm
}

TEST(SynthesizeTake, TorsoJointsProjectIntoActorMask) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const SensorGeometry g = GeometryOf(take.reader->sensors().at("k0"));
  auto joints = take.reader->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(joints.ok()) << joints.status();
  int inside = 0, total = 0;
  for (const auto& frame_joints : *joints) {
    const MaskImage mask = MaskAt(*take.reader, "k0", frame_joints.frame_index());
    const auto by_name = JointsByName(frame_joints);
    for (KinectV2Joint j : {KinectV2Joint::kSpineMid, KinectV2Joint::kSpineShoulder}) {
      ++total;
      auto pixel = g.depth.Project(g.world_from_depth.Inverse() * by_name.at(JointName(j)));
      if (!pixel || !g.depth.IsInside(*pixel)) continue;
      const int x = static_cast<int>(std::lround(pixel->x()));
      const int y = static_cast<int>(std::lround(pixel->y()));
      if (mask.at(x, y) > 0) ++inside;
    }
  }
  ASSERT_GT(total, 0);
  const double percent = 100.0 * inside / total;
  std::cout << "torso joints inside the k0 actor mask: " << percent << " %\n";
  EXPECT_GE(percent, 90.0);
}

TEST(SynthesizeTake, SensorSkeletonFollowsGroundTruthWithinJitter) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  auto joints = take.reader->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(joints.ok()) << joints.status();
  std::map<int64_t, std::map<std::string, Eigen::Vector3d>> truth;
  for (const auto& j : *joints) truth[j.frame_index()] = JointsByName(j);
  double sum_mm = 0.0;
  int tracked = 0;
  for (const auto& [id, calibration] : take.reader->sensors()) {
    const SensorGeometry g = GeometryOf(calibration);
    auto skeletons = take.reader->ReadAll<v1::Skeleton>(SensorTopic(id, "skeleton"));
    ASSERT_TRUE(skeletons.ok()) << skeletons.status();
    for (const auto& skeleton : *skeletons) {
      EXPECT_EQ(skeleton.joints_size(), body::kNumKinectV2Joints);
      for (const auto& joint : skeleton.joints()) {
        EXPECT_TRUE(body::KinectV2JointFromName(joint.name()).has_value()) << joint.name();
        if (joint.tracking_state() != v1::TRACKING_STATE_TRACKED) continue;
        const Eigen::Vector3d p = g.world_from_depth * FromProto(joint.position_in_depth_m());
        sum_mm += (p - truth.at(skeleton.frame_index()).at(joint.name())).norm() * 1e3;
        ++tracked;
      }
    }
  }
  ASSERT_GT(tracked, 100);
  const double mean_mm = sum_mm / tracked;
  std::cout << "tracked sensor joints " << tracked << ": mean distance to GT " << mean_mm
            << " mm (10 mm jitter per axis)\n";
  EXPECT_GT(mean_mm, 5.0);   // mm
  EXPECT_LT(mean_mm, 30.0);  // mm
}

TEST(SynthesizeTake, DepthNoiseMatchesKinectV2Model) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const DepthImageMm noisy = DepthAt(*take.reader, SensorTopic("k0", "depth"), 0);
  const DepthImageMm truth = DepthAt(*take.reader, GroundTruthDepthTopic("k0"), 0);
  const MaskImage mask = MaskAt(*take.reader, "k0", 0);
  ASSERT_EQ(noisy.num_pixels(), truth.num_pixels());
  std::vector<double> errors_mm, depths_m;
  for (int y = 2; y < truth.height - 2; ++y) {
    for (int x = 2; x < truth.width - 2; ++x) {
      if (mask.at(x, y) == 0 || noisy.at(x, y) == 0 || truth.at(x, y) == 0) continue;
      // Smooth neighbourhood only: no edge, no steep slope (3 mm over 5x5 px).
      int lo = 65535, hi = 0;
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) {
          lo = std::min<int>(lo, truth.at(x + dx, y + dy));
          hi = std::max<int>(hi, truth.at(x + dx, y + dy));
        }
      }
      if (lo == 0 || hi - lo > 3) continue;
      errors_mm.push_back(static_cast<double>(noisy.at(x, y)) - truth.at(x, y));
      depths_m.push_back(truth.at(x, y) * 1e-3);
    }
  }
  ASSERT_GT(errors_mm.size(), 100u);
  double mean = 0.0, var = 0.0;
  for (double e : errors_mm) mean += e / errors_mm.size();
  for (double e : errors_mm) var += (e - mean) * (e - mean) / errors_mm.size();
  const double z = Median(depths_m);
  std::cout << errors_mm.size() << " smooth actor pixels at " << z << " m: noise std "
            << std::sqrt(var) << " mm (model sigma " << KinectV2AxialSigmaMm(z, 0.0)
            << " mm), mean " << mean << " mm\n";
  EXPECT_GT(std::sqrt(var), 1.0);  // mm
  EXPECT_LT(std::sqrt(var), 6.0);  // mm

  int dropped = 0, valid = 0;
  for (size_t i = 0; i < truth.data.size(); ++i) {
    if (truth.data[i] == 0) continue;
    ++valid;
    if (noisy.data[i] == 0) ++dropped;
  }
  const double dropped_percent = 100.0 * dropped / valid;
  std::cout << "valid in GT but invalid in noisy depth: " << dropped_percent << " %\n";
  EXPECT_GT(dropped_percent, 0.0);
  EXPECT_LT(dropped_percent, 20.0);
}

TEST(SynthesizeTake, DeviceClocksMapToTakeClock) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  auto joints = take.reader->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(joints.ok()) << joints.status();
  std::map<int64_t, int64_t> truth_stamp_ns;
  for (const auto& j : *joints) truth_stamp_ns[j.frame_index()] = j.stamp_ns();
  const double tolerance_ms = 20.0 + 1000.0 / kFps;
  std::vector<int64_t> offsets;
  for (const auto& [id, calibration] : take.reader->sensors()) {
    offsets.push_back(calibration.clock_offset_ns());
    auto depths = take.reader->ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    ASSERT_TRUE(depths.ok()) << depths.status();
    double worst_ms = 0.0;
    for (const auto& d : *depths) {
      const int64_t host_ns = d.device_stamp_ns() + calibration.clock_offset_ns();
      worst_ms = std::max(worst_ms, std::abs(host_ns - truth_stamp_ns.at(d.frame_index())) * 1e-6);
    }
    std::cout << id << ": clock offset " << calibration.clock_offset_ns() * 1e-6
              << " ms, worst device-to-take gap " << worst_ms << " ms\n";
    EXPECT_LE(worst_ms, tolerance_ms);
  }
  ASSERT_EQ(offsets.size(), 2u);
  EXPECT_GT(std::abs(offsets[0] - offsets[1]) * 1e-6, 1.0);  // ms
}

TEST(SynthesizeTake, ColourShowsTheActor) {
  const SharedTake& take = Take();
  ASSERT_NE(take.reader, nullptr);
  const SensorGeometry g = GeometryOf(take.reader->sensors().at("k0"));
  const auto message = MessageAt<v1::ColorImage>(*take.reader, SensorTopic("k0", "color"), 0);
  auto rgb = DecodeJpeg(message.data());
  ASSERT_TRUE(rgb.ok()) << rgb.status();
  EXPECT_EQ(rgb->width, kColorWidth);
  EXPECT_EQ(rgb->height, kColorHeight);
  const auto by_name = JointsByName(
      MessageAt<v1::GroundTruthJoints>(*take.reader, std::string(kGroundTruthJointsTopic), 0));
  const Rigid3d color_from_world = g.color_from_depth * g.world_from_depth.Inverse();
  for (KinectV2Joint j :
       {KinectV2Joint::kSpineMid, KinectV2Joint::kSpineShoulder, KinectV2Joint::kSpineBase}) {
    auto pixel = g.color.Project(color_from_world * by_name.at(JointName(j)));
    ASSERT_TRUE(pixel && g.color.IsInside(*pixel)) << JointName(j);
    double sum = 0.0;
    int n = 0;
    for (int dy = -2; dy <= 2; ++dy) {
      for (int dx = -2; dx <= 2; ++dx) {
        const int x = std::clamp(static_cast<int>(std::lround(pixel->x())) + dx, 0, rgb->width - 1);
        const int y =
            std::clamp(static_cast<int>(std::lround(pixel->y())) + dy, 0, rgb->height - 1);
        for (int c = 0; c < 3; ++c, ++n) sum += rgb->at(x, y, c);
      }
    }
    std::cout << JointName(j) << " at colour pixel (" << pixel->x() << ", " << pixel->y()
              << "): mean level " << sum / n << "\n";
    EXPECT_GT(sum / n, 20.0);  // 8-bit levels
  }
}

TEST(SynthesizeTake, TopologyCarriesTheTruthsAppearance) {
  const SharedTake& shared = Take();
  ASSERT_NE(shared.reader, nullptr);
  auto topologies = shared.reader->ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic);
  ASSERT_TRUE(topologies.ok() && topologies->size() == 1u);
  const v1::GroundTruthTopology& topology = topologies->front();
  // One uv triangle per triangle, indices into whole (u, v) pairs in [0, 1].
  ASSERT_EQ(topology.uv_triangle_indices_size(), topology.triangle_indices_size());
  ASSERT_EQ(topology.uvs_f32().size() % (2 * sizeof(float)), 0u);
  const size_t num_uvs = topology.uvs_f32().size() / (2 * sizeof(float));
  ASSERT_GT(num_uvs, 0u);
  std::vector<float> uvs(2 * num_uvs);
  std::memcpy(uvs.data(), topology.uvs_f32().data(), topology.uvs_f32().size());
  for (float value : uvs) {
    EXPECT_GE(value, 0.0f);
    EXPECT_LE(value, 1.0f);
  }
  for (uint32_t index : topology.uv_triangle_indices()) EXPECT_LT(index, num_uvs);
  // The albedo is a PNG (signature and IHDR of a 1024 x 1024 image).
  const std::string& png = topology.albedo_png();
  ASSERT_GT(png.size(), 24u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  auto be32 = [&](size_t at) {
    return (static_cast<uint32_t>(static_cast<uint8_t>(png[at])) << 24) |
           (static_cast<uint32_t>(static_cast<uint8_t>(png[at + 1])) << 16) |
           (static_cast<uint32_t>(static_cast<uint8_t>(png[at + 2])) << 8) |
           static_cast<uint32_t>(static_cast<uint8_t>(png[at + 3]));
  };
  EXPECT_EQ(be32(16), 1024u);
  EXPECT_EQ(be32(20), 1024u);
  // The room light of the colour images: unit direction, upward, 0.45 + 0.55.
  const Eigen::Vector3d light = FromProto(topology.direction_to_light_in_world());
  EXPECT_NEAR(light.norm(), 1.0, 1e-9);
  EXPECT_GT(light.y(), 0.5);
  EXPECT_NEAR(topology.ambient(), 0.45, 1e-6);
  EXPECT_NEAR(topology.diffuse(), 0.55, 1e-6);
}

TEST(SynthesizeTake, MakeHumanBodyWalksWithPlausibleStature) {
  const std::string makehuman = testing::TestDataPath("body/makehuman");
  const std::string amc = testing::TestDataPath("mocap/cmu/07_05-walk.amc");
  const std::string asf = testing::TestDataPath("mocap/cmu/07-walk.asf");
  REENACT_REQUIRE_TEST_FILE(makehuman);
  REENACT_REQUIRE_TEST_FILE(amc);
  REENACT_REQUIRE_TEST_FILE(asf);
  SynthOptions options = ShortTakeOptions();
  options.body = "makehuman:" + makehuman;
  options.motion = amc;
  options.asf_path = asf;
  options.num_sensors = 1;
  options.seconds = 0.3;
  options.ground_truth_mesh = false;
  const std::string path = testing::MakeTempDir("synth_makehuman") + "/walk.mcap";
  auto summary = SynthesizeTake(options, path);
  ASSERT_TRUE(summary.ok()) << summary.status();
  auto take = TakeReader::Open(path);
  ASSERT_TRUE(take.ok()) << take.status();
  auto joints = (*take)->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(joints.ok()) << joints.status();
  ASSERT_EQ(joints->size(), static_cast<size_t>(summary->frames));
  for (const auto& frame_joints : *joints) {
    const auto by_name = JointsByName(frame_joints);
    const double foot_y = std::min(by_name.at(JointName(KinectV2Joint::kFootLeft)).y(),
                                   by_name.at(JointName(KinectV2Joint::kFootRight)).y());
    // Head is the base of the skull: a 1.6-1.9 m adult puts it 1.35-1.8 m up.
    const double head_m = by_name.at(JointName(KinectV2Joint::kHead)).y() - foot_y;
    if (frame_joints.frame_index() == 0) {
      std::cout << "MakeHuman " << summary->body_vertices << " vertices, head above lowest foot "
                << head_m << " m\n";
    }
    EXPECT_GT(head_m, 1.3);  // m
    EXPECT_LT(head_m, 1.9);  // m
  }
}

TEST(SynthesizeTake, UnknownBuiltinMotionIsNotFoundAndLeavesNoFile) {
  const std::string path = testing::MakeTempDir("synth_bad_builtin") + "/take.mcap";
  SynthOptions options = ShortTakeOptions();
  options.motion = "builtin:moonwalk";
  auto summary = SynthesizeTake(options, path);
  EXPECT_EQ(summary.status().code(), absl::StatusCode::kNotFound) << summary.status();
  EXPECT_TRUE(NothingAt(path));
}

TEST(SynthesizeTake, MissingMotionFileIsNamedAndLeavesNoFile) {
  const std::string dir = testing::MakeTempDir("synth_missing_bvh");
  const std::string path = dir + "/take.mcap";
  SynthOptions options = ShortTakeOptions();
  options.motion = dir + "/no_such_motion.bvh";
  auto summary = SynthesizeTake(options, path);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("no_such_motion.bvh"), std::string::npos)
      << summary.status();
  EXPECT_TRUE(NothingAt(path));
}

TEST(SynthesizeTake, BadBodySpecIsInvalidArgumentAndLeavesNoFile) {
  const std::string path = testing::MakeTempDir("synth_bad_body") + "/take.mcap";
  SynthOptions options = ShortTakeOptions();
  options.body = "smpl:/nowhere";
  auto summary = SynthesizeTake(options, path);
  EXPECT_EQ(summary.status().code(), absl::StatusCode::kInvalidArgument) << summary.status();
  EXPECT_TRUE(NothingAt(path));
}

TEST(SynthesizeTake, FailedRunKeepsExistingFile) {
  const std::string path = testing::MakeTempDir("synth_keep") + "/take.mcap";
  const std::string sentinel = "an earlier take that must survive\n";
  std::ofstream(path, std::ios::binary) << sentinel;
  SynthOptions options = ShortTakeOptions();
  options.motion = "builtin:moonwalk";
  EXPECT_FALSE(SynthesizeTake(options, path).ok());
  EXPECT_EQ(ReadFile(path), sentinel);
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

// The joints of a take, per frame, in world.
std::vector<std::map<std::string, Eigen::Vector3d>> TruthJoints(const TakeReader& take) {
  std::vector<std::map<std::string, Eigen::Vector3d>> frames;
  auto joints = take.ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  EXPECT_TRUE(joints.ok()) << joints.status();
  if (joints.ok()) {
    for (const auto& j : *joints) frames.push_back(JointsByName(j));
  }
  return frames;
}

// Facing yaw in world (0 = +Z, +90 = +X) of the shoulder line, degrees.
double ShoulderFacingDeg(const Eigen::Vector3d& shoulder_left,
                         const Eigen::Vector3d& shoulder_right) {
  const Eigen::Vector3d left = shoulder_left - shoulder_right;
  const Eigen::Vector3d forward = left.cross(Eigen::Vector3d::UnitY());
  return std::atan2(forward.x(), forward.z()) * 180.0 / M_PI;
}

TEST(SynthesizeTake, YawTurnsThePerformanceAboutTheVertical) {
  const std::string dir = testing::MakeTempDir("synth_yaw");
  SynthOptions options = ShortTakeOptions();
  options.motion = "builtin:front-kick";
  options.num_sensors = 1;
  options.seconds = 0.2;
  options.ground_truth_mesh = false;
  ASSERT_TRUE(SynthesizeTake(options, dir + "/straight.mcap").ok());
  options.yaw_deg = 90.0;
  ASSERT_TRUE(SynthesizeTake(options, dir + "/turned.mcap").ok());
  auto straight = TakeReader::Open(dir + "/straight.mcap");
  auto turned = TakeReader::Open(dir + "/turned.mcap");
  ASSERT_TRUE(straight.ok() && turned.ok());
  const auto straight_joints = TruthJoints(**straight);
  const auto turned_joints = TruthJoints(**turned);
  ASSERT_EQ(straight_joints.size(), turned_joints.size());
  ASSERT_FALSE(straight_joints.empty());
  // Ground truth: every joint is the straight one turned by 90 degrees about
  // +Y through the origin, i.e. (x, y, z) -> (z, y, -x).
  const Eigen::Matrix3d yaw =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  double worst_m = 0.0;
  for (size_t f = 0; f < straight_joints.size(); ++f) {
    for (const auto& [name, p] : straight_joints[f]) {
      worst_m = std::max(worst_m, (yaw * p - turned_joints[f].at(name)).norm());
    }
  }
  const std::string left = JointName(KinectV2Joint::kShoulderLeft);
  const std::string right = JointName(KinectV2Joint::kShoulderRight);
  const double straight_deg =
      ShoulderFacingDeg(straight_joints[0].at(left), straight_joints[0].at(right));
  const double turned_deg =
      ShoulderFacingDeg(turned_joints[0].at(left), turned_joints[0].at(right));
  std::cout << "yaw 90: worst joint off the turned straight take " << worst_m * 1e3
            << " mm; ground-truth facing " << straight_deg << " -> " << turned_deg << " deg\n";
  EXPECT_LT(worst_m, 1e-4);             // m
  EXPECT_NEAR(straight_deg, 0.0, 5.0);  // deg: the built-in motions face +Z
  EXPECT_NEAR(turned_deg, 90.0, 5.0);   // deg: now +X

  // The sensor's skeleton channel sees the turned actor: its shoulder line,
  // taken to world, faces +X as well, and its joints follow the truth.
  const SensorGeometry g = GeometryOf((*turned)->sensors().at("k0"));
  auto skeletons = (*turned)->ReadAll<v1::Skeleton>(SensorTopic("k0", "skeleton"));
  ASSERT_TRUE(skeletons.ok()) << skeletons.status();
  ASSERT_EQ(skeletons->size(), turned_joints.size());
  double sum_deg = 0.0, sum_mm = 0.0;
  int joints = 0;
  for (const v1::Skeleton& skeleton : *skeletons) {
    std::map<std::string, Eigen::Vector3d> in_world;
    for (const auto& joint : skeleton.joints()) {
      in_world[joint.name()] = g.world_from_depth * FromProto(joint.position_in_depth_m());
      sum_mm +=
          (in_world[joint.name()] - turned_joints[skeleton.frame_index()].at(joint.name())).norm() *
          1e3;
      ++joints;
    }
    sum_deg += ShoulderFacingDeg(in_world.at(left), in_world.at(right));
  }
  const double skeleton_deg = sum_deg / skeletons->size();
  std::cout << "yaw 90: k0 skeleton channel facing " << skeleton_deg
            << " deg, mean joint distance to the truth " << sum_mm / joints << " mm\n";
  EXPECT_NEAR(skeleton_deg, 90.0, 5.0);  // deg
  EXPECT_LT(sum_mm / joints, 50.0);      // mm (1 cm jitter, 3 cm where inferred)
}

// A tracker that has not found the body yet: no joint of any sensor's
// skeleton is tracked before lock_on_s, and joints are tracked after it.
TEST(SynthesizeTake, NoJointIsTrackedBeforeTheTrackerLocksOn) {
  SynthOptions options = ShortTakeOptions();
  options.skeleton_errors.lock_on_s = 0.2;
  const std::string path = testing::MakeTempDir("synth_lock_on") + "/take.mcap";
  auto summary = SynthesizeTake(options, path);
  if (!summary.ok() && summary.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << summary.status();
  }
  ASSERT_TRUE(summary.ok()) << summary.status();
  auto reader = TakeReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const int lock_on_frames = static_cast<int>(std::lround(options.fps * 0.2));
  int tracked_before = 0, tracked_after = 0, skeletons = 0;
  for (const auto& [id, calibration] : (*reader)->sensors()) {
    auto all = (*reader)->ReadAll<v1::Skeleton>(SensorTopic(id, "skeleton"));
    ASSERT_TRUE(all.ok()) << all.status();
    for (const v1::Skeleton& skeleton : *all) {
      ++skeletons;
      for (const auto& joint : skeleton.joints()) {
        if (joint.tracking_state() == v1::TRACKING_STATE_NOT_TRACKED) continue;
        (skeleton.frame_index() < lock_on_frames ? tracked_before : tracked_after)++;
      }
    }
  }
  EXPECT_GT(skeletons, 2 * lock_on_frames);
  EXPECT_EQ(tracked_before, 0);
  EXPECT_GT(tracked_after, 20);
  for (const double bad : {-1.0, 4000.0, std::numeric_limits<double>::quiet_NaN()}) {
    options.skeleton_errors.lock_on_s = bad;
    EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

TEST(SynthesizeTake, NonFiniteYawIsInvalidArgument) {
  SynthOptions options = ShortTakeOptions();
  options.yaw_deg = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
  options.yaw_deg = -90.0;
  EXPECT_TRUE(options.Validate().ok());
}

TEST(SynthesizeTake, LeadInHoldsTheFirstPoseThenPlaysTheMotionLater) {
  const std::string dir = testing::MakeTempDir("synth_lead_in");
  SynthOptions options = ShortTakeOptions();
  options.motion = "builtin:arm-raise";  // Moves from its first frame on.
  options.num_sensors = 1;
  options.fps = 10.0;
  options.seconds = 0.8;
  options.ground_truth_mesh = false;
  ASSERT_TRUE(SynthesizeTake(options, dir + "/straight.mcap").ok());
  options.lead_in_s = 0.5;
  options.seconds = 1.3;
  ASSERT_TRUE(SynthesizeTake(options, dir + "/lead-in.mcap").ok());
  auto straight = TakeReader::Open(dir + "/straight.mcap");
  auto lead_in = TakeReader::Open(dir + "/lead-in.mcap");
  ASSERT_TRUE(straight.ok() && lead_in.ok());
  const auto straight_joints = TruthJoints(**straight);
  const auto lead_in_joints = TruthJoints(**lead_in);
  ASSERT_EQ(straight_joints.size(), 8u);
  ASSERT_EQ(lead_in_joints.size(), 13u);
  // Frames 0..5 (0 to 0.5 s) show the first pose; frame 5 + k shows frame k.
  double still_m = 0.0, shifted_m = 0.0;
  for (size_t f = 0; f < lead_in_joints.size(); ++f) {
    const size_t k = f < 5 ? 0 : f - 5;
    for (const auto& [name, p] : lead_in_joints[f]) {
      double& worst_m = f < 5 ? still_m : shifted_m;
      worst_m = std::max(worst_m, (p - straight_joints[k].at(name)).norm());
    }
  }
  const std::string hand = JointName(KinectV2Joint::kHandLeft);
  const double moved_m = (straight_joints[7].at(hand) - straight_joints[0].at(hand)).norm();
  std::cout << "lead-in 0.5 s: still frames within " << still_m * 1e3
            << " mm of the first pose, later frames within " << shifted_m * 1e3
            << " mm of the motion 0.5 s earlier; the left hand moves " << moved_m * 1e3
            << " mm over the first 0.7 s of the motion\n";
  EXPECT_LT(still_m, 1e-4);    // m
  EXPECT_LT(shifted_m, 1e-4);  // m
  EXPECT_GT(moved_m, 0.05);    // m: so that a missing lead-in would show
  options.lead_in_s = -1.0;
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
}

TEST(SynthesizeTake, BoardLiesOnTheFloorWhereTheTruthSays) {
  const std::string dir = testing::MakeTempDir("synth_board");
  SynthOptions options = ShortTakeOptions();
  options.num_sensors = 1;
  options.seconds = 0.1;
  options.color_width = 1920;  // Kinect v2 colour: the board is 2.7 m away.
  options.color_height = 1080;
  options.ground_truth_mesh = false;
  options.board = board::kDefaultBoardSpecText;
  ASSERT_TRUE(SynthesizeTake(options, dir + "/board.mcap").ok());
  auto take = TakeReader::Open(dir + "/board.mcap");
  ASSERT_TRUE(take.ok()) << take.status();
  auto topology = (*take)->ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic);
  ASSERT_TRUE(topology.ok() && topology->size() == 1u);
  EXPECT_EQ(topology->front().board_spec(), board::kDefaultBoardSpecText);
  auto world_from_board = FromProto(topology->front().world_from_board());
  ASSERT_TRUE(world_from_board.ok());
  EXPECT_NEAR((world_from_board->translation - Eigen::Vector3d(1.0, 0.0, 0.0)).norm(), 0.0, 1e-12);

  // The sensor finds the board in its colour image where the truth puts it.
  const SensorGeometry g = GeometryOf((*take)->sensors().at("k0"));
  auto colours = (*take)->ReadAll<v1::ColorImage>(SensorTopic("k0", "color"));
  ASSERT_TRUE(colours.ok() && !colours->empty());
  auto image = DecodeJpeg(colours->front().data());
  ASSERT_TRUE(image.ok()) << image.status();
  auto found = board::DetectBoard(*image, g.color, *board::ParseBoardSpec(options.board));
  ASSERT_TRUE(found.ok()) << found.status();
  const Rigid3d world_from_colour = g.world_from_depth * g.color_from_depth.Inverse();
  const Eigen::Isometry3d truth((world_from_colour.Inverse() * *world_from_board).ToMatrix4());
  const Eigen::Isometry3d delta = found->camera_from_board * truth.inverse();
  const double rotation_deg = Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI;
  const double position_mm =
      1e3 * (found->camera_from_board.translation() - truth.translation()).norm();
  std::cout << "board in the synthetic colour: " << found->num_markers << " markers, RMS "
            << found->reprojection_rms_px << " px, rotation error " << rotation_deg
            << " deg, position error " << position_mm << " mm\n";
  EXPECT_GE(found->num_markers, 3);  // Of 6; one is enough for a pose.
  EXPECT_LT(rotation_deg, 1.0);      // deg
  EXPECT_LT(position_mm, 20.0);      // mm

  options.board = "aruco:DICT_4X4_50:0x2:110:22";
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
  options.board = board::kDefaultBoardSpecText;
  options.board_x_m = 9.0;
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
}

TEST(SynthesizeTake, SameSeedGivesSameDepth) {
  const std::string dir = testing::MakeTempDir("synth_seed");
  SynthOptions options = ShortTakeOptions();
  options.num_sensors = 1;
  options.seconds = 1.0 / kFps;
  options.ground_truth_mesh = false;
  auto depth_bytes = [&](uint64_t seed, const std::string& name) -> std::string {
    options.seed = seed;
    auto summary = SynthesizeTake(options, dir + "/" + name);
    EXPECT_TRUE(summary.ok()) << summary.status();
    auto take = TakeReader::Open(dir + "/" + name);
    EXPECT_TRUE(take.ok()) << take.status();
    if (!take.ok()) return "";
    return MessageAt<v1::DepthImage>(**take, SensorTopic("k0", "depth"), 0).data();
  };
  const std::string a = depth_bytes(7, "a.mcap");
  const std::string b = depth_bytes(7, "b.mcap");
  const std::string c = depth_bytes(8, "c.mcap");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);  // Another seed draws other noise.
}

}  // namespace
}  // namespace reenact::synth
