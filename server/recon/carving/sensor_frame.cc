#include "server/recon/carving/sensor_frame.h"

#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"

namespace reenact::recon::carving {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

absl::StatusOr<PosedCamera> PosedCamera::Create(const CameraIntrinsics& intrinsics,
                                                const Rigid3d& world_from_camera) {
  if (absl::Status status = intrinsics.Validate(); !status.ok()) return status;
  PosedCamera camera;
  camera.intrinsics_ = intrinsics;
  camera.world_from_camera_ = world_from_camera;
  camera.rotation_ = world_from_camera.rotation.toRotationMatrix().cast<float>();
  camera.rotation_t_ = camera.rotation_.transpose();
  camera.translation_ = world_from_camera.translation.cast<float>();
  camera.distorted_ = intrinsics.HasDistortion();
  camera.fx_ = static_cast<float>(intrinsics.fx);
  camera.fy_ = static_cast<float>(intrinsics.fy);
  camera.cx_ = static_cast<float>(intrinsics.cx);
  camera.cy_ = static_cast<float>(intrinsics.cy);
  camera.k1_ = static_cast<float>(intrinsics.k1);
  camera.k2_ = static_cast<float>(intrinsics.k2);
  camera.k3_ = static_cast<float>(intrinsics.k3);
  camera.p1_ = static_cast<float>(intrinsics.p1);
  camera.p2_ = static_cast<float>(intrinsics.p2);
  camera.rays_.resize(static_cast<size_t>(intrinsics.width) * intrinsics.height);
  for (int y = 0; y < intrinsics.height; ++y) {
    for (int x = 0; x < intrinsics.width; ++x) {
      const Eigen::Vector2d distorted((x - intrinsics.cx) / intrinsics.fx,
                                      (y - intrinsics.cy) / intrinsics.fy);
      std::optional<Eigen::Vector2d> ray = intrinsics.Undistort(distorted);
      if (!ray) {
        return absl::InvalidArgumentError(
            absl::StrCat("PosedCamera: the ray of pixel (", x, ", ", y, ") does not undistort"));
      }
      camera.rays_[static_cast<size_t>(y) * intrinsics.width + x] = ray->cast<float>();
    }
  }
  return camera;
}

std::optional<size_t> SurfaceMap::CellAt(const Eigen::Vector2f& pixel) const {
  const int x = static_cast<int>(std::lround(pixel.x() / static_cast<float>(step)));
  const int y = static_cast<int>(std::lround(pixel.y() / static_cast<float>(step)));
  if (x < 0 || y < 0 || x >= width || y >= height) return std::nullopt;
  return Index(x, y);
}

absl::StatusOr<SurfaceMap> BuildSurfaceMap(const PosedCamera& camera, const DepthImageMm& depth_mm,
                                           const MaskImage* mask,
                                           const SurfaceMapOptions& options) {
  if (depth_mm.width != camera.width() || depth_mm.height != camera.height()) {
    return absl::InvalidArgumentError(absl::StrCat("BuildSurfaceMap: depth is ", depth_mm.width,
                                                   "x", depth_mm.height, ", the camera ",
                                                   camera.width(), "x", camera.height()));
  }
  if (mask && (mask->width != depth_mm.width || mask->height != depth_mm.height)) {
    return absl::InvalidArgumentError(absl::StrCat("BuildSurfaceMap: mask is ", mask->width, "x",
                                                   mask->height, ", depth ", depth_mm.width, "x",
                                                   depth_mm.height));
  }
  if (options.step < 1) return absl::InvalidArgumentError("BuildSurfaceMap: step < 1");
  SurfaceMap map;
  map.step = options.step;
  map.width = (depth_mm.width + options.step - 1) / options.step;
  map.height = (depth_mm.height + options.step - 1) / options.step;
  const size_t cells = static_cast<size_t>(map.width) * map.height;
  map.points_in_world_m.assign(cells, Eigen::Vector3f::Constant(kNaN));
  map.normals_in_world.assign(cells, Eigen::Vector3f::Constant(kNaN));
  std::vector<uint16_t> cell_depth(cells, 0);
  for (int my = 0; my < map.height; ++my) {
    for (int mx = 0; mx < map.width; ++mx) {
      const int x = mx * options.step;
      const int y = my * options.step;
      const uint16_t d = depth_mm.at(x, y);
      if (d < options.min_depth_mm || d > options.max_depth_mm) continue;
      if (mask && mask->at(x, y) == 0) continue;
      cell_depth[map.Index(mx, my)] = d;
      map.points_in_world_m[map.Index(mx, my)] = camera.Unproject(x, y, d * 0.001f);
    }
  }
  // Normals: cross product of central differences on the map grid, falling
  // back to one-sided differences at discontinuities; oriented to the camera.
  const Eigen::Vector3f camera_centre = camera.world_from_camera().translation.cast<float>();
  auto usable = [&](int mx, int my, uint16_t centre_depth) {
    if (mx < 0 || my < 0 || mx >= map.width || my >= map.height) return false;
    const uint16_t d = cell_depth[map.Index(mx, my)];
    return d != 0 && std::abs(static_cast<int>(d) - centre_depth) <= options.max_depth_step_mm;
  };
  for (int my = 0; my < map.height; ++my) {
    for (int mx = 0; mx < map.width; ++mx) {
      const size_t index = map.Index(mx, my);
      const uint16_t d = cell_depth[index];
      if (d == 0) continue;
      const Eigen::Vector3f& p = map.points_in_world_m[index];
      auto difference = [&](int dx, int dy) -> std::optional<Eigen::Vector3f> {
        const bool plus = usable(mx + dx, my + dy, d);
        const bool minus = usable(mx - dx, my - dy, d);
        if (plus && minus) {
          return map.points_in_world_m[map.Index(mx + dx, my + dy)] -
                 map.points_in_world_m[map.Index(mx - dx, my - dy)];
        }
        if (plus) return map.points_in_world_m[map.Index(mx + dx, my + dy)] - p;
        if (minus) return p - map.points_in_world_m[map.Index(mx - dx, my - dy)];
        return std::nullopt;
      };
      const std::optional<Eigen::Vector3f> du = difference(1, 0);
      const std::optional<Eigen::Vector3f> dv = difference(0, 1);
      if (!du || !dv) continue;
      Eigen::Vector3f normal = du->cross(*dv);
      const float norm = normal.norm();
      if (!(norm > 0.0f)) continue;
      normal /= norm;
      if (normal.dot(camera_centre - p) < 0.0f) normal = -normal;
      map.normals_in_world[index] = normal;
    }
  }
  return map;
}

void RemoveDepthEdges(int max_step_mm, DepthImageMm* depth_mm) {
  if (max_step_mm <= 0) return;
  const int width = depth_mm->width;
  const int height = depth_mm->height;
  std::vector<uint8_t> edge(static_cast<size_t>(width) * height, 0);
  const uint16_t* d = depth_mm->data.data();
  // Each neighbouring pair (right, down, both diagonals) is compared once and
  // marks both pixels.
  auto compare = [&](size_t a, size_t b) {
    if (d[a] == 0 || d[b] == 0) return;
    if (std::abs(static_cast<int>(d[a]) - static_cast<int>(d[b])) > max_step_mm) {
      edge[a] = 1;
      edge[b] = 1;
    }
  };
  for (int y = 0; y < height; ++y) {
    const size_t row = static_cast<size_t>(y) * width;
    for (int x = 0; x < width; ++x) {
      const size_t i = row + x;
      if (x + 1 < width) compare(i, i + 1);
      if (y + 1 < height) {
        compare(i, i + width);
        if (x + 1 < width) compare(i, i + width + 1);
        if (x > 0) compare(i, i + width - 1);
      }
    }
  }
  for (size_t i = 0; i < edge.size(); ++i) {
    if (edge[i]) depth_mm->data[i] = 0;
  }
}

ColorLookup BuildColorLookup(const SurfaceMap& surface, const PosedCamera& color_camera) {
  ColorLookup lookup;
  lookup.width = color_camera.width();
  lookup.height = color_camera.height();
  const size_t pixels = static_cast<size_t>(lookup.width) * lookup.height;
  lookup.cell.assign(pixels, -1);
  lookup.z_m.assign(pixels, std::numeric_limits<float>::infinity());
  for (size_t index = 0; index < surface.points_in_world_m.size(); ++index) {
    if (!surface.HasPoint(index)) continue;
    const Eigen::Vector3f in_color = color_camera.ToCamera(surface.points_in_world_m[index]);
    Eigen::Vector2f pixel;
    if (!color_camera.ProjectCameraPoint(in_color, &pixel)) continue;
    const int x = static_cast<int>(std::lround(pixel.x()));
    const int y = static_cast<int>(std::lround(pixel.y()));
    if (x < 0 || y < 0 || x >= lookup.width || y >= lookup.height) continue;
    const size_t at = static_cast<size_t>(y) * lookup.width + x;
    if (in_color.z() < lookup.z_m[at]) {
      lookup.z_m[at] = in_color.z();
      lookup.cell[at] = static_cast<int32_t>(index);
    }
  }
  return lookup;
}

}  // namespace reenact::recon::carving
