#include "server/recon/texturing.h"

#include <cmath>
#include <cstdio>
#include <optional>

#include <gtest/gtest.h>

#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"

namespace reenact::recon {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kPi = 3.14159265358979323846;

// ------------------------------------------------------------ the scene --
// Two boxes seen by one RGB-D sensor: part 0 a large flat box, part 1 a
// small box in front of it (frame 0) that hides the middle of part 0's front
// face; in frame 1 the small box stands aside and the large box is turned
// by 25 degrees. Colours are painted by a known smooth pattern of the point
// in the part frame, images made by ray casting.

// A box of half extents `h` centred on the part origin, each face a
// `subdiv` x `subdiv` grid with its own vertices and flat normals,
// triangles counter-clockwise seen from outside.
PartMesh MakeBox(const Vector3f& h, int subdiv) {
  std::vector<Vector3f> positions, normals;
  std::vector<Eigen::Vector3i> triangles;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {-1, 1}) {
      Vector3f n = Vector3f::Zero();
      n[axis] = static_cast<float>(sign);
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // a x b = axis.
      const int base = static_cast<int>(positions.size());
      for (int j = 0; j <= subdiv; ++j) {
        for (int i = 0; i <= subdiv; ++i) {
          Vector3f p;
          p[axis] = sign * h[axis];
          p[a] = h[a] * (2.0f * i / subdiv - 1.0f);
          p[b] = h[b] * (2.0f * j / subdiv - 1.0f);
          positions.push_back(p);
          normals.push_back(n);
        }
      }
      for (int j = 0; j < subdiv; ++j) {
        for (int i = 0; i < subdiv; ++i) {
          const int v00 = base + j * (subdiv + 1) + i, v10 = v00 + 1;
          const int v01 = v00 + subdiv + 1, v11 = v01 + 1;
          if (sign > 0) {
            triangles.emplace_back(v00, v10, v11);
            triangles.emplace_back(v00, v11, v01);
          } else {
            triangles.emplace_back(v00, v11, v10);
            triangles.emplace_back(v00, v01, v11);
          }
        }
      }
    }
  }
  PartMesh g;
  g.positions_in_part_m.resize(3, positions.size());
  g.normals_in_part.resize(3, normals.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    g.positions_in_part_m.col(i) = positions[i];
    g.normals_in_part.col(i) = normals[i];
  }
  g.triangles = triangles;
  return g;
}

const Vector3f kHalf0(0.3f, 0.3f, 0.1f);
const Vector3f kHalf1(0.1f, 0.1f, 0.1f);

// MakeBox(half, 8) as part `part` named `name`.
PartMesh BoxPart(int part, const std::string& name, const Vector3f& half) {
  PartMesh mesh = MakeBox(half, 8);
  mesh.part = part;
  mesh.name = name;
  return mesh;
}

// The painted colour of a point of part `part` (part frame, metres).
Vector3f Pattern(int part, const Vector3d& p) {
  const double k = 2.0 * kPi / 0.3;
  return Vector3f(static_cast<float>(128 + 90 * std::sin(k * p.x())),
                  static_cast<float>(128 + 90 * std::sin(k * p.y() + 1.0)),
                  static_cast<float>((part == 0 ? 70 : 190) + 40 * std::sin(k * p.z())));
}

const Vector3f kBackground(20, 150, 40);

reenact::PartPose Pose(const Vector3d& translation, double yaw_deg = 0.0) {
  reenact::PartPose pose;
  pose.world_from_part.linear() =
      Eigen::AngleAxisd(yaw_deg * kPi / 180.0, Vector3d::UnitY()).toRotationMatrix();
  pose.world_from_part.translation() = translation;
  pose.valid = true;
  return pose;
}

struct Hit {
  int part = -1;
  double t = 0.0;    // Ray parameter (distance for unit directions), metres.
  Vector3d in_part;  // Hit point, part frame.
};

// Nearest hit of the ray o + t d (world) with the posed boxes (slab test).
std::optional<Hit> CastRay(const Vector3d& o, const Vector3d& d,
                           const std::vector<reenact::PartPose>& poses) {
  std::optional<Hit> best;
  for (size_t i = 0; i < poses.size(); ++i) {
    if (!poses[i].valid) continue;
    const Vector3d h = (i == 0 ? kHalf0 : kHalf1).cast<double>() * poses[i].scale;
    const Eigen::Matrix3d rt = poses[i].world_from_part.linear().transpose();
    const Vector3d op = rt * (o - poses[i].world_from_part.translation());
    const Vector3d dp = rt * d;
    double t0 = -1e30, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(dp[a]) < 1e-12) {
        if (std::abs(op[a]) > h[a]) t0 = 1e30;
        continue;
      }
      double ta = (-h[a] - op[a]) / dp[a], tb = (h[a] - op[a]) / dp[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    if (t0 > t1 || t0 <= 0.0) continue;
    if (!best || t0 < best->t) best = Hit{static_cast<int>(i), t0, (op + t0 * dp) / poses[i].scale};
  }
  return best;
}

