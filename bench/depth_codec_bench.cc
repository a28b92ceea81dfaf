// Depth codec speed and compression ratio on a synthetic Kinect v2 frame:
// RVL, RVL + zstd, and plain zstd on the raw 16-bit pixels.
//
// The frame is ray-cast: a sensor 1.2 m above the floor, pitched 8 degrees
// down, in a 4.4 m x 4.4 m room (floor, ceiling, side and back walls) with a
// person-like set of ellipsoids 2.5 m away. Noise grows with distance
// (sigma = 1 mm + 0.2 mm/m^2 * z^2: 1.8 mm at 2 m, 4.2 mm at 4 m); pixels beyond 4.5 m, in the dark
// corners, at depth edges (flying pixels) and 1% at random are invalid (0).
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <zstd.h>

#include "common/geometry/camera.h"
#include "common/io/depth_codec.h"

namespace reenact {
namespace {

struct Ellipsoid {
  Eigen::Vector3d centre_in_world;  // Metres.
  Eigen::Vector3d radii_m;
};

// Distance along `direction` (unit) from `origin` to the ellipsoid, or inf.
double HitEllipsoid(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                    const Ellipsoid& ellipsoid) {
  const Eigen::Vector3d o = (origin - ellipsoid.centre_in_world).cwiseQuotient(ellipsoid.radii_m);
  const Eigen::Vector3d d = direction.cwiseQuotient(ellipsoid.radii_m);
  const double a = d.squaredNorm();
  const double b = 2.0 * o.dot(d);
  const double c = o.squaredNorm() - 1.0;
  const double discriminant = b * b - 4.0 * a * c;
  if (discriminant < 0.0) return INFINITY;
  const double t = (-b - std::sqrt(discriminant)) / (2.0 * a);
  return t > 0.0 ? t : INFINITY;
}

// Distance to the plane {x : x[axis] = value}, or inf when behind.
double HitPlane(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, int axis,
                double value) {
  if (std::abs(direction[axis]) < 1e-9) return INFINITY;
  const double t = (value - origin[axis]) / direction[axis];
  return t > 0.0 ? t : INFINITY;
}

DepthImageMm SyntheticKinectV2Frame() {
  const CameraIntrinsics intrinsics = KinectV2DepthIntrinsics();
  const double pitch_rad = 8.0 * M_PI / 180.0;
  // Camera (x right, y down, z forward) to world (+Y up): flip y, then pitch down.
  const Eigen::Matrix3d world_from_camera =
      Eigen::AngleAxisd(-pitch_rad, Eigen::Vector3d::UnitX()).toRotationMatrix() *
      Eigen::Vector3d(1.0, -1.0, 1.0).asDiagonal();
  const Eigen::Vector3d sensor_in_world(0.0, 1.2, 0.0);
  const std::vector<Ellipsoid> body = {
      {{0.0, 1.62, 2.5}, {0.10, 0.12, 0.11}},                                             // Head.
      {{0.0, 1.25, 2.5}, {0.19, 0.30, 0.12}},                                             // Torso.
      {{-0.1, 0.45, 2.5}, {0.08, 0.45, 0.09}},                                            // Legs.
      {{0.1, 0.45, 2.5}, {0.08, 0.45, 0.09}},  {{-0.3, 1.15, 2.45}, {0.05, 0.32, 0.06}},  // Arms.
      {{0.3, 1.15, 2.45}, {0.05, 0.32, 0.06}},
  };
  std::mt19937 rng(42);
  std::normal_distribution<double> unit_noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DepthImageMm depth_mm(intrinsics.width, intrinsics.height);
  std::vector<double> z_m(depth_mm.num_pixels(), 0.0);
  for (int y = 0; y < intrinsics.height; ++y) {
    for (int x = 0; x < intrinsics.width; ++x) {
      const Eigen::Vector3d ray_in_camera = *intrinsics.Unproject(Eigen::Vector2d(x, y), 1.0);
      const Eigen::Vector3d direction = (world_from_camera * ray_in_camera).normalized();
      double t = std::min({HitPlane(sensor_in_world, direction, 1, 0.0),
                           HitPlane(sensor_in_world, direction, 1, 2.7),
                           HitPlane(sensor_in_world, direction, 0, -2.2),
                           HitPlane(sensor_in_world, direction, 0, 2.2),
                           HitPlane(sensor_in_world, direction, 2, 4.4)});
      for (const Ellipsoid& part : body)
        t = std::min(t, HitEllipsoid(sensor_in_world, direction, part));
      // Depth is z along the optical axis: t times the ray's z per unit length.
      z_m[static_cast<size_t>(y) * intrinsics.width + x] = t / ray_in_camera.norm();
    }
  }
  for (int y = 0; y < intrinsics.height; ++y) {
    for (int x = 0; x < intrinsics.width; ++x) {
      const double z = z_m[static_cast<size_t>(y) * intrinsics.width + x];
      const double corner = std::hypot((x - 256.0) / 256.0, (y - 212.0) / 212.0);
      bool invalid = z > 4.5 || corner > 1.3 || uniform(rng) < 0.01;
      if (x + 1 < intrinsics.width && y + 1 < intrinsics.height) {
        const double step =
            std::max(std::abs(z - z_m[static_cast<size_t>(y) * intrinsics.width + x + 1]),
                     std::abs(z - z_m[static_cast<size_t>(y + 1) * intrinsics.width + x]));
        invalid = invalid || (step > 0.1 && uniform(rng) < 0.7);
      }
      const double sigma_mm = 1.0 + 0.2 * z * z;
      depth_mm.at(x, y) =
          invalid ? 0 : static_cast<uint16_t>(std::lround(z * 1000.0 + sigma_mm * unit_noise(rng)));
    }
  }
  return depth_mm;
}

const DepthImageMm& Frame() {
  static const DepthImageMm* frame = new DepthImageMm(SyntheticKinectV2Frame());
  return *frame;
}

double RawBytes() { return static_cast<double>(Frame().data.size() * sizeof(uint16_t)); }

DepthCodecOptions Options(bool zstd, int level) {
  DepthCodecOptions options;
  options.zstd = zstd;
  options.zstd_level = level;
  return options;
}

// Args: zstd stage (0/1), zstd level.
void BM_RvlEncode(benchmark::State& state) {
  const DepthCodecOptions options = Options(state.range(0) != 0, static_cast<int>(state.range(1)));
  size_t encoded_bytes = 0;
  for (auto _ : state) {
    const absl::StatusOr<std::string> encoded = EncodeDepth(Frame(), options);
    if (!encoded.ok()) {
      state.SkipWithError(std::string(encoded.status().message()).c_str());
      return;
    }
    encoded_bytes = encoded->size();
    benchmark::DoNotOptimize(encoded->data());
  }
  state.counters["ratio"] = RawBytes() / encoded_bytes;
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * RawBytes()));
}
BENCHMARK(BM_RvlEncode)->Args({0, 1})->Args({1, 1})->Args({1, 3})->Unit(benchmark::kMillisecond);

