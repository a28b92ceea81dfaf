// Hand-made scenes for the VDTM tests: one flat square part facing +Z,
// sensors on a circle round it looking at its centre, keyframes of one
// solid colour each, so that the colour drawn tells which keyframe it came
// from.
#pragma once

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/model/reenactment.h"
#include "common/render/render_types.h"

namespace reenact::view::testing {

inline constexpr int kImageWidth = 160;
inline constexpr int kImageHeight = 120;
inline constexpr double kFocalPx = 150.0;
inline const Eigen::Vector3d kCentre(0.0, 1.0, 0.0);  // Of the square, world.
inline constexpr double kHalfSide = 0.2;              // Of the square, metres.
inline constexpr int kSubdivisions = 8;               // Of the square, per side.

inline double Rad(double deg) { return deg * std::numbers::pi / 180.0; }

// A camera on a circle of `distance_m` round kCentre at `yaw_deg` about +Y
// (0: on +Z), looking at kCentre, OpenCV axes.
inline Eigen::Isometry3d WorldFromCamera(double yaw_deg, double distance_m = 2.0) {
  Eigen::Matrix3d looking_down_minus_z;
  looking_down_minus_z.col(0) = Eigen::Vector3d::UnitX();
  looking_down_minus_z.col(1) = -Eigen::Vector3d::UnitY();
  looking_down_minus_z.col(2) = -Eigen::Vector3d::UnitZ();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(Rad(yaw_deg), Eigen::Vector3d::UnitY()) * looking_down_minus_z;
  pose.translation() = kCentre - distance_m * pose.linear().col(2);
  return pose;
}

inline SensorCalibration MakeSensor(const std::string& id, double yaw_deg) {
  SensorCalibration sensor;
  sensor.sensor_id = id;
  CameraIntrinsics k;
  k.width = kImageWidth;
  k.height = kImageHeight;
  k.fx = k.fy = kFocalPx;
  k.cx = (kImageWidth - 1) / 2.0;
  k.cy = (kImageHeight - 1) / 2.0;
  sensor.color_intrinsics = k;
  sensor.depth_intrinsics = k;
  const Eigen::Isometry3d pose = WorldFromCamera(yaw_deg);
  sensor.world_from_depth = Rigid3d(Eigen::Quaterniond(pose.linear()), pose.translation());
  return sensor;
}

inline render::RenderCamera ViewerCamera(double yaw_deg) {
  render::RenderCamera camera;
  camera.width = kImageWidth;
  camera.height = kImageHeight;
  camera.fx = camera.fy = kFocalPx;
  camera.cx = kImageWidth / 2.0;
  camera.cy = kImageHeight / 2.0;
  camera.world_from_camera = WorldFromCamera(yaw_deg);
  return camera;
}

// The square in its part frame: z = 0, facing +Z, (kSubdivisions + 1)^2
// vertices in rows of constant y, counter-clockwise seen from +Z.
inline PartMesh MakeSquarePart(int part, const std::string& name) {
  const int n = kSubdivisions + 1;
  PartMesh mesh;
  mesh.part = part;
  mesh.name = name;
  mesh.positions_in_part_m.resize(3, n * n);
  mesh.normals_in_part.resize(3, n * n);
  mesh.uvs.resize(2, n * n);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = -kHalfSide + 2 * kHalfSide * i / kSubdivisions;
      const double y = -kHalfSide + 2 * kHalfSide * j / kSubdivisions;
      mesh.positions_in_part_m.col(j * n + i) =
          Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), 0.0f);
      mesh.normals_in_part.col(j * n + i) = Eigen::Vector3f::UnitZ();
      mesh.uvs.col(j * n + i) = Eigen::Vector2f(static_cast<float>(i) / kSubdivisions,
                                                static_cast<float>(j) / kSubdivisions);
    }
  }
  for (int j = 0; j < kSubdivisions; ++j) {
    for (int i = 0; i < kSubdivisions; ++i) {
      const int p = j * n + i;
      mesh.triangles.emplace_back(p, p + 1, p + n + 1);
      mesh.triangles.emplace_back(p, p + n + 1, p + n);
    }
  }
  mesh.reference_length_m = static_cast<float>(2 * kHalfSide);
  return mesh;
}

inline int SquareVertexCount() { return (kSubdivisions + 1) * (kSubdivisions + 1); }

// Part 0 at kCentre turned `part_yaw_deg` about +Y, with `scale`; joints
// (optional) in the world.
inline ReenactmentFrame MakeFrame(int index, double part_yaw_deg, double scale = 1.0,
                                  const std::vector<Eigen::Vector3d>& joints = {}) {
  ReenactmentFrame frame;
  frame.frame_index = index;
  frame.stamp_ns = 1'000'000'000LL + index * 33'333'333LL;
  PartPose& pose = frame.parts.emplace_back();
  pose.world_from_part.linear() =
      Eigen::AngleAxisd(Rad(part_yaw_deg), Eigen::Vector3d::UnitY()).toRotationMatrix();
  pose.world_from_part.translation() = kCentre;
  pose.scale = static_cast<float>(scale);  // As stored: float32.
  pose.valid = true;
  frame.joints_in_world_m = joints;
  return frame;
}

// A whole-image keyframe of one colour, every vertex visible, all actor.
inline TextureKeyframe SolidKeyframe(int frame, const std::string& sensor_id,
                                     const Eigen::Vector3i& rgb) {
  RgbImage image(kImageWidth, kImageHeight);
  for (int y = 0; y < kImageHeight; ++y) {
    for (int x = 0; x < kImageWidth; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = static_cast<uint8_t>(rgb[c]);
    }
  }
  TextureKeyframe keyframe;
  keyframe.frame_index = frame;
  keyframe.sensor_id = sensor_id;
  keyframe.color_jpeg = EncodeJpeg(image, 95).value();
  keyframe.mask_rle = EncodeMaskRle(MaskImage(kImageWidth, kImageHeight, 1));
  keyframe.vertex_visible_bits.emplace_back((SquareVertexCount() + 7) / 8, '\xff');
  return keyframe;
}

// Clears the visibility bit of every vertex of part 0 in `keyframe` whose
// part-frame x is below `x_below` (row-major grid of MakeSquarePart).
inline void HideVertices(TextureKeyframe* keyframe, double x_below) {
  std::string& bits = keyframe->vertex_visible_bits[0];
  const int n = kSubdivisions + 1;
  for (int v = 0; v < SquareVertexCount(); ++v) {
    const double x = -kHalfSide + 2 * kHalfSide * (v % n) / kSubdivisions;
    if (x < x_below) bits[v / 8] = static_cast<char>(bits[v / 8] & ~(1 << (v % 8)));
  }
}

// One square part, `frames`, sensors at the given yaws ("s0", "s1", ...).
inline Reenactment MakeSquareReenactment(const std::vector<ReenactmentFrame>& frames,
                                         const std::vector<double>& sensor_yaws_deg,
                                         const std::string& method = "rigid-carved") {
  Reenactment data;
  data.info.reenactment_id = "r-square";
  data.info.method = method;
  data.info.frame_count = static_cast<int>(frames.size());
  data.info.fps = 30.0;
  data.info.part_names.push_back("chest");
  for (size_t s = 0; s < sensor_yaws_deg.size(); ++s) {
    data.info.sensors.push_back(MakeSensor("s" + std::to_string(s), sensor_yaws_deg[s]));
  }
  data.parts.push_back(MakeSquarePart(0, "chest"));
  data.frames = frames;
  return data;
}

}  // namespace reenact::view::testing