struct Sensor {
  SensorCalibration calibration;
  CameraIntrinsics color;  // Full resolution.
  CameraIntrinsics depth;
  Rigid3d world_from_depth;
  Rigid3d color_from_depth;
  Rigid3d world_from_color() const { return world_from_depth * color_from_depth.Inverse(); }
};

Sensor MakeSensor() {
  Sensor s;
  s.color = {640, 480, 525.0, 525.0, 319.5, 239.5};
  s.depth = {320, 240, 262.0, 262.0, 159.5, 119.5};
  s.color_from_depth = Rigid3d(Eigen::Quaterniond::Identity(), Vector3d(-0.052, 0.0, 0.0));
  // Depth camera 1.2 m above the floor at the world origin, looking along
  // world -Z (camera y down = world -Y).
  s.world_from_depth =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Vector3d::UnitX())), Vector3d(0, 1.2, 0));
  s.calibration.sensor_id = "k0";
  s.calibration.model = "test";
  s.calibration.color_intrinsics = s.color;
  s.calibration.depth_intrinsics = s.depth;
  s.calibration.color_from_depth = s.color_from_depth;
  s.calibration.world_from_depth = s.world_from_depth;
  s.calibration.depth_scale_m_per_unit = 0.001;
  return s;
}

// The world ray through `pixel` of a camera at world_from_camera.
std::pair<Vector3d, Vector3d> PixelRay(const CameraIntrinsics& k, const Rigid3d& world_from_camera,
                                       const Vector2d& pixel) {
  const Vector3d d((pixel.x() - k.cx) / k.fx, (pixel.y() - k.cy) / k.fy, 1.0);
  return {world_from_camera.translation, world_from_camera.rotation * d.normalized()};
}

// Colour rendered with intrinsics `k` (full or scaled), one ray per pixel.
RgbImage RenderColour(const Sensor& s, const CameraIntrinsics& k,
                      const std::vector<reenact::PartPose>& poses) {
  RgbImage image(k.width, k.height);
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const auto [o, d] = PixelRay(k, s.world_from_color(), Vector2d(x, y));
      const auto hit = CastRay(o, d, poses);
      const Vector3f c = hit ? Pattern(hit->part, hit->in_part) : kBackground;
      for (int ch = 0; ch < 3; ++ch) image.at(x, y, ch) = static_cast<uint8_t>(std::lround(c[ch]));
    }
  }
  return image;
}

struct DepthAndMask {
  DepthImageMm depth;
  MaskImage mask;
};

DepthAndMask RenderDepth(const Sensor& s, const std::vector<reenact::PartPose>& poses) {
  DepthAndMask out{DepthImageMm(s.depth.width, s.depth.height),
                   MaskImage(s.depth.width, s.depth.height)};
  for (int y = 0; y < s.depth.height; ++y) {
    for (int x = 0; x < s.depth.width; ++x) {
      const auto [o, d] = PixelRay(s.depth, s.world_from_depth, Vector2d(x, y));
      const auto hit = CastRay(o, d, poses);
      if (!hit) continue;
      const Vector3d in_depth = s.world_from_depth.Inverse() * (o + hit->t * d);
      out.depth.at(x, y) = static_cast<uint16_t>(std::lround(in_depth.z() * 1000.0));
      out.mask.at(x, y) = 1;
    }
  }
  return out;
}

std::vector<reenact::PartPose> Frame0Poses() {
  return {Pose(Vector3d(0.0, 1.2, -2.5)), Pose(Vector3d(0.05, 1.2, -1.9))};
}
std::vector<reenact::PartPose> Frame1Poses() {
  return {Pose(Vector3d(0.0, 1.2, -2.5), 25.0), Pose(Vector3d(0.65, 1.2, -2.2))};
}

struct Scene {
  Sensor sensor = MakeSensor();
  std::vector<PartMesh> parts = {BoxPart(0, "big", kHalf0), BoxPart(1, "small", kHalf1)};
};

