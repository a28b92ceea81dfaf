#include "server/recon/texturing.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <unordered_map>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"

namespace reenact::recon {
namespace {

// Points closer to the colour camera than this are not projected, metres.
constexpr double kNearM = 0.01;
constexpr float kInfiniteDepth = std::numeric_limits<float>::infinity();

absl::Status Invalid(const std::string& what) { return absl::InvalidArgumentError(what); }

// ---------------------------------------------------------------- inputs --

struct SensorCameras {
  CameraIntrinsics depth;
  CameraIntrinsics color;  // Full resolution.
  Rigid3d world_from_depth;
  Rigid3d color_from_depth;
  double depth_m_per_unit = 0.001;
};

absl::StatusOr<SensorCameras> CamerasOf(const SensorCalibration& calibration) {
  const std::string where = absl::StrCat("sensor '", calibration.sensor_id, "': ");
  SensorCameras cameras;
  if (const absl::Status depth = calibration.depth_intrinsics.Validate(); !depth.ok()) {
    return Invalid(where + "depth intrinsics: " + std::string(depth.message()));
  }
  if (const absl::Status color = calibration.color_intrinsics.Validate(); !color.ok()) {
    return Invalid(where + "colour intrinsics: " + std::string(color.message()));
  }
  cameras.depth = calibration.depth_intrinsics;
  cameras.color = calibration.color_intrinsics;
  cameras.world_from_depth = calibration.world_from_depth;
  cameras.color_from_depth = calibration.color_from_depth;
  const double scale = calibration.depth_scale_m_per_unit;
  if (!std::isfinite(scale) || scale < 0.0) return Invalid(where + "bad depth_scale_m_per_unit");
  if (scale > 0.0) cameras.depth_m_per_unit = scale;
  return cameras;
}

Rigid3d ColorFromWorld(const SensorCameras& cameras) {
  return cameras.color_from_depth * cameras.world_from_depth.Inverse();
}

absl::Status ValidateGeometry(const PartMesh& part, int id) {
  const auto n = part.positions_in_part_m.cols();
  if (part.normals_in_part.cols() != n) {
    return Invalid(absl::StrCat("part ", id, ": ", n, " positions but ",
                                part.normals_in_part.cols(), " normals"));
  }
  if (!part.positions_in_part_m.allFinite() || !part.normals_in_part.allFinite()) {
    return Invalid(absl::StrCat("part ", id, ": non-finite position or normal"));
  }
  for (const Eigen::Vector3i& t : part.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= n) {
      return Invalid(absl::StrCat("part ", id, ": triangle index out of range (", n, " vertices)"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidatePose(const reenact::PartPose& pose, int id) {
  if (!pose.valid) return absl::OkStatus();
  const Eigen::Matrix4d m = pose.world_from_part.matrix();
  if (!m.allFinite() || !std::isfinite(pose.scale) || pose.scale <= 0.0) {
    return Invalid(absl::StrCat("part ", id, ": non-finite pose or non-positive scale"));
  }
  const Eigen::Matrix3d r = pose.world_from_part.linear();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6) {
    return Invalid(absl::StrCat("part ", id, ": world_from_part rotation is not orthonormal"));
  }
  return absl::OkStatus();
}

template <typename ImageT>
absl::Status ValidateImage(const ImageT& image, const std::string& name) {
  if (image.width <= 0 || image.height <= 0 ||
      image.data.size() != image.num_pixels() * ImageT::channels()) {
    return Invalid(absl::StrCat(name, ": empty image or data size does not match ", image.width,
                                "x", image.height));
  }
  return absl::OkStatus();
}

// Applies a pose and a rigid camera transform to a part point: the camera
// frame point (Eq. 3.14 with T_{b,n} = pose).
Eigen::Vector3d PartToCamera(const Eigen::Vector3d& point_in_part, const reenact::PartPose& pose,
                             const Rigid3d& camera_from_world) {
  const Eigen::Vector3d in_world = pose.scale * (pose.world_from_part.linear() * point_in_part) +
                                   pose.world_from_part.translation();
  return camera_from_world * in_world;
}

// ---------------------------------------------------------------- crops --

// Where a crop sits in the full-resolution colour image and its scale.
struct Crop {
  int x_px = 0;  // Full-resolution pixel of the crop's top-left corner pixel.
  int y_px = 0;
  int width = 0;  // Crop image size, pixels.
  int height = 0;
  double scale = 1.0;  // Crop pixels per full-resolution pixel.

  Eigen::Vector2d FromFull(const Eigen::Vector2d& full) const {
    return (full - Eigen::Vector2d(x_px, y_px) + Eigen::Vector2d::Constant(0.5)) * scale -
           Eigen::Vector2d::Constant(0.5);
  }
};

// The actor's depth pixels projected into the full-resolution colour image.
struct ActorProjection {
  std::vector<Eigen::Vector2d> pixels;  // Full-resolution colour pixels.
  double depth_to_color_px = 1.0;       // Colour pixels per depth pixel (approx.).
};

ActorProjection ProjectActor(const SensorImages& images, const SensorCameras& cameras) {
  ActorProjection out;
  out.depth_to_color_px = cameras.color.fx / cameras.depth.fx;
  for (int y = 0; y < images.depth.height; ++y) {
    for (int x = 0; x < images.depth.width; ++x) {
      const uint16_t d = images.depth.at(x, y);
      if (d == 0 || images.mask.at(x, y) == 0) continue;
      const auto in_depth =
          cameras.depth.Unproject(Eigen::Vector2d(x, y), d * cameras.depth_m_per_unit);
      if (!in_depth) continue;
      const auto pixel = cameras.color.Project(cameras.color_from_depth * *in_depth);
      if (pixel && cameras.color.IsInside(*pixel)) out.pixels.push_back(*pixel);
    }
  }
  return out;
}

// The crop: bounding box of the actor plus margin, clipped to the image,
// its origin aligned to the colour image's pixel grid when that image is
// scaled by 1/k, and downscaled to max_crop_side_px.
Crop ChooseCrop(const ActorProjection& actor, const CameraIntrinsics& color, double image_scale,
                const KeyframeOptions& options) {
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const Eigen::Vector2d& p : actor.pixels) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = options.margin_px;
  int x0 = static_cast<int>(std::max(0.0, std::floor(lo.x() - margin)));
  int y0 = static_cast<int>(std::max(0.0, std::floor(lo.y() - margin)));
  const int x1 = static_cast<int>(std::min(color.width - 1.0, std::ceil(hi.x() + margin)));
  const int y1 = static_cast<int>(std::min(color.height - 1.0, std::ceil(hi.y() + margin)));
  const double step = 1.0 / image_scale;
  if (image_scale < 1.0 && std::abs(step - std::round(step)) < 1e-6) {
    const int k = static_cast<int>(std::round(step));
    x0 -= x0 % k;
    y0 -= y0 % k;
  }
  Crop crop;
  crop.x_px = x0;
  crop.y_px = y0;
  double scale = image_scale;
  const double side = std::max(x1 - x0 + 1, y1 - y0 + 1) * image_scale;
  if (options.max_crop_side_px > 0 && side > options.max_crop_side_px) {
    scale = image_scale * options.max_crop_side_px / side;
  }
  // TextureKeyframe.crop_scale is a float: use its value everywhere so that
  // the crop, the mask and the bits agree with ProjectToKeyframeCrop.
  crop.scale = static_cast<float>(scale);
  crop.width = std::max(1, static_cast<int>(std::lround((x1 - x0 + 1) * crop.scale)));
  crop.height = std::max(1, static_cast<int>(std::lround((y1 - y0 + 1) * crop.scale)));
  return crop;
}

// Bilinear sample of `image` at continuous pixel `p` (centres at integers),
// clamped to the image.
Eigen::Vector3f SampleBilinear(const RgbImage& image, double px, double py) {
  px = std::clamp(px, 0.0, image.width - 1.0);
  py = std::clamp(py, 0.0, image.height - 1.0);
  const int x0 = static_cast<int>(px);
  const int y0 = static_cast<int>(py);
  const int x1 = std::min(x0 + 1, image.width - 1);
  const int y1 = std::min(y0 + 1, image.height - 1);
  const float fx = static_cast<float>(px - x0);
  const float fy = static_cast<float>(py - y0);
  Eigen::Vector3f out;
  for (int c = 0; c < 3; ++c) {
    const float top = (1 - fx) * image.at(x0, y0, c) + fx * image.at(x1, y0, c);
    const float bottom = (1 - fx) * image.at(x0, y1, c) + fx * image.at(x1, y1, c);
    out[c] = (1 - fy) * top + fy * bottom;
  }
  return out;
}

// The crop image, resampled from the (possibly scaled) colour image: a copy
// when the crop is not downscaled, else a box average of n x n bilinear taps.
RgbImage CutCrop(const RgbImage& colour, double image_scale, const Crop& crop) {
  RgbImage out(crop.width, crop.height);
  const double ratio = image_scale / crop.scale;  // Image pixels per crop pixel, >= 1.
  const int taps = std::max(1, static_cast<int>(std::ceil(ratio - 1e-6)));
  const double x0 = crop.x_px * image_scale;
  const double y0 = crop.y_px * image_scale;
  const int ix = static_cast<int>(std::lround(x0)), iy = static_cast<int>(std::lround(y0));
  if (taps == 1 && std::abs(ratio - 1.0) < 1e-6 && std::abs(x0 - ix) < 1e-6 &&
      std::abs(y0 - iy) < 1e-6 && ix + crop.width <= colour.width &&
      iy + crop.height <= colour.height) {  // Pixel-aligned: copy rows.
    for (int y = 0; y < crop.height; ++y) {
      std::memcpy(&out.at(0, y), &colour.at(ix, iy + y), static_cast<size_t>(crop.width) * 3);
    }
    return out;
  }
  for (int y = 0; y < crop.height; ++y) {
    for (int x = 0; x < crop.width; ++x) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int j = 0; j < taps; ++j) {
        for (int i = 0; i < taps; ++i) {
          const double px = x0 + (x + (i + 0.5) / taps) * ratio - 0.5;
          const double py = y0 + (y + (j + 0.5) / taps) * ratio - 0.5;
          sum += SampleBilinear(colour, px, py);
        }
      }
      sum /= static_cast<float>(taps * taps);
      for (int c = 0; c < 3; ++c) {
        out.at(x, y, c) = static_cast<uint8_t>(std::clamp(std::lround(sum[c]), 0L, 255L));
      }
    }
  }
  return out;
}

// The actor mask in crop pixels: every projected actor depth pixel splatted
// as a square of its footprint, then a morphological closing fills the
// holes that missing depth leaves.
MaskImage SplatMask(const ActorProjection& actor, const Crop& crop) {
  MaskImage mask(crop.width, crop.height);
  const double footprint = actor.depth_to_color_px * crop.scale;  // Crop px per depth px.
  const double half = 0.5 * footprint;
  for (const Eigen::Vector2d& full : actor.pixels) {
    const Eigen::Vector2d c = crop.FromFull(full);
    const int xa = std::max(0, static_cast<int>(std::ceil(c.x() - half)));
    const int xb = std::min(crop.width - 1, static_cast<int>(std::floor(c.x() + half)));
    const int ya = std::max(0, static_cast<int>(std::ceil(c.y() - half)));
    const int yb = std::min(crop.height - 1, static_cast<int>(std::floor(c.y() + half)));
    for (int y = ya; y <= yb; ++y) {
      for (int x = xa; x <= xb; ++x) mask.at(x, y) = 1;
    }
    const int xn = static_cast<int>(std::lround(c.x()));
    const int yn = static_cast<int>(std::lround(c.y()));
    if (xn >= 0 && yn >= 0 && xn < crop.width && yn < crop.height) mask.at(xn, yn) = 1;
  }
  const int radius = std::max(1, static_cast<int>(std::ceil(footprint)));
  cv::Mat mat(mask.height, mask.width, CV_8UC1, mask.data.data());
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
  cv::morphologyEx(mat, mat, cv::MORPH_CLOSE, kernel);
  return mask;
}

// ------------------------------------------------------------- z-buffer --

// Depth (metres along the colour camera's z) of the nearest surface per crop
// pixel; +inf where nothing was drawn.
struct ZBuffer {
  int width = 0;
  int height = 0;
  std::vector<float> z_m;

