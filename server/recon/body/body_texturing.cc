#include "server/recon/body/body_texturing.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include <unistd.h>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/video_writer.h"

namespace reenact::recon {
namespace {

// One atlas texel: the surface point it shows.
struct Texel {
  int index = 0;  // y * size + x.
  int triangle = 0;
  float b0 = 0, b1 = 0, b2 = 0;
};

// Texels whose centres lie in a texture triangle (first triangle wins).
std::vector<Texel> RasteriseAtlas(const BodyMesh& mesh, int size) {
  std::vector<Texel> texels;
  std::vector<uint8_t> taken(static_cast<size_t>(size) * size, 0);
  for (size_t t = 0; t < mesh.texture_triangles.size(); ++t) {
    Eigen::Vector2d p[3];
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector2f& uv = mesh.texture_uvs[mesh.texture_triangles[t][c]];
      p[c] = Eigen::Vector2d(uv.x() * size - 0.5, (1.0 - uv.y()) * size - 0.5);
    }
    const double area =
        (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
    if (std::abs(area) < 1e-12) continue;
    const int x0 =
        std::max(0, static_cast<int>(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}))));
    const int x1 =
        std::min(size - 1, static_cast<int>(std::ceil(std::max({p[0].x(), p[1].x(), p[2].x()}))));
    const int y0 =
        std::max(0, static_cast<int>(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}))));
    const int y1 =
        std::min(size - 1, static_cast<int>(std::ceil(std::max({p[0].y(), p[1].y(), p[2].y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d q(x, y);
        const auto edge = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
          return ((b - a).x() * (q - a).y() - (b - a).y() * (q - a).x()) / area;
        };
        const double w0 = edge(p[1], p[2]), w1 = edge(p[2], p[0]), w2 = edge(p[0], p[1]);
        constexpr double kEps = -1e-4;
        if (w0 < kEps || w1 < kEps || w2 < kEps) continue;
        const int index = y * size + x;
        if (taken[index]) continue;
        taken[index] = 1;
        texels.push_back({index, static_cast<int>(t), static_cast<float>(w0),
                          static_cast<float>(w1), static_cast<float>(w2)});
      }
    }
  }
  return texels;
}

// Depth of the posed mesh in a camera: a CPU z-buffer over projected
// triangles (vertices in the camera frame and their pixels).
std::vector<float> RenderDepth(const std::vector<Eigen::Vector3i>& triangles,
                               const std::vector<Eigen::Vector3f>& in_camera,
                               const std::vector<Eigen::Vector2f>& pixels, int width, int height) {
  std::vector<float> depth(static_cast<size_t>(width) * height,
                           std::numeric_limits<float>::infinity());
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3f& a = in_camera[t[0]];
    const Eigen::Vector3f& b = in_camera[t[1]];
    const Eigen::Vector3f& c = in_camera[t[2]];
    if (a.z() <= 0.05f || b.z() <= 0.05f || c.z() <= 0.05f) continue;
    const Eigen::Vector2f& pa = pixels[t[0]];
    const Eigen::Vector2f& pb = pixels[t[1]];
    const Eigen::Vector2f& pc = pixels[t[2]];
    const float area = (pb - pa).x() * (pc - pa).y() - (pb - pa).y() * (pc - pa).x();
    if (std::abs(area) < 1e-6f) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({pa.x(), pb.x(), pc.x()}))));
    const int x1 =
        std::min(width - 1, static_cast<int>(std::ceil(std::max({pa.x(), pb.x(), pc.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({pa.y(), pb.y(), pc.y()}))));
    const int y1 =
        std::min(height - 1, static_cast<int>(std::ceil(std::max({pa.y(), pb.y(), pc.y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2f q(static_cast<float>(x), static_cast<float>(y));
        const auto edge = [&](const Eigen::Vector2f& e0, const Eigen::Vector2f& e1) {
          return ((e1 - e0).x() * (q - e0).y() - (e1 - e0).y() * (q - e0).x()) / area;
        };
        const float w0 = edge(pb, pc), w1 = edge(pc, pa), w2 = edge(pa, pb);
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = w0 * a.z() + w1 * b.z() + w2 * c.z();
        float& d = depth[static_cast<size_t>(y) * width + x];
        d = std::min(d, z);
      }
    }
  }
  return depth;
}

// Minimum of the depth buffer over the 3 x 3 pixels around (x, y): tolerant
// of the half-pixel between a texel's projection and the raster.
float NearDepth(const std::vector<float>& depth, int width, int height, int x, int y) {
  float out = std::numeric_limits<float>::infinity();
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int u = x + dx, v = y + dy;
      if (u < 0 || v < 0 || u >= width || v >= height) continue;
      out = std::min(out, depth[static_cast<size_t>(v) * width + u]);
    }
  }
  return out;
}

// Whether the four pixels a bilinear lookup at (x..x+1, y..y+1) reads all
// show the posed mesh no farther than `max_depth_m`: at the silhouette a
// lookup would blend in the background, at an occlusion edge the surface
// behind.
bool TapsOnSurface(const std::vector<float>& depth, int width, int x, int y, float max_depth_m) {
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      if (!(depth[static_cast<size_t>(y + dy) * width + x + dx] <= max_depth_m)) return false;
    }
  }
  return true;
}