TextureKeyframe MakeKeyframe(const Scene& scene, const std::vector<reenact::PartPose>& poses,
                             int frame_index, const KeyframeOptions& options = {},
                             int colour_divisor = 1) {
  const CameraIntrinsics k =
      *ScaledIntrinsics(scene.sensor.color, scene.sensor.color.width / colour_divisor,
                        scene.sensor.color.height / colour_divisor);
  const RgbImage colour = RenderColour(scene.sensor, k, poses);
  const DepthAndMask dm = RenderDepth(scene.sensor, poses);
  const SensorImages images{scene.sensor.calibration, colour, dm.mask, dm.depth};
  auto keyframe = MakeTextureKeyframe(scene.parts, poses, images, frame_index, 1000 * frame_index,
                                      "k0", options);
  EXPECT_TRUE(keyframe.ok()) << keyframe.status();
  return keyframe.ok() ? *keyframe : TextureKeyframe();
}

// Ground truth: the vertex faces the colour camera, lies in the image and
// the first surface along its ray is itself (within 1 cm).
bool TrulyVisible(const Scene& scene, const std::vector<reenact::PartPose>& poses, int part,
                  int v) {
  const reenact::PartPose& pose = poses[part];
  const Vector3d p =
      pose.world_from_part * scene.parts[part].positions_in_part_m.col(v).cast<double>();
  const Vector3d n =
      pose.world_from_part.linear() * scene.parts[part].normals_in_part.col(v).cast<double>();
  const Vector3d c = scene.sensor.world_from_color().translation;
  if (n.dot(p - c) >= 0.0) return false;
  const auto pixel = scene.sensor.color.Project(scene.sensor.world_from_color().Inverse() * p);
  if (!pixel || !scene.sensor.color.IsInside(*pixel)) return false;
  const auto hit = CastRay(c, (p - c).normalized(), poses);
  return hit && hit->t >= (p - c).norm() - 0.01;
}

// Whether the rays through `pixel` and its four neighbours at +-3 px all hit
// part `part` (a vertex well inside that part's silhouette).
bool WellInsideSilhouette(const Scene& scene, const std::vector<reenact::PartPose>& poses,
                          const Vector2d& pixel, int part) {
  for (const Vector2d& off :
       {Vector2d(0, 0), Vector2d(3, 0), Vector2d(-3, 0), Vector2d(0, 3), Vector2d(0, -3)}) {
    const auto [o, d] = PixelRay(scene.sensor.color, scene.sensor.world_from_color(), pixel + off);
    const auto hit = CastRay(o, d, poses);
    if (!hit || hit->part != part) return false;
  }
  return true;
}

std::optional<Vector2d> ColourPixel(const Scene& scene, const reenact::PartPose& pose,
                                    const Vector3d& in_part) {
  return scene.sensor.color.Project(scene.sensor.world_from_color().Inverse() *
                                    (pose.world_from_part * in_part));
}

// ---------------------------------------------------------------- tests --

TEST(MakeTextureKeyframe, VisibilityBitsFollowOcclusion) {
  const Scene scene;
  const auto poses = Frame0Poses();
  const TextureKeyframe keyframe = MakeKeyframe(scene, poses, 0);
  ASSERT_EQ(static_cast<int>(keyframe.vertex_visible_bits.size()), 2);
  int occluded_checked = 0, occluded_wrong = 0, visible_checked = 0, visible_wrong = 0;
  int truth_count = 0, bit_count = 0, agree = 0, total = 0;
  for (int part = 0; part < 2; ++part) {
    const int n = static_cast<int>(scene.parts[part].positions_in_part_m.cols());
    ASSERT_EQ(keyframe.vertex_visible_bits[part].size(), static_cast<size_t>((n + 7) / 8));
    for (int v = 0; v < n; ++v) {
      const bool bit = VertexVisible(keyframe.vertex_visible_bits[part], v);
      const bool truth = TrulyVisible(scene, poses, part, v);
      truth_count += truth;
      bit_count += bit;
      agree += truth == bit;
      ++total;
      const Vector3d x = scene.parts[part].positions_in_part_m.col(v).cast<double>();
      const auto pixel = ColourPixel(scene, poses[part], x);
      if (!pixel) continue;
      const Vector3d n_world = poses[part].world_from_part.linear() *
                               scene.parts[part].normals_in_part.col(v).cast<double>();
      const bool facing = n_world.z() > 0.5;  // Front faces (camera looks along -Z).
      if (part == 0 && facing && WellInsideSilhouette(scene, poses, *pixel, 1)) {
        ++occluded_checked;
        occluded_wrong += bit;
      }
      if (truth && WellInsideSilhouette(scene, poses, *pixel, part)) {
        ++visible_checked;
        visible_wrong += !bit;
      }
    }
  }
  // The small box hides a 0.2 m square of the large box's front face: about
  // 4 x 4 grid vertices, at least 9 well inside its silhouette.
  EXPECT_GE(occluded_checked, 9);
  EXPECT_EQ(occluded_wrong, 0) << "hidden vertices marked visible";
  EXPECT_GE(visible_checked, 60);  // Inner front-face vertices of both boxes, less the hidden.
  EXPECT_EQ(visible_wrong, 0) << "clearly visible vertices marked hidden";
  EXPECT_NEAR(bit_count, truth_count, 0.05 * truth_count);
  EXPECT_GE(static_cast<double>(agree) / total, 0.98);
  std::printf(
      "visibility: %d/%d bits agree with ray casting; %d set, %d truly visible; "
      "%d hidden checked, %d visible checked\n",
      agree, total, bit_count, truth_count, occluded_checked, visible_checked);
}