  ZBuffer(int w, int h) : width(w), height(h), z_m(static_cast<size_t>(w) * h, kInfiniteDepth) {}
  float& at(int x, int y) { return z_m[static_cast<size_t>(y) * width + x]; }
};

// One part's vertices as the keyframe's colour camera sees them.
struct ProjectedPart {
  std::vector<Eigen::Vector3d> in_camera;  // Colour camera frame, metres.
  std::vector<Eigen::Vector2d> in_crop;    // Crop pixels; NaN when behind the camera.
};

ProjectedPart ProjectPart(const PartMesh& part, const reenact::PartPose& pose,
                          const Rigid3d& color_from_world, const CameraIntrinsics& color,
                          const Crop& crop) {
  ProjectedPart out;
  const auto n = part.positions_in_part_m.cols();
  out.in_camera.resize(n);
  out.in_crop.assign(n, Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  // PartToCamera folded into one affine map.
  const Eigen::Matrix3d color_from_world_rotation = color_from_world.rotation.toRotationMatrix();
  const Eigen::Matrix3d linear =
      color_from_world_rotation * (pose.scale * pose.world_from_part.linear());
  const Eigen::Vector3d offset = color_from_world * pose.world_from_part.translation();
  for (Eigen::Index i = 0; i < n; ++i) {
    out.in_camera[i] = linear * part.positions_in_part_m.col(i).cast<double>() + offset;
    if (out.in_camera[i].z() < kNearM) continue;
    if (const auto pixel = color.Project(out.in_camera[i])) out.in_crop[i] = crop.FromFull(*pixel);
  }
  return out;
}

// Draws one triangle with depth interpolated perspective-correctly (1/z is
// affine in screen space); either winding.
void RasterizeTriangle(const Eigen::Vector2d (&p)[3], const double (&z)[3], ZBuffer* zbuffer) {
  const double area = (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
  if (!(std::abs(area) > 1e-12)) return;
  const double min_x = std::min({p[0].x(), p[1].x(), p[2].x()});
  const double max_x = std::max({p[0].x(), p[1].x(), p[2].x()});
  const double min_y = std::min({p[0].y(), p[1].y(), p[2].y()});
  const double max_y = std::max({p[0].y(), p[1].y(), p[2].y()});
  // Clamp in double first: vertices near the camera plane project far out.
  const int xa = static_cast<int>(std::max(0.0, std::ceil(min_x)));
  const int xb = static_cast<int>(std::min(zbuffer->width - 1.0, std::floor(max_x)));
  const int ya = static_cast<int>(std::max(0.0, std::ceil(min_y)));
  const int yb = static_cast<int>(std::min(zbuffer->height - 1.0, std::floor(max_y)));
  if (xa > xb || ya > yb) return;
  // Barycentric k is affine in the pixel: b_k = gx[k] x + gy[k] y + g0[k],
  // ((c - a) x (pixel - a)) / area for the edge a -> c opposite vertex k.
  const double inv_area = 1.0 / area;
  double gx[3], gy[3], g0[3];
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d& a = p[(k + 1) % 3];
    const Eigen::Vector2d edge = p[(k + 2) % 3] - a;
    gx[k] = -edge.y() * inv_area;
    gy[k] = edge.x() * inv_area;
    g0[k] = (edge.y() * a.x() - edge.x() * a.y()) * inv_area;
  }
  const double inv_z[3] = {1.0 / z[0], 1.0 / z[1], 1.0 / z[2]};
  for (int y = ya; y <= yb; ++y) {
    float* row = &zbuffer->at(0, y);
    for (int x = xa; x <= xb; ++x) {
      const double b0 = gx[0] * x + gy[0] * y + g0[0];
      const double b1 = gx[1] * x + gy[1] * y + g0[1];
      const double b2 = gx[2] * x + gy[2] * y + g0[2];
      if (b0 < -1e-9 || b1 < -1e-9 || b2 < -1e-9) continue;
      // 1/z is affine in screen space (perspective-correct depth).
      const float depth = static_cast<float>(1.0 / (b0 * inv_z[0] + b1 * inv_z[1] + b2 * inv_z[2]));
      row[x] = std::min(row[x], depth);
    }
  }
}

void RasterizePart(const PartMesh& part, const ProjectedPart& projected, ZBuffer* zbuffer) {
  for (const Eigen::Vector3i& t : part.triangles) {
    Eigen::Vector2d p[3];
    double z[3];
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      p[k] = projected.in_crop[t[k]];
      z[k] = projected.in_camera[t[k]].z();
      ok = ok && p[k].allFinite() && z[k] >= kNearM;
    }
    if (ok) RasterizeTriangle(p, z, zbuffer);
  }
}

// The pixel whose centre is nearest to `p`; false when that is outside a
// width x height image (or `p` is not finite).
bool NearestPixel(const Eigen::Vector2d& p, int width, int height, int* x, int* y) {
  if (!(p.x() >= -0.5 && p.x() < width - 0.5 && p.y() >= -0.5 && p.y() < height - 0.5)) {
    return false;
  }
  *x = std::clamp(static_cast<int>(std::floor(p.x() + 0.5)), 0, width - 1);
  *y = std::clamp(static_cast<int>(std::floor(p.y() + 0.5)), 0, height - 1);
  return true;
}

void SetBit(std::string* bits, int index) {
  (*bits)[index / 8] =
      static_cast<char>(static_cast<uint8_t>((*bits)[index / 8]) | (1u << (index % 8)));
}

// Fig. 3.7: a vertex is visible when it faces the camera, lands on the
// crop's actor mask, and is no more than `tolerance_m` behind the depth
// buffer of all parts.
std::string VisibilityBits(const PartMesh& part, const reenact::PartPose& pose,
                           const Rigid3d& color_from_world, const ProjectedPart& projected,
                           const ZBuffer& zbuffer, const MaskImage& mask, double tolerance_m) {
  const int n = static_cast<int>(part.positions_in_part_m.cols());
  std::string bits((n + 7) / 8, '\0');
  if (!pose.valid) return bits;
  const Eigen::Matrix3d color_from_part =
      color_from_world.rotation.toRotationMatrix() * pose.world_from_part.linear();
  for (int i = 0; i < n; ++i) {
    int x = 0, y = 0;
    if (!NearestPixel(projected.in_crop[i], zbuffer.width, zbuffer.height, &x, &y)) continue;
    if (mask.at(x, y) == 0) continue;
    const Eigen::Vector3d normal = color_from_part * part.normals_in_part.col(i).cast<double>();
    if (normal.squaredNorm() > 1e-12 && normal.dot(projected.in_camera[i]) >= 0.0) continue;
    const double z = projected.in_camera[i].z();
    const float zbuf = zbuffer.z_m[static_cast<size_t>(y) * zbuffer.width + x];
    if (z <= zbuf + tolerance_m) SetBit(&bits, i);
  }
  return bits;
}

absl::Status ValidateKeyframeInputs(const std::vector<PartMesh>& parts,
                                    const std::vector<reenact::PartPose>& poses,
                                    const SensorImages& images, const SensorCameras& cameras) {
  if (parts.size() != poses.size()) {
    return Invalid(absl::StrCat(parts.size(), " parts but ", poses.size(), " poses"));
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    RETURN_IF_ERROR(ValidateGeometry(parts[i], static_cast<int>(i)));
    RETURN_IF_ERROR(ValidatePose(poses[i], static_cast<int>(i)));
  }
  RETURN_IF_ERROR(ValidateImage(images.colour, "colour"));
  RETURN_IF_ERROR(ValidateImage(images.mask, "mask"));
  RETURN_IF_ERROR(ValidateImage(images.depth, "depth"));
  if (images.depth.width != cameras.depth.width || images.depth.height != cameras.depth.height) {
    return Invalid(absl::StrCat("depth is ", images.depth.width, "x", images.depth.height,
                                " but the depth intrinsics are ", cameras.depth.width, "x",
                                cameras.depth.height));
  }
  if (images.mask.width != images.depth.width || images.mask.height != images.depth.height) {
    return Invalid(absl::StrCat("mask is ", images.mask.width, "x", images.mask.height,
                                " but depth is ", images.depth.width, "x", images.depth.height));
  }
  const double scale = static_cast<double>(images.colour.width) / cameras.color.width;
  if (scale > 1.0 || std::abs(cameras.color.height * scale - images.colour.height) > 1.0) {
    return Invalid(absl::StrCat("colour is ", images.colour.width, "x", images.colour.height,
                                ", not the colour intrinsics' ", cameras.color.width, "x",
                                cameras.color.height, " or a uniform downscale of them"));
  }
  return absl::OkStatus();
}

}  // namespace

// ------------------------------------------------------------ public API --

absl::Status KeyframeOptions::Validate() const {
  if (margin_px < 0) return Invalid("KeyframeOptions.margin_px must be >= 0");
  if (jpeg_quality < 1 || jpeg_quality > 100) {
    return Invalid("KeyframeOptions.jpeg_quality must be in 1..100");
  }
  if (max_crop_side_px < 0) return Invalid("KeyframeOptions.max_crop_side_px must be >= 0");
  if (!std::isfinite(visibility_tolerance_m) || visibility_tolerance_m < 0.0) {
    return Invalid("KeyframeOptions.visibility_tolerance_m must be finite and >= 0");
  }
  return absl::OkStatus();
}

absl::StatusOr<TextureKeyframe> MakeTextureKeyframe(const std::vector<PartMesh>& parts,
                                                    const std::vector<reenact::PartPose>& poses,
                                                    const SensorImages& images, int frame_index,
                                                    int64_t stamp_ns, const std::string& sensor_id,
                                                    const KeyframeOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(const SensorCameras cameras, CamerasOf(images.calibration));
  RETURN_IF_ERROR(ValidateKeyframeInputs(parts, poses, images, cameras));
  const double image_scale = static_cast<double>(images.colour.width) / cameras.color.width;

  const ActorProjection actor = ProjectActor(images, cameras);
  if (actor.pixels.empty()) {
    return absl::NotFoundError(absl::StrCat("frame ", frame_index, " sensor '", sensor_id,
                                            "': no actor pixel projects into the colour image"));
  }
  const Crop crop = ChooseCrop(actor, cameras.color, image_scale, options);
  TextureKeyframe keyframe;
  keyframe.frame_index = frame_index;
  keyframe.sensor_id = sensor_id;
  keyframe.stamp_ns = stamp_ns;
  keyframe.crop_x_px = crop.x_px;
  keyframe.crop_y_px = crop.y_px;
  keyframe.crop_scale = static_cast<float>(crop.scale);
  ASSIGN_OR_RETURN(keyframe.color_jpeg,
                   EncodeJpeg(CutCrop(images.colour, image_scale, crop), options.jpeg_quality));
  const MaskImage mask = SplatMask(actor, crop);
  keyframe.mask_rle = EncodeMaskRle(mask);

  // Fig. 3.7: depth of all posed parts, then per-vertex visibility.
  const Rigid3d color_from_world = ColorFromWorld(cameras);
  std::vector<ProjectedPart> projected(parts.size());
  ZBuffer zbuffer(crop.width, crop.height);
  for (size_t i = 0; i < parts.size(); ++i) {
    if (!poses[i].valid) continue;
    projected[i] = ProjectPart(parts[i], poses[i], color_from_world, cameras.color, crop);
    RasterizePart(parts[i], projected[i], &zbuffer);
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    keyframe.vertex_visible_bits.push_back(VisibilityBits(parts[i], poses[i], color_from_world,
                                                          projected[i], zbuffer, mask,
                                                          options.visibility_tolerance_m));
  }
  return keyframe;
}

absl::StatusOr<KeyframeCamera> KeyframeCameraOf(const SensorCalibration& calibration,
                                                const TextureKeyframe& keyframe) {
  ASSIGN_OR_RETURN(const SensorCameras cameras, CamerasOf(calibration));
  const double scale = keyframe.crop_scale;
  if (!std::isfinite(scale) || scale < 0.0) {
    return Invalid(absl::StrCat("keyframe ", keyframe.frame_index, ": bad crop_scale ", scale));
  }
  KeyframeCamera camera;
  camera.color_intrinsics = cameras.color;
  camera.color_from_world = ColorFromWorld(cameras);
  camera.crop_x_px = keyframe.crop_x_px;
  camera.crop_y_px = keyframe.crop_y_px;
  camera.crop_scale = scale == 0.0 ? 1.0 : scale;
  return camera;
}

std::optional<Eigen::Vector2d> ProjectToKeyframeCrop(const Eigen::Vector3d& point_in_part_m,
                                                     const reenact::PartPose& pose,
                                                     const KeyframeCamera& camera) {
  // Eq. 3.14: x_n = T_{b,n} x (the part's pose at the keyframe's instant).
  const Eigen::Vector3d in_color = PartToCamera(point_in_part_m, pose, camera.color_from_world);
  // Eq. 3.15: rho, the colour camera's projection, then the crop offset.
  const auto full = camera.color_intrinsics.Project(in_color);
  if (!full) return std::nullopt;
  return ((*full - Eigen::Vector2d(camera.crop_x_px, camera.crop_y_px)).array() + 0.5) *
             camera.crop_scale -
         0.5;
}

bool VertexVisible(const std::string& bits, int vertex) {
  if (vertex < 0 || static_cast<size_t>(vertex / 8) >= bits.size()) return false;
  return (static_cast<uint8_t>(bits[vertex / 8]) >> (vertex % 8)) & 1u;
}

// ---------------------------------------------------------------- baking --

namespace {

// A keyframe's camera and poses; its crop and mask are decoded one keyframe
// at a time (takes keep hundreds of keyframes).
struct BakeKeyframe {
  const TextureKeyframe* message = nullptr;
  KeyframeCamera camera;
  std::vector<reenact::PartPose> poses;  // Of the keyframe's instant, part-id order.
  // Per part: the rotation of colour_from_world * world_from_part and the
  // part origin in the colour camera (PartToCamera = scale * rotation * x +
  // origin), precomputed for the per-triangle loops.
  std::vector<Eigen::Matrix3d> color_from_part_rotation;
  std::vector<Eigen::Vector3d> part_origin_in_color;
};

std::string KeyframeName(const TextureKeyframe& m) {
  return absl::StrCat("keyframe (frame ", m.frame_index, ", sensor '", m.sensor_id, "')");
}

absl::StatusOr<BakeKeyframe> PrepareKeyframe(
    const TextureKeyframe& message, const std::map<int, const ReenactmentFrame*>& frames,
    const std::map<std::string, const SensorCalibration*>& sensors) {
  const auto frame = frames.find(message.frame_index);
  if (frame == frames.end()) {
    return Invalid(KeyframeName(message) + ": no frame with that frame_index");
  }
  const auto sensor = sensors.find(message.sensor_id);
  if (sensor == sensors.end()) return Invalid(KeyframeName(message) + ": no such sensor");
  BakeKeyframe keyframe;
  keyframe.message = &message;
  ASSIGN_OR_RETURN(keyframe.camera, KeyframeCameraOf(*sensor->second, message));
  keyframe.poses = frame->second->parts;
  for (size_t i = 0; i < keyframe.poses.size(); ++i) {
    RETURN_IF_ERROR(ValidatePose(keyframe.poses[i], static_cast<int>(i)));
  }
  const Eigen::Matrix3d color_from_world =
      keyframe.camera.color_from_world.rotation.toRotationMatrix();
  for (const reenact::PartPose& pose : keyframe.poses) {
    keyframe.color_from_part_rotation.push_back(color_from_world * pose.world_from_part.linear());
    keyframe.part_origin_in_color.push_back(keyframe.camera.color_from_world *
                                            pose.world_from_part.translation());
  }
  return keyframe;
}

absl::Status DecodeKeyframe(const TextureKeyframe& message, RgbImage* crop, MaskImage* mask) {
  auto jpeg = DecodeJpeg(message.color_jpeg);
  if (!jpeg.ok()) {
    return Invalid(KeyframeName(message) +
                   ": colour crop: " + std::string(jpeg.status().message()));
  }
  auto rle = DecodeMaskRle(message.mask_rle);
  if (!rle.ok()) {
    return Invalid(KeyframeName(message) + ": mask: " + std::string(rle.status().message()));
  }
  if (rle->width != jpeg->width || rle->height != jpeg->height) {
    return Invalid(absl::StrCat(KeyframeName(message), ": mask is ", rle->width, "x", rle->height,
                                " but the crop is ", jpeg->width, "x", jpeg->height));
  }
  *crop = *std::move(jpeg);
  *mask = *std::move(rle);
  return absl::OkStatus();
}

absl::Status CheckKeyframeCoversPart(const BakeKeyframe& keyframe, int part, int vertices) {
  const TextureKeyframe& m = *keyframe.message;
  const std::string where = absl::StrCat(KeyframeName(m), " part ", part);
  if (static_cast<int>(keyframe.poses.size()) <= part)
    return Invalid(where + ": frame has no pose");
  if (static_cast<int>(m.vertex_visible_bits.size()) <= part) {
    return Invalid(where + ": no vertex_visible_bits");
  }
  const size_t expected = (static_cast<size_t>(vertices) + 7) / 8;
  if (m.vertex_visible_bits[part].size() != expected) {
    return Invalid(absl::StrCat(where, ": ", m.vertex_visible_bits[part].size(),
                                " bytes of visibility bits for ", vertices, " vertices"));
  }
  return absl::OkStatus();
}

// Which triangles share an atlas cell. Two neighbours across an edge (one
// that both traverse, in opposite directions) share one, that edge on the
// cell's diagonal and its two vertices shared by both; the rest take a half
// cell each, two to a cell. Greedy over the triangles in order, so a
// function of the mesh alone.
struct CellLayout {
  // Per triangle: 2 k + h for half h of cell k (0 upper-left, 1
  // lower-right).
  std::vector<int> slot;
  // Per triangle: its corner off the shared diagonal; -1 for a triangle on
  // its own.
  std::vector<int> apex;
  int cells = 0;
};

CellLayout PairTriangles(const PartMesh& part) {
  const int n = static_cast<int>(part.triangles.size());
  const auto edge_key = [](int from, int to) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(from)) << 32) | static_cast<uint32_t>(to);
  };
  // A directed edge traversed twice (a non-manifold or flipped mesh) keeps
  // its first triangle.
  std::unordered_map<uint64_t, int> triangle_of_edge;
  triangle_of_edge.reserve(static_cast<size_t>(n) * 3);
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) {
      triangle_of_edge.emplace(edge_key(part.triangles[t][k], part.triangles[t][(k + 1) % 3]), t);
    }
  }
  CellLayout layout;
  layout.slot.assign(n, -1);
  layout.apex.assign(n, -1);
  for (int t = 0; t < n; ++t) {
    if (layout.slot[t] >= 0) continue;
    const Eigen::Vector3i& a = part.triangles[t];
    for (int k = 0; k < 3 && layout.slot[t] < 0; ++k) {
      const auto it = triangle_of_edge.find(edge_key(a[(k + 1) % 3], a[k]));
      if (it == triangle_of_edge.end() || it->second == t || layout.slot[it->second] >= 0) {
        continue;
      }
      const int u = it->second;
      const Eigen::Vector3i& b = part.triangles[u];
      int apex_u = -1;
      for (int m = 0; m < 3; ++m) {
        if (b[m] != a[k] && b[m] != a[(k + 1) % 3]) apex_u = m;
      }
      if (apex_u < 0) continue;  // Degenerate: all three corners on the edge.
      layout.slot[t] = 2 * layout.cells;
      layout.slot[u] = 2 * layout.cells + 1;
      layout.apex[t] = (k + 2) % 3;
      layout.apex[u] = apex_u;
      ++layout.cells;
    }
  }
  int half = 0;
  for (int t = 0; t < n; ++t) {
    if (layout.slot[t] >= 0) continue;
    layout.slot[t] = 2 * layout.cells + half;
    if (half == 1) ++layout.cells;
    half = 1 - half;
  }
  if (half == 1) ++layout.cells;
  return layout;
}