// Fills unobserved atlas texels (weight 0) from observed ones: a push-pull
// pyramid (average down, fill holes on the way up).
void PushPull(std::vector<Eigen::Vector4f>* sums, int size) {
  if (size <= 1) return;
  const int half = (size + 1) / 2;
  std::vector<Eigen::Vector4f> coarse(static_cast<size_t>(half) * half, Eigen::Vector4f::Zero());
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const Eigen::Vector4f& s = (*sums)[static_cast<size_t>(y) * size + x];
      if (s.w() > 0) coarse[static_cast<size_t>(y / 2) * half + x / 2] += s / s.w();
    }
  }
  PushPull(&coarse, half);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      Eigen::Vector4f& s = (*sums)[static_cast<size_t>(y) * size + x];
      if (s.w() > 0) continue;
      const Eigen::Vector4f& c = coarse[static_cast<size_t>(y / 2) * half + x / 2];
      if (c.w() > 0) s = c / c.w();
    }
  }
}

// Per pixel of a depth buffer of the posed mesh, the distance in pixels to
// its nearest edge: a pixel off the mesh, or one whose depth jumps by more
// than `jump_m` to a neighbour (an occlusion edge). Two-pass chamfer
// distance (1 along rows and columns, sqrt 2 diagonally), capped at 64.
std::vector<float> EdgeDistance(const std::vector<float>& depth, int width, int height,
                                float jump_m) {
  constexpr float kFar = 64.0f;
  constexpr float kDiagonal = 1.41421356f;
  std::vector<float> d(depth.size(), kFar);
  const auto at = [&](int x, int y) { return depth[static_cast<size_t>(y) * width + x]; };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float z = at(x, y);
      bool edge = !std::isfinite(z);
      if (!edge && x + 1 < width) edge = !(std::abs(at(x + 1, y) - z) <= jump_m);
      if (!edge && y + 1 < height) edge = !(std::abs(at(x, y + 1) - z) <= jump_m);
      if (!edge && x > 0) edge = !(std::abs(at(x - 1, y) - z) <= jump_m);
      if (!edge && y > 0) edge = !(std::abs(at(x, y - 1) - z) <= jump_m);
      if (edge) d[static_cast<size_t>(y) * width + x] = 0.0f;
    }
  }
  const auto relax = [&](int x, int y, int dx, int dy, float step) {
    const int u = x + dx, v = y + dy;
    if (u < 0 || v < 0 || u >= width || v >= height) return;
    float& here = d[static_cast<size_t>(y) * width + x];
    here = std::min(here, d[static_cast<size_t>(v) * width + u] + step);
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      relax(x, y, -1, 0, 1.0f);
      relax(x, y, 0, -1, 1.0f);
      relax(x, y, -1, -1, kDiagonal);
      relax(x, y, 1, -1, kDiagonal);
    }
  }
  for (int y = height - 1; y >= 0; --y) {
    for (int x = width - 1; x >= 0; --x) {
      relax(x, y, 1, 0, 1.0f);
      relax(x, y, 0, 1, 1.0f);
      relax(x, y, 1, 1, kDiagonal);
      relax(x, y, -1, 1, kDiagonal);
    }
  }
  return d;
}