TEST(MakeTextureKeyframe, CropCoversTheActorAndMaskMatches) {
  const Scene scene;
  const auto poses = Frame0Poses();
  KeyframeOptions options;
  const TextureKeyframe keyframe = MakeKeyframe(scene, poses, 0, options);
  const auto crop = DecodeJpeg(keyframe.color_jpeg);
  const auto mask = DecodeMaskRle(keyframe.mask_rle);
  ASSERT_TRUE(crop.ok() && mask.ok());
  ASSERT_EQ(crop->width, mask->width);
  ASSERT_EQ(crop->height, mask->height);
  EXPECT_FLOAT_EQ(keyframe.crop_scale, 1.0f);
  // Ground-truth actor in full colour pixels.
  const CameraIntrinsics& k = scene.sensor.color;
  int x_min = k.width, x_max = -1, y_min = k.height, y_max = -1;
  int inter = 0, uni = 0;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const auto [o, d] = PixelRay(k, scene.sensor.world_from_color(), Vector2d(x, y));
      const bool actor = CastRay(o, d, poses).has_value();
      if (actor) {
        x_min = std::min(x_min, x), x_max = std::max(x_max, x);
        y_min = std::min(y_min, y), y_max = std::max(y_max, y);
      }
      const int cx = x - keyframe.crop_x_px, cy = y - keyframe.crop_y_px;
      const bool in_mask =
          cx >= 0 && cy >= 0 && cx < mask->width && cy < mask->height && mask->at(cx, cy) > 0;
      inter += actor && in_mask;
      uni += actor || in_mask;
    }
  }
  ASSERT_GE(x_max, 0);
  // The crop holds the actor's box and no more than the margin (+4 px for
  // the depth camera's coarser silhouette) around it.
  EXPECT_LE(keyframe.crop_x_px, x_min);
  EXPECT_LE(keyframe.crop_y_px, y_min);
  EXPECT_GE(keyframe.crop_x_px + crop->width - 1, x_max);
  EXPECT_GE(keyframe.crop_y_px + crop->height - 1, y_max);
  EXPECT_GE(keyframe.crop_x_px, x_min - options.margin_px - 4);
  EXPECT_GE(keyframe.crop_y_px, y_min - options.margin_px - 4);
  EXPECT_LE(keyframe.crop_x_px + crop->width - 1, x_max + options.margin_px + 4);
  EXPECT_LE(keyframe.crop_y_px + crop->height - 1, y_max + options.margin_px + 4);
  const double iou = static_cast<double>(inter) / uni;
  EXPECT_GE(iou, 0.97) << "mask IoU against the ray-cast silhouette";
  std::printf("crop %dx%d at (%d, %d) for actor box x %d..%d y %d..%d; mask IoU %.4f\n",
              crop->width, crop->height, keyframe.crop_x_px, keyframe.crop_y_px, x_min, x_max,
              y_min, y_max, iou);
}