// Atlas layout: one square cell of `cell_px` per CellLayout cell on a
// `grid` x `grid` lattice; slot 2k takes the upper-left half of cell k (in
// image rows, y down), 2k + 1 the lower-right half. Corners sit `inset_px`
// inside the cell's edges. A pair of neighbours meets on the diagonal; a
// triangle on its own keeps `2 inset_px` from the diagonal side, so that the
// two long sides of a cell of two are sqrt(2) inset_px apart. Every texel
// of a cell belongs to the triangle on its side of the diagonal (gutters
// included), so bilinear lookups near an edge stay on the triangle's
// colours, or on its neighbour's across a shared diagonal.
struct Atlas {
  int size_px = 0;
  int grid = 0;
  int cell_px = 0;
  double inset_px = 1.5;
  CellLayout layout;

  Eigen::Vector2i CellOrigin(int t) const {
    const int cell = layout.slot[t] / 2;
    return Eigen::Vector2i((cell % grid) * cell_px, (cell / grid) * cell_px);
  }
  bool UpperHalf(int t) const { return layout.slot[t] % 2 == 0; }

  // Corners of triangle `t` in texture pixels (x right, y down, 0 = the
  // image's top-left edge), corner k of the triangle first.
  std::array<Eigen::Vector2d, 3> Corners(int t) const {
    const Eigen::Vector2d o = CellOrigin(t).cast<double>();
    const double c = cell_px, p = inset_px, q = 2 * inset_px;
    const int apex = layout.apex[t];
    if (apex < 0) {
      if (UpperHalf(t)) {
        return {o + Eigen::Vector2d(p, p), o + Eigen::Vector2d(c - q, p),
                o + Eigen::Vector2d(p, c - q)};
      }
      return {o + Eigen::Vector2d(c - p, c - p), o + Eigen::Vector2d(q, c - p),
              o + Eigen::Vector2d(c - p, q)};
    }
    // The apex in the cell's corner, the shared edge on the diagonal: the
    // upper triangle's edge runs top-right to bottom-left, the lower one's
    // back, so both name the same two points.
    std::array<Eigen::Vector2d, 3> corners;
    const Eigen::Vector2d top_right = o + Eigen::Vector2d(c - p, p);
    const Eigen::Vector2d bottom_left = o + Eigen::Vector2d(p, c - p);
    const bool upper = UpperHalf(t);
    corners[apex] = o + (upper ? Eigen::Vector2d(p, p) : Eigen::Vector2d(c - p, c - p));
    corners[(apex + 1) % 3] = upper ? top_right : bottom_left;
    corners[(apex + 2) % 3] = upper ? bottom_left : top_right;
    return corners;
  }
};