// The observations of the atlas's texels in one (instant, sensor) view:
// per seen texel its colour times its weight, and the weight (cos^p of the
// angle to the normal; with `edge_falloff_px` > 0 also ramped from 0 at the
// posed mesh's silhouette and occlusion edges to 1 that many colour pixels
// away from them).
absl::Status ObserveView(const TakeFrames& take, const BodyMesh& mesh,
                         const std::vector<Texel>& texels, const Eigen::Matrix3Xd& posed,
                         int instant, int sensor, const AtlasOptions& options,
                         double edge_falloff_px,
                         std::vector<std::pair<int, Eigen::Vector4f>>* observations) {
  ASSIGN_OR_RETURN(const RgbImage colour,
                   take.LoadColor(instant, sensor, options.colour_denominator));
  ASSIGN_OR_RETURN(const CameraIntrinsics intrinsics, take.ColorIntrinsicsForImage(sensor, colour));
  const TakeSensor& info = take.sensors()[sensor];
  const Rigid3d color_from_world =
      (info.world_from_depth * info.color_from_depth.Inverse()).Inverse();
  const int v_count = mesh.num_vertices();
  // The sensor's own depth, for the measured-surface test.
  DepthImageMm measured;
  if (options.measured_threshold_m > 0) {
    ASSIGN_OR_RETURN(measured, take.LoadActorDepth(instant, sensor));
  }
  const Rigid3d depth_from_color = info.color_from_depth.Inverse();
  const float measured_threshold_mm = static_cast<float>(1000.0 * options.measured_threshold_m);
  std::vector<Eigen::Vector3f> in_camera(v_count);
  std::vector<Eigen::Vector2f> pixels(v_count);
  for (int v = 0; v < v_count; ++v) {
    const Eigen::Vector3d p = color_from_world * Eigen::Vector3d(posed.col(v));
    in_camera[v] = p.cast<float>();
    const auto pixel = intrinsics.Project(p);
    pixels[v] = pixel ? pixel->cast<float>() : Eigen::Vector2f(-1e6f, -1e6f);
  }
  const std::vector<float> depth =
      RenderDepth(mesh.triangles, in_camera, pixels, colour.width, colour.height);
  // Face normals in the camera frame.
  std::vector<Eigen::Vector3f> face_normal(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    face_normal[t] = (in_camera[tri[1]] - in_camera[tri[0]])
                         .cross(in_camera[tri[2]] - in_camera[tri[0]])
                         .normalized();
  }
  std::vector<float> edge_distance_px;
  if (edge_falloff_px > 0) {
    edge_distance_px = EdgeDistance(depth, colour.width, colour.height,
                                    static_cast<float>(options.visibility_threshold_m));
  }
  std::vector<std::pair<int, Eigen::Vector4f>>& local = *observations;
  local.clear();
  local.reserve(texels.size() / 4);
  const float threshold = static_cast<float>(options.visibility_threshold_m);
  const float power = static_cast<float>(options.frontality_power);
  for (const Texel& texel : texels) {
    const Eigen::Vector3i& tri = mesh.triangles[texel.triangle];
    const Eigen::Vector3f p =
        texel.b0 * in_camera[tri[0]] + texel.b1 * in_camera[tri[1]] + texel.b2 * in_camera[tri[2]];
    const float facing = -face_normal[texel.triangle].dot(p.normalized());
    if (!(facing > 0.1f)) continue;
    const Eigen::Vector2f q =
        texel.b0 * pixels[tri[0]] + texel.b1 * pixels[tri[1]] + texel.b2 * pixels[tri[2]];
    const int x = static_cast<int>(std::floor(q.x()));
    const int y = static_cast<int>(std::floor(q.y()));
    if (x < 0 || y < 0 || x + 1 >= colour.width || y + 1 >= colour.height) continue;
    const float rendered =
        NearDepth(depth, colour.width, colour.height, static_cast<int>(std::lround(q.x())),
                  static_cast<int>(std::lround(q.y())));
    if (p.z() > rendered + threshold) continue;  // Hidden (thesis 4.4, T).
    if (!measured.empty()) {
      // The sensor must have measured this surface there (not a hand in
      // front of it that the fit put elsewhere).
      const Eigen::Vector3d in_depth = depth_from_color * p.cast<double>();
      const auto dp = info.depth_intrinsics.Project(in_depth);
      if (!dp) continue;
      const int dx = static_cast<int>(std::lround(dp->x()));
      const int dy = static_cast<int>(std::lround(dp->y()));
      if (dx < 0 || dy < 0 || dx >= measured.width || dy >= measured.height) continue;
      const uint16_t d = measured.at(dx, dy);
      if (d == 0 || std::abs(static_cast<float>(d) - 1000.0f * static_cast<float>(in_depth.z())) >
                        measured_threshold_mm) {
        continue;
      }
    }
    if (!TapsOnSurface(depth, colour.width, x, y, p.z() + threshold)) continue;
    const float fx = q.x() - x, fy = q.y() - y;
    Eigen::Vector3f rgb;
    for (int c = 0; c < 3; ++c) {
      rgb[c] = (1 - fx) * (1 - fy) * colour.at(x, y, c) + fx * (1 - fy) * colour.at(x + 1, y, c) +
               (1 - fx) * fy * colour.at(x, y + 1, c) + fx * fy * colour.at(x + 1, y + 1, c);
    }
    float weight = std::pow(facing, power);
    if (!edge_distance_px.empty()) {
      const float d = edge_distance_px[static_cast<size_t>(std::lround(q.y())) * colour.width +
                                       std::lround(q.x())];
      weight *= std::min(1.0f, d / static_cast<float>(edge_falloff_px));
      if (!(weight > 0)) continue;
    }
    local.emplace_back(
        texel.index, Eigen::Vector4f(weight * rgb.x(), weight * rgb.y(), weight * rgb.z(), weight));
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status AtlasOptions::Validate() const {
  if (size_px < 16 || size_px > 8192) {
    return absl::InvalidArgumentError(absl::StrCat("atlas size ", size_px, " outside [16, 8192]"));
  }
  if (!(visibility_threshold_m > 0)) {
    return absl::InvalidArgumentError("visibility threshold must be > 0");
  }
  if (every < 1) return absl::InvalidArgumentError("texture every must be >= 1");
  if (colour_denominator != 1 && colour_denominator != 2 && colour_denominator != 4 &&
      colour_denominator != 8) {
    return absl::InvalidArgumentError("colour denominator must be 1, 2, 4 or 8");
  }
  return absl::OkStatus();
}

absl::StatusOr<AtlasSums> AccumulateBodyAtlas(const TakeFrames& take, const BodyMesh& mesh,
                                              const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                              const AtlasOptions& options,
                                              const ProgressCallback& progress, int first,
                                              int end) {
  RETURN_IF_ERROR(options.Validate());
  if (posed_vertices_m.size() != static_cast<size_t>(take.num_instants())) {
    return absl::InvalidArgumentError("one posed mesh per instant expected");
  }
  if (end < 0) end = take.num_instants();
  if (first < 0 || first > end || end > take.num_instants()) {
    return absl::InvalidArgumentError(
        absl::StrCat("instants [", first, ", ", end, ") outside the take's ", take.num_instants()));
  }
  const int size = options.size_px;
  const std::vector<Texel> texels = RasteriseAtlas(mesh, size);
  std::vector<std::pair<int, int>> views;
  // Every k-th instant of the whole take, whichever range is baked, so that
  // ranges baked apart sum to the whole.
  for (int i = first + (options.every - first % options.every) % options.every; i < end;
       i += options.every) {
    if (posed_vertices_m[i].cols() != mesh.num_vertices()) continue;
    for (int s = 0; s < take.num_sensors(); ++s) {
      const SensorView& view = take.instant(i).views[s];
      if (view.present && !view.color_jpeg.empty()) views.emplace_back(i, s);
    }
  }
  // Sums per texel: r, g, b (weighted), weight.
  std::vector<Eigen::Vector4f> sums(static_cast<size_t>(size) * size, Eigen::Vector4f::Zero());
  std::mutex mutex;
  std::atomic<int> done{0};
  std::atomic<bool> cancelled{false};
  absl::Status first_error;
  take.pool().ParallelFor(0, static_cast<int>(views.size()), [&](int k) {
    if (cancelled) return;
    // Named locals, not a structured binding: the lambda below uses them.
    const int instant = views[k].first;
    const int sensor = views[k].second;
    absl::Status status = [&]() -> absl::Status {
      std::vector<std::pair<int, Eigen::Vector4f>> local;
      RETURN_IF_ERROR(ObserveView(take, mesh, texels, posed_vertices_m[instant], instant, sensor,
                                  options,
                                  /*edge_falloff_px=*/0.0, &local));
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& [index, value] : local) sums[index] += value;
      return absl::OkStatus();
    }();
    const int finished = ++done;
    std::lock_guard<std::mutex> lock(mutex);
    if (!status.ok() && first_error.ok()) first_error = status;
    if (!status.ok()) cancelled = true;
    if (progress && !progress({"texture", static_cast<double>(finished) / views.size(), finished,
                               static_cast<int64_t>(views.size())})) {
      cancelled = true;
    }
  });
  RETURN_IF_ERROR(first_error);
  if (cancelled) return absl::CancelledError("cancelled while texturing");
  AtlasSums out;
  out.size_px = size;
  out.views = static_cast<int>(views.size());
  out.sums = std::move(sums);
  return out;
}

absl::Status AddAtlasSums(const AtlasSums& part, AtlasSums& total) {
  if (part.sums.size() != static_cast<size_t>(part.size_px) * part.size_px) {
    return absl::InvalidArgumentError("atlas sums of the wrong size");
  }
  if (total.sums.empty()) {
    total = part;
    return absl::OkStatus();
  }
  if (part.size_px != total.size_px) {
    return absl::InvalidArgumentError(absl::StrCat("atlas sums of ", part.size_px, " and ",
                                                   total.size_px, " px cannot be added"));
  }
  for (size_t i = 0; i < part.sums.size(); ++i) total.sums[i] += part.sums[i];
  total.views += part.views;
  return absl::OkStatus();
}

absl::StatusOr<AtlasResult> FinishBodyAtlas(const BodyMesh& mesh, AtlasSums sums) {
  const int size = sums.size_px;
  if (size < 16 || size > 8192 || sums.sums.size() != static_cast<size_t>(size) * size) {
    return absl::InvalidArgumentError("atlas sums of the wrong size");
  }
  const std::vector<Texel> texels = RasteriseAtlas(mesh, size);
  std::vector<Eigen::Vector4f>& sum = sums.sums;
  AtlasResult result;
  result.views = sums.views;
  int observed = 0;
  for (const Texel& texel : texels) observed += sum[texel.index].w() > 0 ? 1 : 0;
  result.observed_fraction = texels.empty() ? 0.0 : static_cast<double>(observed) / texels.size();
  PushPull(&sum, size);
  result.atlas = RgbImage(size, size);
  for (int i = 0; i < size * size; ++i) {
    const Eigen::Vector4f& s = sum[i];
    for (int c = 0; c < 3; ++c) {
      const float value = s.w() > 0 ? s[c] / s.w() : 128.0f;
      result.atlas.data[3 * i + c] = static_cast<uint8_t>(std::clamp(value + 0.5f, 0.0f, 255.0f));
    }
  }
  return result;
}

absl::StatusOr<AtlasResult> BakeBodyAtlas(const TakeFrames& take, const BodyMesh& mesh,
                                          const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                          const AtlasOptions& options,
                                          const ProgressCallback& progress) {
  ASSIGN_OR_RETURN(AtlasSums sums,
                   AccumulateBodyAtlas(take, mesh, posed_vertices_m, options, progress));
  return FinishBodyAtlas(mesh, std::move(sums));
}

absl::Status AppearanceOptions::Validate() const {
  if (size_px < 16 || size_px > 8192) {
    return absl::InvalidArgumentError(
        absl::StrCat("appearance size ", size_px, " outside [16, 8192]"));
  }
  if (window < 0 || window > 16) {
    return absl::InvalidArgumentError(
        absl::StrCat("appearance window ", window, " outside [0, 16]"));
  }
  if (!(prior_weight > 0) || !(edge_falloff_px >= 0)) {
    return absl::InvalidArgumentError("appearance prior weight must be > 0 and edge falloff >= 0");
  }
  return absl::OkStatus();
}

namespace {

// Bilinear sample of `image` at texel (x, y) of a size x size atlas over
// the same uvs (texel centres aligned).
Eigen::Vector3f SampleAtlas(const RgbImage& image, int size, int x, int y) {
  const float px = (static_cast<float>(x) + 0.5f) * image.width / size - 0.5f;
  const float py = (static_cast<float>(y) + 0.5f) * image.height / size - 0.5f;
  const int x0 = std::clamp(static_cast<int>(std::floor(px)), 0, image.width - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(py)), 0, image.height - 1);
  const int x1 = std::min(x0 + 1, image.width - 1), y1 = std::min(y0 + 1, image.height - 1);
  const float fx = std::clamp(px - static_cast<float>(x0), 0.0f, 1.0f);
  const float fy = std::clamp(py - static_cast<float>(y0), 0.0f, 1.0f);
  Eigen::Vector3f out;
  for (int c = 0; c < 3; ++c) {
    out[c] = (1 - fx) * (1 - fy) * image.at(x0, y0, c) + fx * (1 - fy) * image.at(x1, y0, c) +
             (1 - fx) * fy * image.at(x0, y1, c) + fx * fy * image.at(x1, y1, c);
  }
  return out;
}

using Observations = std::vector<std::pair<int, Eigen::Vector4f>>;

}  // namespace