// Mean absolute error (8-bit levels) between the crop at the projection of
// clearly visible vertices and their painted colour.
double VertexColourError(const Scene& scene, const std::vector<reenact::PartPose>& poses,
                         const TextureKeyframe& keyframe, int* count) {
  const auto camera = KeyframeCameraOf(scene.sensor.calibration, keyframe);
  const auto crop = DecodeJpeg(keyframe.color_jpeg);
  EXPECT_TRUE(camera.ok() && crop.ok());
  double error = 0.0;
  *count = 0;
  for (int part = 0; part < 2; ++part) {
    for (int v = 0; v < scene.parts[part].positions_in_part_m.cols(); ++v) {
      const Vector3d x = scene.parts[part].positions_in_part_m.col(v).cast<double>();
      const auto full = ColourPixel(scene, poses[part], x);
      if (!TrulyVisible(scene, poses, part, v) || !WellInsideSilhouette(scene, poses, *full, part))
        continue;
      const auto pixel = ProjectToKeyframeCrop(x, poses[part], *camera);  // Eq. 3.14-3.15.
      if (!pixel) return 1e9;
      const int px = static_cast<int>(std::lround(pixel->x())),
                py = static_cast<int>(std::lround(pixel->y()));
      if (px < 0 || py < 0 || px >= crop->width || py >= crop->height) return 1e9;
      const Vector3f want = Pattern(part, x);
      for (int c = 0; c < 3; ++c) error += std::abs(crop->at(px, py, c) - want[c]);
      ++*count;
    }
  }
  return *count > 0 ? error / (3.0 * *count) : 1e9;
}

TEST(ProjectToKeyframeCrop, LandsOnThePaintedColour) {
  const Scene scene;
  const auto poses = Frame0Poses();
  int count = 0;
  const double mae = VertexColourError(scene, poses, MakeKeyframe(scene, poses, 0), &count);
  EXPECT_GE(count, 60);
  EXPECT_LT(mae, 4.0) << "levels";
  // The same through a half-resolution colour image and a downscaled crop.
  KeyframeOptions small;
  small.max_crop_side_px = 60;
  const TextureKeyframe scaled = MakeKeyframe(scene, poses, 0, small, 2);
  EXPECT_LT(scaled.crop_scale, 0.5f);
  EXPECT_GT(scaled.crop_scale, 0.2f);
  const double mae_scaled = VertexColourError(scene, poses, scaled, &count);
  EXPECT_LT(mae_scaled, 10.0) << "levels";
  std::printf(
      "vertex colour through Eq. 3.14-3.15: %.2f levels (full), %.2f levels "
      "(half-resolution colour, crop_scale %.3f)\n",
      mae, mae_scaled, scaled.crop_scale);
}

// The parts and a frame for BakePartTextures.
std::vector<PartMesh> PartMeshes(const Scene& scene) { return scene.parts; }

ReenactmentFrame ToFrame(int index, const std::vector<reenact::PartPose>& poses) {
  ReenactmentFrame frame;
  frame.frame_index = index;
  frame.parts = poses;
  return frame;
}

struct BakeError {
  double mae = 1e9;         // All observed texels, levels.
  double mae_hidden = 1e9;  // Texels of part 0 hidden in frame 0, seen in frame 1.
  int texels = 0;
  int hidden_texels = 0;
};

// Compares the baked textures with the painted pattern at texels at least
// 1 px inside their triangle whose point some keyframe truly sees.
BakeError MeasureBake(const Scene& scene, const std::vector<PartMesh>& baked) {
  const std::vector<std::vector<reenact::PartPose>> frames = {Frame0Poses(), Frame1Poses()};
  BakeError out;
  double sum = 0.0, sum_hidden = 0.0;
  for (int p = 0; p < 2; ++p) {
    const auto texture = DecodeJpeg(baked[p].baked_texture_jpeg);
    const PartMesh* geometry = &baked[p];
    EXPECT_TRUE(texture.ok());
    if (!texture.ok()) return out;
    EXPECT_EQ(geometry->uvs.cols(), geometry->positions_in_part_m.cols());
    const float* uv = geometry->uvs.data();
    const int size = texture->width;
    for (const auto& t : geometry->triangles) {
      std::array<Vector2d, 3> c;
      for (int k = 0; k < 3; ++k)
        c[k] = Vector2d(uv[2 * t[k]] * size, (1.0 - uv[2 * t[k] + 1]) * size);
      const Eigen::AlignedBox2d box(c[0].cwiseMin(c[1]).cwiseMin(c[2]),
                                    c[0].cwiseMax(c[1]).cwiseMax(c[2]));
      for (int y = static_cast<int>(box.min().y()); y < box.max().y(); ++y) {
        for (int x = static_cast<int>(box.min().x()); x < box.max().x(); ++x) {
          const Vector2d q(x + 0.5, y + 0.5);
          Eigen::Matrix2d m;
          m << c[1] - c[0], c[2] - c[0];
          const Vector2d b12 = m.inverse() * (q - c[0]);
          const Eigen::Vector3d b(1 - b12.sum(), b12.x(), b12.y());
          // At least ~1 px inside: barycentric margin scaled by the leg length.
          if (b.minCoeff() < 1.0 / (c[1] - c[0]).norm()) continue;
          const Vector3d x3 = b[0] * geometry->positions_in_part_m.col(t[0]).cast<double>() +
                              b[1] * geometry->positions_in_part_m.col(t[1]).cast<double>() +
                              b[2] * geometry->positions_in_part_m.col(t[2]).cast<double>();
          const Vector3d n = geometry->normals_in_part.col(t[0]).cast<double>();
          bool seen[2] = {false, false};
          for (int f = 0; f < 2; ++f) {
            const Vector3d pw = frames[f][p].world_from_part * x3;
            const Vector3d cam = scene.sensor.world_from_color().translation;
            if ((frames[f][p].world_from_part.linear() * n).dot(pw - cam) >=
                -0.1 * (pw - cam).norm())
              continue;
            const auto hit = CastRay(cam, (pw - cam).normalized(), frames[f]);
            const auto full = ColourPixel(scene, frames[f][p], x3);
            seen[f] = hit && hit->part == p && hit->t >= (pw - cam).norm() - 0.005 &&
                      WellInsideSilhouette(scene, frames[f], *full, p);
          }
          if (!seen[0] && !seen[1]) continue;
          const Vector3f want = Pattern(p, x3);
          double e = 0.0;
          for (int ch = 0; ch < 3; ++ch) e += std::abs(texture->at(x, y, ch) - want[ch]) / 3.0;
          sum += e;
          ++out.texels;
          if (p == 0 && !seen[0] && n.z() > 0.5) {
            sum_hidden += e;
            ++out.hidden_texels;
          }
        }
      }
    }
  }
  if (out.texels > 0) out.mae = sum / out.texels;
  if (out.hidden_texels > 0) out.mae_hidden = sum_hidden / out.hidden_texels;
  return out;
}