absl::StatusOr<Atlas> LayOutAtlas(const PartMesh& part, int size_px) {
  Atlas atlas;
  atlas.layout = PairTriangles(part);
  const int cells = std::max(1, atlas.layout.cells);
  atlas.grid = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(cells))));
  // Grow the texture (doubling, up to kMaxGrownTexturePx) until cells are
  // at least 4 px.
  while (size_px / atlas.grid < 4 && size_px < kMaxGrownTexturePx) {
    size_px = std::min(2 * size_px, kMaxGrownTexturePx);
  }
  atlas.size_px = size_px;
  atlas.cell_px = size_px / atlas.grid;
  if (atlas.cell_px < 4) {
    return Invalid(absl::StrCat("part ", part.part, ": ", part.triangles.size(),
                                " triangles do not fit a ", size_px, " px texture (cells of ",
                                atlas.cell_px, " px); lower the mesh resolution"));
  }
  atlas.inset_px = std::clamp(atlas.cell_px / 8.0, 0.5, 1.5);
  return atlas;
}

// The vertices of a part once baked: per triangle corner one vertex, except
// that the two triangles of a cell share the two on their diagonal.
// `source`: per baked vertex, the vertex of `part` it copies; `triangles`:
// the baked triangles, in `part`'s order.
struct BakedVertices {
  std::vector<int> source;
  std::vector<Eigen::Vector3i> triangles;
};