absl::Status BakeBodyAppearance(
    const TakeFrames& take, const BodyMesh& mesh,
    const std::vector<Eigen::Matrix3Xd>& posed_vertices_m, const RgbImage& static_atlas,
    const AtlasOptions& atlas_options, const AppearanceOptions& options,
    const std::function<absl::Status(int instant, const RgbImage& atlas)>& sink,
    const ProgressCallback& progress, AppearanceFigures* figures) {
  RETURN_IF_ERROR(atlas_options.Validate());
  RETURN_IF_ERROR(options.Validate());
  if (posed_vertices_m.size() != static_cast<size_t>(take.num_instants())) {
    return absl::InvalidArgumentError("one posed mesh per instant expected");
  }
  if (static_atlas.width < 1 || static_atlas.height < 1 ||
      static_atlas.data.size() !=
          static_cast<size_t>(static_atlas.width) * static_atlas.height * 3) {
    return absl::InvalidArgumentError("appearance needs the static atlas");
  }
  const int size = options.size_px;
  const int n = take.num_instants();
  const std::vector<Texel> texels = RasteriseAtlas(mesh, size);
  // The prior: the static atlas's colour at every surface texel.
  std::vector<Eigen::Vector3f> prior(texels.size());
  for (size_t t = 0; t < texels.size(); ++t) {
    prior[t] = SampleAtlas(static_atlas, size, texels[t].index % size, texels[t].index / size);
  }
  // Observations of the instants in the window, combined over sensors.
  std::map<int, Observations> observed;
  const auto observe = [&](int instant) -> absl::Status {
    if (observed.count(instant) > 0) return absl::OkStatus();
    Observations& all = observed[instant];
    if (posed_vertices_m[instant].cols() != mesh.num_vertices()) return absl::OkStatus();
    std::vector<int> sensors;
    for (int s = 0; s < take.num_sensors(); ++s) {
      const SensorView& view = take.instant(instant).views[s];
      if (view.present && !view.color_jpeg.empty()) sensors.push_back(s);
    }
    std::vector<Observations> per_sensor(sensors.size());
    std::vector<absl::Status> status(sensors.size());
    take.pool().ParallelFor(0, static_cast<int>(sensors.size()), [&](int k) {
      status[k] = ObserveView(take, mesh, texels, posed_vertices_m[instant], instant, sensors[k],
                              atlas_options, options.edge_falloff_px, &per_sensor[k]);
    });
    for (size_t k = 0; k < sensors.size(); ++k) {
      RETURN_IF_ERROR(status[k]);
      all.insert(all.end(), per_sensor[k].begin(), per_sensor[k].end());
    }
    return absl::OkStatus();
  };
  const float lambda = static_cast<float>(options.prior_weight);
  std::vector<Eigen::Vector4f> sums(static_cast<size_t>(size) * size);
  std::vector<uint8_t> seen(static_cast<size_t>(size) * size);
  RgbImage atlas(size, size);
  double observed_sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const int first = std::max(0, i - options.window);
    const int last = std::min(n - 1, i + options.window);
    for (int k = first; k <= last; ++k) RETURN_IF_ERROR(observe(k));
    while (!observed.empty() && observed.begin()->first < first) observed.erase(observed.begin());
    std::fill(sums.begin(), sums.end(), Eigen::Vector4f::Zero());
    std::fill(seen.begin(), seen.end(), 0);
    for (size_t t = 0; t < texels.size(); ++t) {
      sums[texels[t].index] = Eigen::Vector4f(lambda * prior[t].x(), lambda * prior[t].y(),
                                              lambda * prior[t].z(), lambda);
    }
    if (posed_vertices_m[i].cols() == mesh.num_vertices()) {
      for (int k = first; k <= last; ++k) {
        const float temporal = std::ldexp(1.0f, -std::abs(k - i));
        for (const auto& [index, value] : observed[k]) {
          sums[index] += temporal * value;
          seen[index] = 1;
        }
      }
    }
    int seen_count = 0;
    for (const Texel& texel : texels) seen_count += seen[texel.index];
    observed_sum += texels.empty() ? 0.0 : static_cast<double>(seen_count) / texels.size();
    PushPull(&sums, size);
    for (int p = 0; p < size * size; ++p) {
      const Eigen::Vector4f& v = sums[p];
      for (int c = 0; c < 3; ++c) {
        const float value = v.w() > 0 ? v[c] / v.w() : 128.0f;
        atlas.data[3 * p + c] = static_cast<uint8_t>(std::clamp(value + 0.5f, 0.0f, 255.0f));
      }
    }
    RETURN_IF_ERROR(sink(i, atlas));
    if (progress && !progress({"appearance", static_cast<double>(i + 1) / n, i + 1, n})) {
      return absl::CancelledError("cancelled while baking the appearance");
    }
  }
  if (figures != nullptr) {
    figures->frames = n;
    figures->mean_observed_fraction = n > 0 ? observed_sum / n : 0.0;
  }
  return absl::OkStatus();
}

