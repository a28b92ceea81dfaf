#include "server/recon/carving/tsdf.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "server/recon/carving/marching_cubes.h"
#include "server/recon/carving/testing/analytic_scenes.h"

namespace reenact::recon::carving {
namespace {

constexpr double kPi = 3.14159265358979323846;
using testing::Box;
using testing::LookAtCamera;
using testing::RenderDepth;
using testing::Sphere;
using testing::Union;

// Four sensors round the origin at 2.5 m, 0.6 m up, looking at the origin.
std::vector<PosedCamera> RingOfCameras() {
  std::vector<PosedCamera> cameras;
  for (int i = 0; i < 4; ++i) {
    const double angle = 2.0 * kPi * i / 4 + 0.3;
    cameras.push_back(
        LookAtCamera(Eigen::Vector3d(2.5 * std::sin(angle), 0.6, 2.5 * std::cos(angle)),
                     Eigen::Vector3d::Zero()));
  }
  return cameras;
}

// The floor under the shapes, so that free space below them is carved.
testing::RayCaster Floor() {
  return Box(Eigen::Vector3d(3, 0.05, 3),
             Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, -0.45, 0)));
}

TEST(VolumeBox, BoneBoxCoversTheBoneAndValidates) {
  const VolumeBox box = BoneBox(-0.04, 0.34, 0.06, 0.008);
  ASSERT_TRUE(box.Validate().ok());
  EXPECT_TRUE(box.Contains(Eigen::Vector3d(0, 0, 0)));
  EXPECT_TRUE(box.Contains(Eigen::Vector3d(0.059, 0.339, -0.059)));
  EXPECT_TRUE(box.Contains(Eigen::Vector3d(0, -0.039, 0)));
  EXPECT_FALSE(box.Contains(Eigen::Vector3d(0.0, -0.06, 0)));
  EXPECT_FALSE(box.Contains(Eigen::Vector3d(0.08, 0.1, 0)));
  VolumeBox bad = box;
  bad.nx = 0;
  EXPECT_FALSE(bad.Validate().ok());
  EXPECT_FALSE(TsdfVolume::Create(box, 0.0).ok());
}

// 21 voxels of 1 cm along the Z axis from z = -0.1 to z = +0.1.
VolumeBox AxisColumn() {
  VolumeBox box;
  box.voxel_m = 0.01;
  box.nx = box.ny = 1;
  box.nz = 21;
  box.min_corner_in_part_m = Eigen::Vector3d(0, 0, -0.1);
  return box;
}

TEST(TsdfVolume, TruncationFollowsEq311) {
  // One camera looking down -Z at a wall at z = 0 (2 m away).
  const PosedCamera camera = LookAtCamera(Eigen::Vector3d(0, 0, 2.0), Eigen::Vector3d::Zero());
  const DepthImageMm depth = RenderDepth(
      camera, Box(Eigen::Vector3d(3, 3, 0.5),
                  Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -0.5))));
  // A column of voxels along the optical axis from z = +0.1 to z = -0.1.
  const VolumeBox box = AxisColumn();
  const double mu = 0.03;
  absl::StatusOr<TsdfVolume> volume = TsdfVolume::Create(box, mu);
  ASSERT_TRUE(volume.ok()) << volume.status();
  ASSERT_TRUE(volume->Integrate(camera, depth, Rigid3d()).ok());
  ASSERT_TRUE(volume->Integrate(camera, depth, Rigid3d()).ok());
  for (int k = 0; k < box.nz; ++k) {
    const double z = -0.1 + 0.01 * k;  // Voxel z; the wall is at 0, the camera at +2.
    const double eta = z;              // Observed depth minus voxel depth.
    if (eta < -mu - 1e-3) {
      EXPECT_EQ(volume->count(0, 0, k), 0) << "z " << z;  // Ignored, not in N*.
    } else if (eta >= mu + 1e-3) {
      EXPECT_EQ(volume->count(0, 0, k), 2) << "z " << z;
      EXPECT_FLOAT_EQ(volume->value(0, 0, k), static_cast<float>(mu)) << "z " << z;
    } else if (std::abs(eta) < mu - 1e-3) {
      EXPECT_EQ(volume->count(0, 0, k), 2) << "z " << z;
      EXPECT_NEAR(volume->value(0, 0, k), eta, 0.0011) << "z " << z;
    }
  }
  EXPECT_FALSE(volume->Integrate(camera, DepthImageMm(4, 4), Rigid3d()).ok());
}