BakedVertices SplitVertices(const PartMesh& part, const CellLayout& layout) {
  BakedVertices out;
  out.source.reserve(part.triangles.size() * 2);
  out.triangles.reserve(part.triangles.size());
  // (cell, vertex of `part`) -> baked vertex, for the shared diagonals.
  std::map<std::pair<int, int>, int> on_diagonal;
  for (size_t t = 0; t < part.triangles.size(); ++t) {
    Eigen::Vector3i triangle;
    for (int k = 0; k < 3; ++k) {
      const int v = part.triangles[t][k];
      const int next = static_cast<int>(out.source.size());
      if (layout.apex[t] >= 0 && k != layout.apex[t]) {
        const auto [it, added] = on_diagonal.emplace(std::make_pair(layout.slot[t] / 2, v), next);
        triangle[k] = it->second;
        if (!added) continue;
      } else {
        triangle[k] = next;
      }
      out.source.push_back(v);
    }
    out.triangles.push_back(triangle);
  }
  return out;
}

// Barycentric coordinates of `p` in triangle `c`, clamped onto the triangle
// (texels of the gutter take the colour of the nearest edge).
Eigen::Vector3d ClampedBarycentric(const std::array<Eigen::Vector2d, 3>& c,
                                   const Eigen::Vector2d& p) {
  const Eigen::Vector2d e1 = c[1] - c[0], e2 = c[2] - c[0], d = p - c[0];
  const double det = e1.x() * e2.y() - e1.y() * e2.x();
  const double b1 = (d.x() * e2.y() - d.y() * e2.x()) / det;
  const double b2 = (e1.x() * d.y() - e1.y() * d.x()) / det;
  Eigen::Vector3d b(1.0 - b1 - b2, b1, b2);
  b = b.cwiseMax(0.0);
  return b / b.sum();
}