TEST(BakePartTextures, ReproducesPaintedColoursAndSkipsOccluders) {
  const Scene scene;
  const std::vector<TextureKeyframe> keyframes = {MakeKeyframe(scene, Frame0Poses(), 0),
                                                  MakeKeyframe(scene, Frame1Poses(), 1)};
  const std::vector<ReenactmentFrame> frames = {ToFrame(0, Frame0Poses()),
                                                ToFrame(1, Frame1Poses())};
  std::vector<PartMesh> parts = PartMeshes(scene);
  BakeSummary summary;
  ASSERT_TRUE(BakePartTextures(keyframes, frames, {scene.sensor.calibration}, BakeOptions(), &parts,
                               &summary)
                  .ok());
  EXPECT_EQ(summary.parts_baked, 2);
  EXPECT_EQ(summary.triangles, 2 * 6 * 8 * 8 * 2);
  // Back, top, bottom and some side faces are seen by no keyframe.
  EXPECT_GT(summary.triangles_unobserved, 0);
  EXPECT_LT(summary.triangles_unobserved, summary.triangles);
  for (int p = 0; p < 2; ++p) {
    EXPECT_EQ(parts[p].triangles.size(), static_cast<size_t>(6 * 8 * 8 * 2));
    // Neighbours share a cell and its diagonal's two vertices: on a grid of
    // squares nearly every triangle has one, 2 vertices per triangle instead
    // of 3.
    EXPECT_LE(parts[p].num_vertices(), 6 * 8 * 8 * 2 * 2 + 6 * 8 * 2) << "part " << p;
    std::printf("part %d: %d triangles on %d vertices once baked (%d before)\n", p,
                static_cast<int>(parts[p].triangles.size()), parts[p].num_vertices(),
                PartMeshes(scene)[p].num_vertices());
  }
  const BakeError error = MeasureBake(scene, parts);
  EXPECT_GT(error.texels, 20000);
  EXPECT_GT(error.hidden_texels, 500);
  EXPECT_LT(error.mae, 5.0) << "levels over " << error.texels << " texels";
  EXPECT_LT(error.mae_hidden, 5.0)
      << "levels over the " << error.hidden_texels << " texels hidden in frame 0";
  std::printf(
      "bake: MAE %.2f levels over %d texels, %.2f levels over %d texels hidden in "
      "frame 0; %d of %d triangles unobserved, cells of %d px\n",
      error.mae, error.texels, error.mae_hidden, error.hidden_texels, summary.triangles_unobserved,
      summary.triangles, summary.min_cell_px);
}