TEST(TsdfVolume, RaysWithoutAReturnAreFreeOnlyAsFarAsTheSensorReaches) {
  // A camera at z = +2 looking down -Z, every pixel marked as a free ray,
  // and a column of voxels from 1.9 m to 2.1 m in front of it.
  const PosedCamera camera = LookAtCamera(Eigen::Vector3d(0, 0, 2.0), Eigen::Vector3d::Zero());
  DepthImageMm free(camera.width(), camera.height());
  std::fill(free.data.begin(), free.data.end(), kFreeRayMm);
  const VolumeBox box = AxisColumn();
  const double mu = 0.03;
  absl::StatusOr<TsdfVolume> volume = TsdfVolume::Create(box, mu);
  ASSERT_TRUE(volume.ok()) << volume.status();
  // Reaching 2 m: the voxels nearer than 2 m are free, those beyond unseen.
  ASSERT_TRUE(volume->Integrate(camera, free, Rigid3d(), nullptr, 2.0f).ok());
  for (int k = 0; k < box.nz; ++k) {
    const double depth_m = 2.0 - (-0.1 + 0.01 * k);  // From the camera.
    if (depth_m < 2.0 - 1e-3) {
      EXPECT_EQ(volume->count(0, 0, k), 1) << "depth " << depth_m;
      EXPECT_FLOAT_EQ(volume->value(0, 0, k), static_cast<float>(mu)) << "depth " << depth_m;
    } else if (depth_m > 2.0 + 1e-3) {
      EXPECT_EQ(volume->count(0, 0, k), 0) << "depth " << depth_m;
    }
  }
  // With no bound the whole ray is free.
  ASSERT_TRUE(volume->Integrate(camera, free, Rigid3d()).ok());
  EXPECT_EQ(volume->count(0, 0, 0), 1);
  EXPECT_EQ(volume->count(0, 0, box.nz - 1), 2);
}

// Fuses a box moving through several poses (each depth image integrated
// with the part transform of its instant) and meshes it: the mesh, in the
// part frame, is the box.
TEST(TsdfVolume, FusedMovingBoxMeshesToTheBoxInThePartFrame) {
  const Eigen::Vector3d half(0.09, 0.16, 0.06);
  const std::vector<PosedCamera> cameras = RingOfCameras();
  const VolumeBox box = [] {
    VolumeBox b;
    b.voxel_m = 0.008;
    b.nx = b.ny = b.nz = 51;
    b.min_corner_in_part_m = Eigen::Vector3d::Constant(-0.2);
    return b;
  }();
  absl::StatusOr<TsdfVolume> volume = TsdfVolume::Create(box, 0.02);
  ASSERT_TRUE(volume.ok()) << volume.status();
  for (int n = 0; n < 5; ++n) {
    const Rigid3d world_from_part(Eigen::Quaterniond(Eigen::AngleAxisd(
                                      0.25 * n, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())),
                                  Eigen::Vector3d(0.03 * n, 0.02 * n, -0.02 * n));
    const testing::RayCaster scene = Union({Box(half, world_from_part), Floor()});
    for (const PosedCamera& camera : cameras) {
      ASSERT_TRUE(volume->Integrate(camera, RenderDepth(camera, scene), world_from_part).ok());
    }
  }
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(volume->ToSdfGrid());
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_GT(mesh->num_triangles(), 500);
  // Distance of each vertex to the box surface (part frame).
  double sum_mm = 0.0;
  double worst_mm = 0.0;
  for (const Eigen::Vector3f& p : mesh->positions_m) {
    const Eigen::Vector3d q = p.cast<double>().cwiseAbs() - half;
    const double outside = q.cwiseMax(0.0).norm();
    const double inside = std::min(q.maxCoeff(), 0.0);
    const double distance_mm = std::abs(outside + inside) * 1000.0;
    sum_mm += distance_mm;
    worst_mm = std::max(worst_mm, distance_mm);
  }
  const double mean_mm = sum_mm / mesh->positions_m.size();
  RecordProperty("mean_distance_um", static_cast<int>(mean_mm * 1000.0));
  RecordProperty("worst_distance_um", static_cast<int>(worst_mm * 1000.0));
  RecordProperty("volume_ratio_permille",
                 static_cast<int>(1000.0 * EnclosedVolume(*mesh) / (8.0 * half.prod())));
  EXPECT_LT(mean_mm, 2.0) << "mean vertex distance to the box";
  EXPECT_LT(worst_mm, 10.0);
  // Averaging Eq. 3.10 lets a free-space value from a view that sees a voxel
  // just off the silhouette outweigh the small negative values of the other
  // views, which rounds edges and erodes the box by a few millimetres.
  const double volume_ratio = EnclosedVolume(*mesh) / (8.0 * half.prod());
  EXPECT_GT(volume_ratio, 0.75);
  EXPECT_LT(volume_ratio, 1.02);
}