// Calls f(x, y, barycentric) for every texel of triangle `t`'s half cell.
template <typename F>
void ForEachTexel(const Atlas& atlas, int t, F&& f) {
  const std::array<Eigen::Vector2d, 3> corners = atlas.Corners(t);
  const Eigen::Vector2i o = atlas.CellOrigin(t);
  for (int ly = 0; ly < atlas.cell_px; ++ly) {
    for (int lx = 0; lx < atlas.cell_px; ++lx) {
      const bool first_half = lx + ly + 1 < atlas.cell_px;  // Texel centre before the diagonal.
      if (first_half != atlas.UpperHalf(t)) continue;
      const Eigen::Vector2d centre(o.x() + lx + 0.5, o.y() + ly + 0.5);
      f(o.x() + lx, o.y() + ly, ClampedBarycentric(corners, centre));
    }
  }
}

// A keyframe chosen for one triangle.
struct Candidate {
  int keyframe = 0;
  double weight = 0.0;   // Frontality, -n . v.
  bool partial = false;  // Not all three vertices visible: test per texel.
};

// Unit normal of triangle `t` in the part frame: the mean of its vertex
// normals, else the geometric normal; zero for a degenerate triangle.
Eigen::Vector3d TriangleNormal(const PartMesh& part, const Eigen::Vector3i& t) {
  Eigen::Vector3d normal = (part.normals_in_part.col(t[0]) + part.normals_in_part.col(t[1]) +
                            part.normals_in_part.col(t[2]))
                               .cast<double>();
  if (normal.squaredNorm() < 1e-12) {
    const Eigen::Vector3d a = part.positions_in_part_m.col(t[0]).cast<double>();
    normal = (part.positions_in_part_m.col(t[1]).cast<double>() - a)
                 .cross(part.positions_in_part_m.col(t[2]).cast<double>() - a);
  }
  if (normal.squaredNorm() < 1e-24) return Eigen::Vector3d::Zero();
  return normal.normalized();
}