TEST(RemapVisibilityBitsToBakedMeshes, FollowsTheVertexSplit) {
  const Scene scene;
  std::vector<TextureKeyframe> keyframes = {MakeKeyframe(scene, Frame0Poses(), 0)};
  const std::vector<TextureKeyframe> before_keyframes = keyframes;
  const std::vector<PartMesh> before = PartMeshes(scene);
  std::vector<PartMesh> parts = before;
  ASSERT_TRUE(BakePartTextures(keyframes, {ToFrame(0, Frame0Poses())}, {scene.sensor.calibration},
                               BakeOptions(), &parts)
                  .ok());
  ASSERT_TRUE(RemapVisibilityBitsToBakedMeshes(before, &keyframes).ok());
  int set_before = 0, set_after = 0;
  for (int p = 0; p < 2; ++p) {
    const std::string& old_bits = before_keyframes[0].vertex_visible_bits[p];
    const std::string& new_bits = keyframes[0].vertex_visible_bits[p];
    ASSERT_EQ(new_bits.size(), static_cast<size_t>((parts[p].num_vertices() + 7) / 8));
    ASSERT_EQ(parts[p].triangles.size(), before[p].triangles.size());
    // Triangles keep their order; each corner's bit is its old vertex's.
    for (size_t t = 0; t < parts[p].triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(VertexVisible(new_bits, parts[p].triangles[t][k]),
                  VertexVisible(old_bits, before[p].triangles[t][k]));
      }
    }
    for (int v = 0; v < parts[p].num_vertices(); ++v) set_after += VertexVisible(new_bits, v);
    for (int v = 0; v < static_cast<int>(old_bits.size()) * 8; ++v) {
      set_before += VertexVisible(old_bits, v);
    }
  }
  EXPECT_GT(set_after, set_before);  // Shared vertices become several corners.
  // Bits that do not fit the meshes: error, keyframes unchanged.
  std::vector<TextureKeyframe> again = keyframes;
  EXPECT_EQ(RemapVisibilityBitsToBakedMeshes(before, &again).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(again[0].vertex_visible_bits, keyframes[0].vertex_visible_bits);
}

// Control: without the occlusion test (a tolerance beyond the scene's
// depth), frame 0 lends the small box's colours to the hidden part of the
// large box, and the measure above catches it.
TEST(BakePartTextures, OcclusionTestMatters) {
  const Scene scene;
  KeyframeOptions no_occlusion;
  no_occlusion.visibility_tolerance_m = 10.0;
  const std::vector<TextureKeyframe> keyframes = {
      MakeKeyframe(scene, Frame0Poses(), 0, no_occlusion),
      MakeKeyframe(scene, Frame1Poses(), 1, no_occlusion)};
  const std::vector<ReenactmentFrame> frames = {ToFrame(0, Frame0Poses()),
                                                ToFrame(1, Frame1Poses())};
  std::vector<PartMesh> parts = PartMeshes(scene);
  ASSERT_TRUE(
      BakePartTextures(keyframes, frames, {scene.sensor.calibration}, BakeOptions(), &parts).ok());
  const BakeError error = MeasureBake(scene, parts);
  EXPECT_GT(error.mae_hidden, 15.0) << "levels";
  std::printf("bake without occlusion test: %.2f levels over the texels hidden in frame 0\n",
              error.mae_hidden);
}

// ---------------------------------------------------------- bad inputs --

TEST(MakeTextureKeyframe, RejectsCorruptInput) {
  const Scene scene;
  auto poses = Frame0Poses();
  const RgbImage colour = RenderColour(scene.sensor, scene.sensor.color, poses);
  const DepthAndMask dm = RenderDepth(scene.sensor, poses);
  auto make = [&](const std::vector<PartMesh>& parts, const std::vector<reenact::PartPose>& p,
                  const RgbImage& c, const MaskImage& m, const DepthImageMm& d) {
    return MakeTextureKeyframe(parts, p, SensorImages{scene.sensor.calibration, c, m, d}, 0, 0,
                               "k0")
        .status()
        .code();
  };
  const auto kInvalid = absl::StatusCode::kInvalidArgument;
  EXPECT_EQ(make(scene.parts, poses, colour, MaskImage(10, 10), dm.depth), kInvalid);
  EXPECT_EQ(make(scene.parts, poses, RgbImage(100, 100), dm.mask, dm.depth), kInvalid);
  EXPECT_EQ(make(scene.parts, {poses[0]}, colour, dm.mask, dm.depth), kInvalid);
  auto nan_poses = poses;
  nan_poses[1].world_from_part.translation().x() = std::nan("");
  EXPECT_EQ(make(scene.parts, nan_poses, colour, dm.mask, dm.depth), kInvalid);
  auto bad_parts = scene.parts;
  bad_parts[0].triangles[3] = Eigen::Vector3i(0, 1, 100000);
  EXPECT_EQ(make(bad_parts, poses, colour, dm.mask, dm.depth), kInvalid);
  RgbImage short_colour = colour;
  short_colour.data.resize(10);
  EXPECT_EQ(make(scene.parts, poses, short_colour, dm.mask, dm.depth), kInvalid);
  EXPECT_EQ(make(scene.parts, poses, colour, MaskImage(dm.mask.width, dm.mask.height), dm.depth),
            absl::StatusCode::kNotFound);
  KeyframeOptions bad_options;
  bad_options.jpeg_quality = 0;
  EXPECT_EQ(MakeTextureKeyframe(scene.parts, poses,
                                SensorImages{scene.sensor.calibration, colour, dm.mask, dm.depth},
                                0, 0, "k0", bad_options)
                .status()
                .code(),
            kInvalid);
}