namespace {

// A file in the system's temporary folder, removed with this object. The
// video goes through a file because the MP4 muxer's faststart pass (the index
// moved to the front, so a player can start before the whole file has
// arrived) reopens its output by name to shift the data.
class TemporaryFile {
 public:
  static absl::StatusOr<TemporaryFile> Create(const std::string& suffix) {
    std::error_code error;
    const std::filesystem::path folder = std::filesystem::temp_directory_path(error);
    if (error) return absl::InternalError("no temporary folder: " + error.message());
    std::string path = (folder / ("reenact-XXXXXX" + suffix)).string();
    const int fd = mkstemps(path.data(), static_cast<int>(suffix.size()));
    if (fd < 0) return absl::InternalError(absl::StrCat("cannot create ", path));
    close(fd);
    return TemporaryFile(std::move(path));
  }
  TemporaryFile(TemporaryFile&& other) noexcept : path_(std::exchange(other.path_, "")) {}
  TemporaryFile& operator=(TemporaryFile&&) = delete;
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  ~TemporaryFile() {
    if (!path_.empty()) std::remove(path_.c_str());
  }
  const std::string& path() const { return path_; }

 private:
  explicit TemporaryFile(std::string path) : path_(std::move(path)) {}
  std::string path_;
};

}  // namespace