// The keyframes a triangle takes its colour from: those that see all three
// vertices (else those that see any), most frontal first, up to blend_count
// within blend_frontality_window of the best.
std::vector<Candidate> ChooseKeyframes(const PartMesh& part, int part_id, const Eigen::Vector3i& t,
                                       const std::vector<BakeKeyframe>& keyframes,
                                       const BakeOptions& options) {
  const Eigen::Vector3d normal = TriangleNormal(part, t);
  if (normal.isZero()) return {};
  const Eigen::Vector3d centroid =
      (part.positions_in_part_m.col(t[0]) + part.positions_in_part_m.col(t[1]) +
       part.positions_in_part_m.col(t[2]))
          .cast<double>() /
      3.0;
  std::vector<Candidate> full, partial;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    const BakeKeyframe& kf = keyframes[k];
    const reenact::PartPose& pose = kf.poses[part_id];
    if (!pose.valid) continue;
    const std::string& bits = kf.message->vertex_visible_bits[part_id];
    const int seen =
        VertexVisible(bits, t[0]) + VertexVisible(bits, t[1]) + VertexVisible(bits, t[2]);
    if (seen == 0) continue;
    const Eigen::Matrix3d& rotation = kf.color_from_part_rotation[part_id];
    const Eigen::Vector3d in_camera =
        pose.scale * (rotation * centroid) + kf.part_origin_in_color[part_id];
    const Eigen::Vector3d n_camera = rotation * normal;
    const double frontality = -n_camera.dot(in_camera.normalized());
    if (!(frontality > 0.05)) continue;
    (seen == 3 ? full : partial).push_back({static_cast<int>(k), frontality, seen < 3});
  }
  std::vector<Candidate>& chosen = full.empty() ? partial : full;
  std::sort(chosen.begin(), chosen.end(),
            [](const Candidate& a, const Candidate& b) { return a.weight > b.weight; });
  std::vector<Candidate> out;
  for (const Candidate& c : chosen) {
    if (static_cast<int>(out.size()) == options.blend_count) break;
    if (c.weight < chosen.front().weight - options.blend_frontality_window) break;
    out.push_back(c);
  }
  return out;
}

// One part being baked: its atlas and per-texel colour sums.
struct PartBake {
  int part_id = 0;
  const PartMesh* geometry = nullptr;
  Atlas atlas;
  std::vector<float> colour_sum;       // 3 per texel, weighted.
  std::vector<float> weight_sum;       // 1 per texel.
  std::vector<uint8_t> triangle_seen;  // 1 per triangle.
};

// A triangle to texture from one keyframe.
struct WorkItem {
  int part = 0;  // Index into the PartBake list.
  int triangle = 0;
  Candidate candidate;
};

// Accumulates the colours that keyframe `kf` shows for the texels of one
// triangle: texels whose point lands on the crop's actor mask (and, for a
// partly visible triangle, whose nearest vertex is visible).
void AccumulateTriangle(const BakeKeyframe& kf, const RgbImage& crop, const MaskImage& mask,
                        const WorkItem& item, PartBake* bake) {
  const PartMesh& part = *bake->geometry;
  const Eigen::Vector3i& tri = part.triangles[item.triangle];
  const std::string& bits = kf.message->vertex_visible_bits[bake->part_id];
  const reenact::PartPose& pose = kf.poses[bake->part_id];
  const float w = static_cast<float>(item.candidate.weight);
  ForEachTexel(bake->atlas, item.triangle, [&](int x, int y, const Eigen::Vector3d& b) {
    int nearest = 0;
    b.maxCoeff(&nearest);
    if (item.candidate.partial && !VertexVisible(bits, tri[nearest])) return;
    const Eigen::Vector3d point = b[0] * part.positions_in_part_m.col(tri[0]).cast<double>() +
                                  b[1] * part.positions_in_part_m.col(tri[1]).cast<double>() +
                                  b[2] * part.positions_in_part_m.col(tri[2]).cast<double>();
    const auto pixel = ProjectToKeyframeCrop(point, pose, kf.camera);
    int px = 0, py = 0;
    if (!pixel || !NearestPixel(*pixel, crop.width, crop.height, &px, &py)) return;
    if (mask.at(px, py) == 0) return;
    const Eigen::Vector3f colour = SampleBilinear(crop, pixel->x(), pixel->y());
    const size_t texel = static_cast<size_t>(y) * bake->atlas.size_px + x;
    for (int c = 0; c < 3; ++c) bake->colour_sum[texel * 3 + c] += w * colour[c];
    bake->weight_sum[texel] += w;
    bake->triangle_seen[item.triangle] = 1;
  });
}

// The texture of a part: blended colours where observed, the mean observed
// colour (mid grey when there is none) elsewhere.
RgbImage FinishTexture(const PartBake& bake) {
  const int size = bake.atlas.size_px;
  RgbImage texture(size, size);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  size_t count = 0;
  for (size_t i = 0; i < texture.num_pixels(); ++i) {
    if (!(bake.weight_sum[i] > 0.0f)) continue;
    for (int c = 0; c < 3; ++c) {
      const float v = bake.colour_sum[i * 3 + c] / bake.weight_sum[i];
      texture.data[i * 3 + c] = static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      sum[c] += texture.data[i * 3 + c];
    }
    ++count;
  }
  const Eigen::Vector3d mean = count > 0 ? Eigen::Vector3d(sum / static_cast<double>(count))
                                         : Eigen::Vector3d::Constant(128);
  for (size_t i = 0; i < texture.num_pixels(); ++i) {
    if (bake.weight_sum[i] > 0.0f) continue;
    for (int c = 0; c < 3; ++c) {
      texture.data[i * 3 + c] = static_cast<uint8_t>(std::lround(mean[c]));
    }
  }
  return texture;
}

// `part` with its vertices split as SplitVertices says and their uvs (the
// shape, name, id and other fields unchanged).
PartMesh SplitMesh(const PartMesh& part, const Atlas& atlas) {
  BakedVertices split = SplitVertices(part, atlas.layout);
  const auto vertices = static_cast<Eigen::Index>(split.source.size());
  PartMesh mesh = part;
  mesh.positions_in_part_m.resize(3, vertices);
  mesh.normals_in_part.resize(3, vertices);
  mesh.uvs.resize(2, vertices);
  for (Eigen::Index v = 0; v < vertices; ++v) {
    mesh.positions_in_part_m.col(v) = part.positions_in_part_m.col(split.source[v]);
    mesh.normals_in_part.col(v) = part.normals_in_part.col(split.source[v]);
  }
  for (size_t t = 0; t < part.triangles.size(); ++t) {
    const std::array<Eigen::Vector2d, 3> uv_px = atlas.Corners(static_cast<int>(t));
    for (int k = 0; k < 3; ++k) {
      mesh.uvs.col(split.triangles[t][k]) =
          Eigen::Vector2f(static_cast<float>(uv_px[k].x() / atlas.size_px),
                          static_cast<float>(1.0 - uv_px[k].y() / atlas.size_px));  // Bottom-left.
    }
  }
  mesh.triangles = std::move(split.triangles);
  return mesh;
}