TEST(BakePartTextures, RejectsCorruptInputAndLeavesPartsUnchanged) {
  const Scene scene;
  const std::vector<TextureKeyframe> good = {MakeKeyframe(scene, Frame0Poses(), 0)};
  const std::vector<ReenactmentFrame> frames = {ToFrame(0, Frame0Poses())};
  const std::vector<SensorCalibration> sensors = {scene.sensor.calibration};
  const std::vector<PartMesh> original = PartMeshes(scene);
  auto bake = [&](const std::vector<TextureKeyframe>& k, const std::vector<ReenactmentFrame>& f,
                  std::vector<PartMesh> parts) {
    const absl::Status status = BakePartTextures(k, f, sensors, BakeOptions(), &parts);
    if (!status.ok()) {
      for (size_t i = 0; i < parts.size(); ++i) EXPECT_TRUE(parts[i].baked_texture_jpeg.empty());
    }
    return status.code();
  };
  const auto kInvalid = absl::StatusCode::kInvalidArgument;
  ASSERT_EQ(bake(good, frames, original), absl::StatusCode::kOk);

  auto short_bits = good;
  short_bits[0].vertex_visible_bits[1] = "x";
  EXPECT_EQ(bake(short_bits, frames, original), kInvalid);
  auto bad_jpeg = good;
  bad_jpeg[0].color_jpeg = "not a jpeg";
  EXPECT_EQ(bake(bad_jpeg, frames, original), kInvalid);
  auto bad_mask = good;
  bad_mask[0].mask_rle = EncodeMaskRle(MaskImage(3, 3));
  EXPECT_EQ(bake(bad_mask, frames, original), kInvalid);
  auto unknown_frame = good;
  unknown_frame[0].frame_index = 7;
  EXPECT_EQ(bake(unknown_frame, frames, original), kInvalid);
  auto unknown_sensor = good;
  unknown_sensor[0].sensor_id = "k9";
  EXPECT_EQ(bake(unknown_sensor, frames, original), kInvalid);
  auto nan_frames = frames;
  nan_frames[0].parts[0].world_from_part.translation().x() = std::nan("");
  EXPECT_EQ(bake(good, nan_frames, original), kInvalid);
  auto nan_scale = frames;
  nan_scale[0].parts[1].scale = std::nan("");
  EXPECT_EQ(bake(good, nan_scale, original), kInvalid);
  auto odd_normals = original;
  odd_normals[0].normals_in_part.conservativeResize(3, odd_normals[0].num_vertices() - 1);
  EXPECT_EQ(bake(good, frames, odd_normals), kInvalid);
  auto bad_index = original;
  bad_index[1].triangles[0][0] = 99999;
  EXPECT_EQ(bake(good, frames, bad_index), kInvalid);
  auto nan_crop_scale = good;
  nan_crop_scale[0].crop_scale = std::nanf("");
  EXPECT_EQ(bake(nan_crop_scale, frames, original), kInvalid);
}

TEST(BakePartTextures, GrowsATextureTooSmallForThePartsTriangles) {
  const Scene scene;
  BakeOptions tiny;
  tiny.texture_size_px = 16;  // 768 triangles: a 20 x 20 grid of 4 px cells, 80 px.
  std::vector<PartMesh> parts = PartMeshes(scene);
  ASSERT_TRUE(BakePartTextures({MakeKeyframe(scene, Frame0Poses(), 0)}, {ToFrame(0, Frame0Poses())},
                               {scene.sensor.calibration}, tiny, &parts)
                  .ok());
  auto baked = DecodeJpeg(parts[0].baked_texture_jpeg);
  ASSERT_TRUE(baked.ok()) << baked.status();
  EXPECT_EQ(baked->width, 128);  // 16 doubled until it holds 80 px.
  EXPECT_EQ(baked->height, 128);
}

}  // namespace
}  // namespace reenact::recon