// The same fusion with wrong part transforms (the motion not compensated)
// smears the box: the test above can fail.
TEST(TsdfVolume, UncompensatedMotionSmearsTheShape) {
  const Eigen::Vector3d half(0.09, 0.16, 0.06);
  const std::vector<PosedCamera> cameras = RingOfCameras();
  VolumeBox box;
  box.voxel_m = 0.008;
  box.nx = box.ny = box.nz = 51;
  box.min_corner_in_part_m = Eigen::Vector3d::Constant(-0.2);
  absl::StatusOr<TsdfVolume> volume = TsdfVolume::Create(box, 0.02);
  ASSERT_TRUE(volume.ok());
  for (int n = 0; n < 5; ++n) {
    const Rigid3d world_from_part(Eigen::Quaterniond(Eigen::AngleAxisd(
                                      0.25 * n, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())),
                                  Eigen::Vector3d(0.03 * n, 0.02 * n, -0.02 * n));
    const testing::RayCaster scene = Union({Box(half, world_from_part), Floor()});
    for (const PosedCamera& camera : cameras) {
      ASSERT_TRUE(volume->Integrate(camera, RenderDepth(camera, scene), Rigid3d()).ok());
    }
  }
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(volume->ToSdfGrid());
  ASSERT_TRUE(mesh.ok());
  double sum_mm = 0.0;
  for (const Eigen::Vector3f& p : mesh->positions_m) {
    const Eigen::Vector3d q = p.cast<double>().cwiseAbs() - half;
    sum_mm += std::abs(q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0)) * 1000.0;
  }
  EXPECT_GT(sum_mm / std::max<size_t>(1, mesh->positions_m.size()), 4.0);
}

TEST(TsdfVolume, OwnershipKeepsOtherPartsSurfacesOut) {
  const PosedCamera camera = LookAtCamera(Eigen::Vector3d(0, 0, 2.0), Eigen::Vector3d::Zero());
  const DepthImageMm depth = RenderDepth(
      camera, Box(Eigen::Vector3d(3, 3, 0.5),
                  Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -0.5))));
  VolumeBox box;
  box.voxel_m = 0.01;
  box.nx = box.ny = 1;
  box.nz = 21;
  box.min_corner_in_part_m = Eigen::Vector3d(0, 0, -0.1);
  // Every pixel belongs to label 2; the volume accepts label 1 only.
  MaskImage labels(256, 212, 2);
  SurfaceOwnership ownership;
  ownership.labels = &labels;
  ownership.step = 2;
  ownership.accepted[1] = true;
  absl::StatusOr<TsdfVolume> volume = TsdfVolume::Create(box, 0.03);
  ASSERT_TRUE(volume.ok());
  ASSERT_TRUE(volume->Integrate(camera, depth, Rigid3d(), &ownership).ok());
  EXPECT_EQ(volume->count(0, 0, 10), 0);  // At the wall: another part's surface.
  EXPECT_EQ(volume->count(0, 0, 20), 1);  // 10 cm in front: free space counts.
  ownership.accepted[2] = true;
  ASSERT_TRUE(volume->Integrate(camera, depth, Rigid3d(), &ownership).ok());
  EXPECT_EQ(volume->count(0, 0, 10), 1);
  // Unlabelled pixels (0) follow accepted[0] like any other label.
  MaskImage unlabelled(256, 212, 0);
  ownership.labels = &unlabelled;
  ASSERT_TRUE(volume->Integrate(camera, depth, Rigid3d(), &ownership).ok());
  EXPECT_EQ(volume->count(0, 0, 10), 1);
  EXPECT_EQ(volume->count(0, 0, 20), 3);
  MaskImage small(10, 10, 0);
  ownership.labels = &small;
  EXPECT_FALSE(volume->Integrate(camera, depth, Rigid3d(), &ownership).ok());
}

}  // namespace
}  // namespace reenact::recon::carving