// Validates the meshes against the keyframes and lays out their atlases.
absl::StatusOr<std::vector<PartBake>> PlanParts(const std::vector<PartMesh>& parts,
                                                const std::vector<BakeKeyframe>& keyframes,
                                                const BakeOptions& options) {
  std::vector<PartBake> bakes;
  for (const PartMesh& mesh : parts) {
    if (mesh.part < 0) return Invalid(absl::StrCat("negative part id ", mesh.part));
    RETURN_IF_ERROR(ValidateGeometry(mesh, mesh.part));
    const int vertices = mesh.num_vertices();
    for (const BakeKeyframe& k : keyframes) {
      RETURN_IF_ERROR(CheckKeyframeCoversPart(k, mesh.part, vertices));
    }
    PartBake bake;
    bake.part_id = mesh.part;
    bake.geometry = &mesh;
    const int triangles = static_cast<int>(bake.geometry->triangles.size());
    ASSIGN_OR_RETURN(bake.atlas, LayOutAtlas(mesh, options.texture_size_px));
    const size_t texels = static_cast<size_t>(bake.atlas.size_px) * bake.atlas.size_px;
    bake.colour_sum.assign(texels * 3, 0.0f);
    bake.weight_sum.assign(texels, 0.0f);
    bake.triangle_seen.assign(triangles, 0);
    bakes.push_back(std::move(bake));
  }
  return bakes;
}

}  // namespace

absl::Status BakeOptions::Validate() const {
  if (texture_size_px < 8 || texture_size_px > 8192) {
    return Invalid("BakeOptions.texture_size_px must be in 8..8192");
  }
  if (jpeg_quality < 1 || jpeg_quality > 100)
    return Invalid("BakeOptions.jpeg_quality must be in 1..100");
  if (blend_count < 1) return Invalid("BakeOptions.blend_count must be >= 1");
  if (!std::isfinite(blend_frontality_window) || blend_frontality_window < 0.0) {
    return Invalid("BakeOptions.blend_frontality_window must be finite and >= 0");
  }
  return absl::OkStatus();
}

absl::Status BakePartTextures(const std::vector<TextureKeyframe>& keyframes,
                              const std::vector<ReenactmentFrame>& frames,
                              const std::vector<SensorCalibration>& sensors,
                              const BakeOptions& options, std::vector<PartMesh>* parts,
                              BakeSummary* summary) {
  if (parts == nullptr) return Invalid("BakePartTextures: parts is null");
  RETURN_IF_ERROR(options.Validate());
  std::map<int, const ReenactmentFrame*> frame_by_index;
  for (const ReenactmentFrame& f : frames) frame_by_index[f.frame_index] = &f;
  std::map<std::string, const SensorCalibration*> sensor_by_id;
  for (const SensorCalibration& s : sensors) sensor_by_id[s.sensor_id] = &s;
  std::vector<BakeKeyframe> prepared;
  prepared.reserve(keyframes.size());
  for (const TextureKeyframe& k : keyframes) {
    ASSIGN_OR_RETURN(BakeKeyframe keyframe, PrepareKeyframe(k, frame_by_index, sensor_by_id));
    prepared.push_back(std::move(keyframe));
  }
  ASSIGN_OR_RETURN(std::vector<PartBake> bakes, PlanParts(*parts, prepared, options));

  // Keyframe choice per triangle, then one pass per keyframe so that only
  // one crop is decoded at a time.
  std::vector<std::vector<WorkItem>> work(prepared.size());
  for (size_t p = 0; p < bakes.size(); ++p) {
    const PartMesh& geometry = *bakes[p].geometry;
    for (size_t t = 0; t < geometry.triangles.size(); ++t) {
      for (const Candidate& c :
           ChooseKeyframes(geometry, bakes[p].part_id, geometry.triangles[t], prepared, options)) {
        work[c.keyframe].push_back({static_cast<int>(p), static_cast<int>(t), c});
      }
    }
  }
  RgbImage crop;
  MaskImage mask;
  for (size_t k = 0; k < prepared.size(); ++k) {
    RETURN_IF_ERROR(DecodeKeyframe(*prepared[k].message, &crop, &mask));
    for (const WorkItem& item : work[k]) {
      AccumulateTriangle(prepared[k], crop, mask, item, &bakes[item.part]);
    }
  }

  BakeSummary figures;
  std::vector<PartMesh> baked;
  baked.reserve(bakes.size());
  for (size_t p = 0; p < bakes.size(); ++p) {
    baked.push_back(SplitMesh(*bakes[p].geometry, bakes[p].atlas));
    ASSIGN_OR_RETURN(baked[p].baked_texture_jpeg,
                     EncodeJpeg(FinishTexture(bakes[p]), options.jpeg_quality));
    const int triangles = static_cast<int>(bakes[p].triangle_seen.size());
    figures.triangles += triangles;
    figures.triangles_unobserved +=
        triangles - static_cast<int>(std::count(bakes[p].triangle_seen.begin(),
                                                bakes[p].triangle_seen.end(), uint8_t{1}));
    figures.min_cell_px =
        p == 0 ? bakes[p].atlas.cell_px : std::min(figures.min_cell_px, bakes[p].atlas.cell_px);
    ++figures.parts_baked;
  }
  parts->swap(baked);
  if (summary != nullptr) *summary = figures;
  return absl::OkStatus();
}

absl::Status RemapVisibilityBitsToBakedMeshes(const std::vector<PartMesh>& before_bake,
                                              std::vector<TextureKeyframe>* keyframes) {
  if (keyframes == nullptr) return Invalid("RemapVisibilityBitsToBakedMeshes: keyframes is null");
  std::vector<TextureKeyframe> remapped(*keyframes);
  for (const PartMesh& geometry : before_bake) {
    RETURN_IF_ERROR(ValidateGeometry(geometry, geometry.part));
    const int part = geometry.part;
    const size_t vertices = static_cast<size_t>(geometry.positions_in_part_m.cols());
    const std::vector<int> source = SplitVertices(geometry, PairTriangles(geometry)).source;
    for (TextureKeyframe& keyframe : remapped) {
      if (part < 0 || part >= static_cast<int>(keyframe.vertex_visible_bits.size()) ||
          keyframe.vertex_visible_bits[part].size() != (vertices + 7) / 8) {
        return Invalid(absl::StrCat(KeyframeName(keyframe), " part ", part,
                                    ": visibility bits do not match the mesh"));
      }
      const std::string& old_bits = keyframe.vertex_visible_bits[part];
      std::string bits((source.size() + 7) / 8, '\0');
      for (size_t v = 0; v < source.size(); ++v) {
        if (VertexVisible(old_bits, source[v])) SetBit(&bits, static_cast<int>(v));
      }
      keyframe.vertex_visible_bits[part] = std::move(bits);
    }
  }
  keyframes->swap(remapped);
  return absl::OkStatus();
}

}  // namespace reenact::recon