void BM_RvlDecode(benchmark::State& state) {
  const DepthCodecOptions options = Options(state.range(0) != 0, static_cast<int>(state.range(1)));
  const std::string encoded = *EncodeDepth(Frame(), options);
  for (auto _ : state) {
    const absl::StatusOr<DepthImageMm> decoded = DecodeDepth(encoded);
    if (!decoded.ok() || decoded->data != Frame().data) {
      state.SkipWithError("decode mismatch");
      return;
    }
    benchmark::DoNotOptimize(decoded->data.data());
  }
  state.counters["ratio"] = RawBytes() / encoded.size();
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * RawBytes()));
}
BENCHMARK(BM_RvlDecode)->Args({0, 1})->Args({1, 1})->Args({1, 3})->Unit(benchmark::kMillisecond);

// Plain zstd on the raw little-endian pixels, for comparison. Arg: level.
void BM_ZstdEncode(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  std::string compressed(ZSTD_compressBound(static_cast<size_t>(RawBytes())), '\0');
  size_t compressed_bytes = 0;
  for (auto _ : state) {
    compressed_bytes = ZSTD_compress(compressed.data(), compressed.size(), Frame().data.data(),
                                     static_cast<size_t>(RawBytes()), level);
    benchmark::DoNotOptimize(compressed.data());
  }
  if (ZSTD_isError(compressed_bytes)) {
    state.SkipWithError("zstd failed");
    return;
  }
  state.counters["ratio"] = RawBytes() / compressed_bytes;
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * RawBytes()));
}
BENCHMARK(BM_ZstdEncode)->Arg(1)->Arg(3)->Unit(benchmark::kMillisecond);

void BM_ZstdDecode(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  std::string compressed(ZSTD_compressBound(static_cast<size_t>(RawBytes())), '\0');
  compressed.resize(ZSTD_compress(compressed.data(), compressed.size(), Frame().data.data(),
                                  static_cast<size_t>(RawBytes()), level));
  std::vector<uint16_t> decoded(Frame().data.size());
  for (auto _ : state) {
    const size_t bytes = ZSTD_decompress(decoded.data(), decoded.size() * sizeof(uint16_t),
                                         compressed.data(), compressed.size());
    if (ZSTD_isError(bytes)) {
      state.SkipWithError("zstd failed");
      return;
    }
    benchmark::DoNotOptimize(decoded.data());
  }
  state.counters["ratio"] = RawBytes() / compressed.size();
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * RawBytes()));
}
BENCHMARK(BM_ZstdDecode)->Arg(1)->Arg(3)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace reenact

BENCHMARK_MAIN();
