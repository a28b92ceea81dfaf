#include "common/geometry/umeyama.h"

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace reenact {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct PointPairs {
  std::vector<Eigen::Vector3d> source;
  std::vector<Eigen::Vector3d> target;
};

// Source points spread over a 2 m cube; target = truth * source + N(0, sigma).
PointPairs MakePairs(const Sim3d& target_from_source, int count, double sigma_m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma_m);
  PointPairs pairs;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d source(uniform(rng), uniform(rng), uniform(rng));
    pairs.source.push_back(source);
    pairs.target.push_back(target_from_source * source +
                           Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  return pairs;
}

TEST(FitSimilarityUmeyama, RecoversKnownSimilarityUnderNoise) {
  const Sim3d truth(
      1.25, Eigen::Quaterniond(Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, -2, 0.5).normalized())),
      Eigen::Vector3d(0.4, 1.1, -2.3));
  const PointPairs pairs = MakePairs(truth, 200, 0.002, 7);  // sigma = 2 mm.
  const absl::StatusOr<Sim3d> fit = FitSimilarityUmeyama(pairs.source, pairs.target);
  ASSERT_TRUE(fit.ok()) << fit.status();
  EXPECT_LT(RotationAngleRad(fit->rotation, truth.rotation) * 180.0 / kPi, 0.2);  // Degrees.
  EXPECT_LT((fit->translation - truth.translation).norm(), 0.002);                // Metres.
  EXPECT_NEAR(fit->scale / truth.scale, 1.0, 0.002);                              // 0.2 %.
}

TEST(FitSimilarityUmeyama, ExactOnNoiseFreeData) {
  const Sim3d truth(0.5, Eigen::Quaterniond(Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitY())),
                    Eigen::Vector3d(-1.0, 0.0, 4.0));
  const PointPairs pairs = MakePairs(truth, 10, 0.0, 3);
  const absl::StatusOr<Sim3d> fit = FitSimilarityUmeyama(pairs.source, pairs.target);
  ASSERT_TRUE(fit.ok()) << fit.status();
  EXPECT_LT(RotationAngleRad(fit->rotation, truth.rotation), 1e-9);  // Radians.
  EXPECT_LT((fit->translation - truth.translation).norm(), 1e-9);    // Metres.
  EXPECT_NEAR(fit->scale, truth.scale, 1e-9);
}

TEST(FitSimilarityUmeyama, ReflectedDataStillGivesProperRotation) {
  // Target is a mirror image of the source: the best orthogonal fit is a
  // reflection, which the sign fix must turn into a proper rotation.
  const PointPairs pairs = MakePairs(Sim3d(), 50, 0.0, 11);
  std::vector<Eigen::Vector3d> mirrored = pairs.target;
  for (Eigen::Vector3d& point : mirrored) point.x() = -point.x();
  const absl::StatusOr<Sim3d> fit = FitSimilarityUmeyama(pairs.source, mirrored);
  ASSERT_TRUE(fit.ok()) << fit.status();
  EXPECT_NEAR(fit->rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
}

TEST(FitSimilarityUmeyama, RigidModeKeepsUnitScale) {
  const Sim3d truth(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(0.0, 1.0, 0.0));
  const PointPairs pairs = MakePairs(truth, 30, 0.0, 5);
  UmeyamaOptions options;
  options.estimate_scale = false;
  const absl::StatusOr<Sim3d> fit = FitSimilarityUmeyama(pairs.source, pairs.target, options);
  ASSERT_TRUE(fit.ok()) << fit.status();
  EXPECT_EQ(fit->scale, 1.0);
  EXPECT_LT(RotationAngleRad(fit->rotation, truth.rotation), 1e-9);  // Radians.
}

TEST(FitSimilarityUmeyama, RejectsDegenerateInput) {
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_EQ(FitSimilarityUmeyama(two, two).status().code(), absl::StatusCode::kInvalidArgument);

  std::vector<Eigen::Vector3d> collinear;
  for (int i = 0; i < 10; ++i) collinear.push_back(Eigen::Vector3d(i, 2.0 * i, -i));
  EXPECT_EQ(FitSimilarityUmeyama(collinear, collinear).status().code(),
            absl::StatusCode::kFailedPrecondition);

  const std::vector<Eigen::Vector3d> coincident(5, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(FitSimilarityUmeyama(coincident, collinear).status().code(),
            absl::StatusCode::kInvalidArgument);  // Sizes differ: 5 vs 10.
  EXPECT_EQ(FitSimilarityUmeyama(coincident, coincident).status().code(),
            absl::StatusCode::kFailedPrecondition);

  std::vector<Eigen::Vector3d> with_nan = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const std::vector<Eigen::Vector3d> clean = with_nan;
  with_nan[2].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(FitSimilarityUmeyama(clean, with_nan).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(FitSimilarityUmeyama(clean, clean).ok());
}

}  // namespace
}  // namespace reenact
