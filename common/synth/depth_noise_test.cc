#include "common/synth/depth_noise.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>

#include <gtest/gtest.h>

namespace reenact::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Ideal depth (m) of every pixel from `depth_at(x, y)`, 0 where it returns <= 0.
FloatImage MakeDepth(const CameraIntrinsics& k, const std::function<double(int, int)>& depth_at) {
  FloatImage depth(k.width, k.height);
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x)
      depth.at(x, y) = static_cast<float>(std::max(0.0, depth_at(x, y)));
  }
  return depth;
}

FloatImage FrontoParallel(const CameraIntrinsics& k, double z_m) {
  return MakeDepth(k, [z_m](int, int) { return z_m; });
}

// Fraction (%) of pixels in the central `half` x `half` window that are 0.
double InvalidPercentNearCentre(const DepthImageMm& depth, int half) {
  int invalid = 0, total = 0;
  for (int y = depth.height / 2 - half; y < depth.height / 2 + half; ++y) {
    for (int x = depth.width / 2 - half; x < depth.width / 2 + half; ++x, ++total) {
      if (depth.at(x, y) == 0) ++invalid;
    }
  }
  return 100.0 * invalid / total;
}

TEST(KinectV2AxialSigmaMm, MatchesPublishedModel) {
  // sigma_z = 1.5 - 0.5 z + 0.3 z^2 (mm) at normal incidence.
  EXPECT_NEAR(KinectV2AxialSigmaMm(1.0, 0.0), 1.3, 1e-9);    // mm
  EXPECT_NEAR(KinectV2AxialSigmaMm(2.5, 0.0), 2.125, 1e-9);  // mm
  EXPECT_NEAR(KinectV2AxialSigmaMm(4.0, 0.0), 4.3, 1e-9);    // mm
  // The incidence term at 60 degrees: 0.1 z^1.5 theta^2 / (pi/2 - theta)^2 = 0.4 z^1.5.
  EXPECT_NEAR(KinectV2AxialSigmaMm(2.0, kPi / 3) - KinectV2AxialSigmaMm(2.0, 0.0),
              0.4 * std::pow(2.0, 1.5), 1e-9);  // mm
}

TEST(KinectV2AxialSigmaMm, GrowsWithIncidence) {
  double previous = KinectV2AxialSigmaMm(2.0, 0.0);
  for (double deg = 10; deg <= 80; deg += 10) {
    const double sigma = KinectV2AxialSigmaMm(2.0, deg * kPi / 180);
    EXPECT_GT(sigma, previous) << deg << " degrees";
    previous = sigma;
  }
}

TEST(ApplyKinectV2DepthNoise, FrontoParallelPlaneHasModelSigma) {
  const CameraIntrinsics k = KinectV2DepthIntrinsics();
  DepthNoiseOptions options;
  options.sigma_lateral_px = 0.0;
  const DepthImageMm noisy = ApplyKinectV2DepthNoise(FrontoParallel(k, 2.0), k, options, 11);
  // Central 100x100 px: incidence under 11 degrees, where the model's
  // incidence term adds less than 0.01 mm.
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  for (int y = k.height / 2 - 50; y < k.height / 2 + 50; ++y) {
    for (int x = k.width / 2 - 50; x < k.width / 2 + 50; ++x, ++n) {
      ASSERT_NE(noisy.at(x, y), 0);
      const double e = noisy.at(x, y) - 2000.0;
      sum += e;
      sum_sq += e * e;
    }
  }
  const double mean = sum / n;
  const double std_mm = std::sqrt(sum_sq / n - mean * mean);
  const double model = KinectV2AxialSigmaMm(2.0, 0.0);
  std::cout << "plane at 2 m: std " << std_mm << " mm, model " << model << " mm, mean " << mean
            << " mm\n";
  EXPECT_NEAR(std_mm, model, 0.15 * model);  // mm (15 %)
  EXPECT_NEAR(mean, 0.0, 0.1);               // mm
}

TEST(ApplyKinectV2DepthNoise, OutOfRangeIsInvalid) {
  const CameraIntrinsics k = KinectV2DepthIntrinsics();
  const DepthNoiseOptions options;
  for (double z_m : {0.4, 4.7}) {
    const DepthImageMm noisy = ApplyKinectV2DepthNoise(FrontoParallel(k, z_m), k, options, 5);
    EXPECT_NEAR(InvalidPercentNearCentre(noisy, 100), 100.0, 1e-9) << z_m << " m";
  }
  const DepthImageMm inside = ApplyKinectV2DepthNoise(FrontoParallel(k, 3.0), k, options, 5);
  EXPECT_LT(InvalidPercentNearCentre(inside, 100), 1.0) << "3 m";  // %
}