absl::Status BakeAppearanceVideo(const TakeFrames& take,
                                 const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                 const RgbImage& static_atlas, const AtlasOptions& atlas_options,
                                 const AppearanceOptions& options, int crf, BodyMesh* mesh,
                                 const ProgressCallback& progress, AppearanceFigures* figures) {
  ASSIGN_OR_RETURN(const TemporaryFile file, TemporaryFile::Create(".mp4"));
  VideoWriterOptions video;
  video.crf = crf;
  // One key frame a second: a player seeks to any instant decoding at most
  // a second of frames.
  video.keyframe_interval = std::max(1, static_cast<int>(std::lround(take.fps())));
  const int size = options.size_px;
  ASSIGN_OR_RETURN(std::unique_ptr<VideoWriter> writer,
                   VideoWriter::Open(file.path(), size, size, take.fps(), video));
  RETURN_IF_ERROR(BakeBodyAppearance(
      take, *mesh, posed_vertices_m, static_atlas, atlas_options, options,
      [&writer](int /*instant*/, const RgbImage& atlas) { return writer->Append(atlas); }, progress,
      figures));
  RETURN_IF_ERROR(writer->Close());
  std::ifstream in(file.path(), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad() || bytes.empty()) {
    return absl::InternalError("cannot read back the appearance video");
  }
  mesh->appearance_mp4 = std::move(bytes);
  mesh->appearance_size_px = size;
  mesh->appearance_frame_count = take.num_instants();
  mesh->appearance_codec = writer->codec_name();
  return absl::OkStatus();
}

}  // namespace reenact::recon