TEST(ApplyKinectV2DepthNoise, GrazingPlaneIsMostlyInvalid) {
  const CameraIntrinsics k = KinectV2DepthIntrinsics();
  // A plane through (0, 0, z0) whose normal leans `tilt` from the optical
  // axis about the camera's y axis: incidence near the centre equals `tilt`.
  auto plane = [&k](double z0, double tilt_deg) {
    const double t = tilt_deg * kPi / 180;
    return MakeDepth(k, [&k, z0, t](int x, int) {
      const double xn = (x - k.cx) / k.fx;
      const double denominator = std::sin(t) * xn + std::cos(t);
      return denominator > 0 ? z0 * std::cos(t) / denominator : 0.0;
    });
  };
  DepthNoiseOptions options;
  options.flying_pixel_probability = 0.0;  // Isolate the incidence limit.
  options.sigma_lateral_px = 0.0;
  // At 1 m the per-pixel depth step of an 85 degree plane (~31 mm) stays
  // under edge_jump_m; at 2.5 m it exceeds it (~68 mm), so the estimate must
  // still tell a steep surface from a silhouette.
  for (const double z0 : {1.0, 2.5}) {
    const DepthImageMm grazing = ApplyKinectV2DepthNoise(plane(z0, 85.0), k, options, 3);
    const DepthImageMm oblique = ApplyKinectV2DepthNoise(plane(z0, 45.0), k, options, 3);
    const double grazing_invalid = InvalidPercentNearCentre(grazing, 5);
    const double oblique_invalid = InvalidPercentNearCentre(oblique, 5);
    std::cout << "at " << z0 << " m, invalid near the centre: 85 degrees " << grazing_invalid
              << " %, 45 degrees " << oblique_invalid << " %\n";
    EXPECT_GT(grazing_invalid, 90.0) << "at " << z0 << " m";  // %
    EXPECT_LT(oblique_invalid, 5.0) << "at " << z0 << " m";   // %
  }
}

TEST(ApplyKinectV2DepthNoise, FlyingPixelsOnlyWhenEnabled) {
  const CameraIntrinsics k = KinectV2DepthIntrinsics();
  // A step: near plane (1.5 m) on the left half, far plane (2.5 m) on the right.
  const FloatImage step = MakeDepth(k, [&k](int x, int) { return x < k.width / 2 ? 1.5 : 2.5; });
  auto count_between = [&](double probability) {
    DepthNoiseOptions options;
    options.flying_pixel_probability = probability;
    const DepthImageMm noisy = ApplyKinectV2DepthNoise(step, k, options, 21);
    int between = 0;
    for (uint16_t d : noisy.data) between += (d > 1550 && d < 2450) ? 1 : 0;
    return between;
  };
  const int always = count_between(1.0);
  const int never = count_between(0.0);
  std::cout << "pixels between the two depths: " << always << " (probability 1), " << never
            << " (probability 0) of " << k.height << " rows\n";
  EXPECT_GT(always, k.height / 2);
  EXPECT_EQ(never, 0);
}

TEST(ApplyKinectV2DepthNoise, DeterministicForSeed) {
  const CameraIntrinsics k = KinectV2DepthIntrinsics();
  const DepthNoiseOptions options;
  const FloatImage plane = FrontoParallel(k, 2.0);
  const DepthImageMm a = ApplyKinectV2DepthNoise(plane, k, options, 42);
  const DepthImageMm b = ApplyKinectV2DepthNoise(plane, k, options, 42);
  const DepthImageMm c = ApplyKinectV2DepthNoise(plane, k, options, 43);
  int differ_same = 0, differ_other = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    differ_same += a.data[i] != b.data[i];
    differ_other += a.data[i] != c.data[i];
  }
  EXPECT_EQ(differ_same, 0);
  EXPECT_GT(100.0 * differ_other / a.data.size(), 10.0);  // % of pixels
}

TEST(DepthNoiseOptions, ValidateRejectsBadOptions) {
  EXPECT_TRUE(DepthNoiseOptions{}.Validate().ok());
  auto bad = [](const std::function<void(DepthNoiseOptions*)>& change) {
    DepthNoiseOptions options;
    change(&options);
    return options.Validate().code() == absl::StatusCode::kInvalidArgument;
  };
  EXPECT_TRUE(bad([](auto* o) { o->min_range_m = 0.0; }));
  EXPECT_TRUE(bad([](auto* o) { o->max_range_m = 0.4; }));
  EXPECT_TRUE(bad([](auto* o) { o->max_incidence_deg = 95.0; }));
  EXPECT_TRUE(bad([](auto* o) { o->sigma_lateral_px = -1.0; }));
  EXPECT_TRUE(bad([](auto* o) { o->edge_jump_m = 0.0; }));
  EXPECT_TRUE(bad([](auto* o) { o->flying_pixel_probability = 1.5; }));
  EXPECT_TRUE(bad([](auto* o) { o->axial_noise_scale = -0.1; }));
}

}  // namespace
}  // namespace reenact::synth
