#include "server/recon/carving/part_registration.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "server/recon/carving/optical_flow.h"
#include "server/recon/carving/sensor_frame.h"
#include "server/recon/carving/testing/analytic_scenes.h"

namespace reenact::recon::carving {
namespace {

constexpr double kPi = 3.14159265358979323846;
using testing::Box;
using testing::LookAtCamera;
using testing::RenderDepth;
using testing::Sphere;

double DegreesBetween(const Rigid3d& a, const Rigid3d& b) {
  return RotationAngleRad(a.rotation, b.rotation) * 180.0 / kPi;
}

// A known motion of the part: 4 degrees about a tilted axis, 2-3 cm.
Rigid3d TrueDelta() {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(4.0 * kPi / 180.0,
                                                      Eigen::Vector3d(0.3, 1.0, 0.2).normalized())),
                 Eigen::Vector3d(0.015, -0.010, 0.020));
}

// Two sensors facing each other across the origin (as the synthetic takes
// place them), each with its depth images at n-1 and n.
struct TwoSensorScene {
  std::vector<PosedCamera> cameras;
  std::vector<SurfaceMap> before;
  std::vector<SurfaceMap> after;
};

TwoSensorScene RenderScene(const testing::RayCaster& before, const testing::RayCaster& after) {
  TwoSensorScene scene;
  scene.cameras.push_back(LookAtCamera(Eigen::Vector3d(0.3, 0.4, 2.5), Eigen::Vector3d::Zero()));
  scene.cameras.push_back(LookAtCamera(Eigen::Vector3d(-0.3, 0.4, -2.5), Eigen::Vector3d::Zero()));
  for (const PosedCamera& camera : scene.cameras) {
    scene.before.push_back(*BuildSurfaceMap(camera, RenderDepth(camera, before), nullptr));
    scene.after.push_back(*BuildSurfaceMap(camera, RenderDepth(camera, after), nullptr));
  }
  return scene;
}

std::vector<SourcePoint> SourcesOf(const TwoSensorScene& scene) {
  std::vector<SourcePoint> sources;
  for (size_t view = 0; view < scene.before.size(); ++view) {
    const SurfaceMap& map = scene.before[view];
    for (size_t cell = 0; cell < map.points_in_world_m.size(); ++cell) {
      if (!map.HasNormal(cell)) continue;
      SourcePoint source;
      source.point_in_world_m = map.points_in_world_m[cell];
      source.normal_in_world = map.normals_in_world[cell];
      source.view = static_cast<int>(view);
      source.weight = static_cast<float>(map.step * map.step);
      sources.push_back(source);
    }
  }
  return sources;
}

std::vector<RegistrationView> ViewsOf(const TwoSensorScene& scene) {
  std::vector<RegistrationView> views;
  for (size_t i = 0; i < scene.cameras.size(); ++i) {
    views.push_back({&scene.cameras[i], &scene.after[i]});
  }
  return views;
}

const Eigen::Vector3d kBoxHalf(0.15, 0.25, 0.10);
const Rigid3d kBoxPose(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()) *
                                          Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitX())),
                       Eigen::Vector3d(0.02, 0.05, -0.03));

TEST(RegisterPart, PointToPlaneRecoversABoxMotion) {
  const Rigid3d truth = TrueDelta();
  const TwoSensorScene scene =
      RenderScene(Box(kBoxHalf, kBoxPose), Box(kBoxHalf, truth * kBoxPose));
  PartRegistrationOptions options;
  options.w_o = 0.0;
  options.w_s = 0.0;
  absl::StatusOr<PartRegistrationSummary> summary =
      RegisterPart(SourcesOf(scene), ViewsOf(scene), {}, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_TRUE(summary->solved);
  EXPECT_GT(summary->plane_pairs, 1500);
  const Eigen::Vector3d centre = kBoxPose.translation;
  const double error_mm = ((summary->delta * centre) - (truth * centre)).norm() * 1000.0;
  const double error_deg = DegreesBetween(summary->delta, truth);
  RecordProperty("box_centre_error_um", static_cast<int>(error_mm * 1000.0));
  RecordProperty("rotation_error_millideg", static_cast<int>(error_deg * 1000.0));
  RecordProperty("iterations", summary->iterations);
  EXPECT_LT(error_mm, 1.0) << "box centre error, mm";
  EXPECT_LT(error_deg, 0.5);
  EXPECT_LT(summary->plane_rms_m, 0.002);
  EXPECT_LE(summary->iterations, options.max_iterations);
  // Without registration the box centre would be off by the whole motion.
  EXPECT_GT(((truth * centre) - centre).norm() * 1000.0, 20.0);
}

TEST(RegisterPart, SkeletonTermAlonePullsToTheSkeletonTransform) {
  const Rigid3d truth = TrueDelta();
  // Proximal joint, distal joint and an axis point of a 30 cm forearm.
  const std::vector<Eigen::Vector3d> part_points = {Eigen::Vector3d(0.1, 1.0, 0.0),
                                                    Eigen::Vector3d(0.1, 0.7, 0.05),
                                                    Eigen::Vector3d(0.2, 1.0, 0.0)};
  std::vector<SkeletonAnchor> anchors;
  for (const Eigen::Vector3d& p : part_points) anchors.push_back({p, truth * p, 1.0});
  PartRegistrationOptions options;
  options.w_s = 5.0;
  absl::StatusOr<PartRegistrationSummary> summary = RegisterPart({}, {}, anchors, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_TRUE(summary->converged);
  EXPECT_LT(DegreesBetween(summary->delta, truth), 1e-4);
  EXPECT_LT((summary->delta.translation - truth.translation).norm(), 1e-7);
}

TEST(RegisterPart, SkeletonTermFixesWhatASphereLeavesOpen) {
  // A sphere's surface fixes its centre but not its spin: point-to-plane
  // pulls the centre, the (deliberately offset) anchors set the rotation.
  const Eigen::Vector3d centre(0.0, 0.1, 0.0);
  const Rigid3d truth = TrueDelta();
  const TwoSensorScene scene = RenderScene(Sphere(centre, 0.12), Sphere(truth * centre, 0.12));
  std::vector<SkeletonAnchor> anchors;
  for (const Eigen::Vector3d& offset :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0.2, 0), Eigen::Vector3d(0.1, 0, 0)}) {
    anchors.push_back({centre + offset, truth * (centre + offset), 1.0});
  }
  PartRegistrationOptions options;
  options.w_o = 0.0;
  options.w_s = 1000.0;
  absl::StatusOr<PartRegistrationSummary> summary =
      RegisterPart(SourcesOf(scene), ViewsOf(scene), anchors, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_LT(((summary->delta * centre) - (truth * centre)).norm() * 1000.0, 1.0);
  EXPECT_LT(DegreesBetween(summary->delta, truth), 0.5);
}

TEST(RegisterPart, PointToPointTermRecoversTheMotionFromFlowTargets) {
  // Flow targets that are exact (the moved point itself, rounded to the
  // depth grid by taking the nearest D_n point) determine rotation too.
  const Eigen::Vector3d centre(0.0, 0.1, 0.0);
  const Rigid3d truth = TrueDelta();
  const TwoSensorScene scene = RenderScene(Sphere(centre, 0.12), Sphere(truth * centre, 0.12));
  std::vector<SourcePoint> sources = SourcesOf(scene);
  for (SourcePoint& source : sources) {
    source.has_flow_target = true;
    source.flow_target_in_world_m = (truth * source.point_in_world_m.cast<double>()).cast<float>();
  }
  PartRegistrationOptions options;
  options.w_o = 1.0;
  options.w_s = 0.0;
  absl::StatusOr<PartRegistrationSummary> summary =
      RegisterPart(sources, ViewsOf(scene), {}, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_GT(summary->flow_pairs, 300);
  EXPECT_LT(((summary->delta * centre) - (truth * centre)).norm() * 1000.0, 1.0);
  EXPECT_LT(DegreesBetween(summary->delta, truth), 0.5);
}

TEST(RegisterPart, NoDataIsNotSolved) {
  absl::StatusOr<PartRegistrationSummary> summary =
      RegisterPart({}, {}, {}, PartRegistrationOptions());
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_FALSE(summary->solved);
  EXPECT_EQ(summary->iterations, 0);
}

TEST(RegisterPart, RejectsBadOptions) {
  PartRegistrationOptions options;
  options.w_o = -1.0;
  EXPECT_EQ(RegisterPart({}, {}, {}, options).status().code(), absl::StatusCode::kInvalidArgument);
  options = PartRegistrationOptions();
  options.max_iterations = 0;
  EXPECT_EQ(RegisterPart({}, {}, {}, options).status().code(), absl::StatusCode::kInvalidArgument);
  options = PartRegistrationOptions();
  options.max_pair_distance_m = 0.0;
  EXPECT_EQ(RegisterPart({}, {}, {}, options).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(SurfaceMap, PointsAndNormalsOfAPlaneFacingTheCamera) {
  const PosedCamera camera = LookAtCamera(Eigen::Vector3d(0, 0, 2.0), Eigen::Vector3d::Zero());
  // A large thin box: its +Z face is the plane z = 0 facing the camera.
  const DepthImageMm depth = RenderDepth(
      camera, Box(Eigen::Vector3d(2, 2, 0.01),
                  Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -0.01))));
  absl::StatusOr<SurfaceMap> map = BuildSurfaceMap(camera, depth, nullptr);
  ASSERT_TRUE(map.ok()) << map.status();
  int normals = 0;
  double worst_z_m = 0.0;
  double worst_normal = 0.0;
  for (size_t cell = 0; cell < map->points_in_world_m.size(); ++cell) {
    if (!map->HasNormal(cell)) continue;
    ++normals;
    worst_z_m = std::max(worst_z_m, std::abs(double{map->points_in_world_m[cell].z()}));
    worst_normal = std::max(worst_normal, 1.0 - map->normals_in_world[cell].z());
  }
  EXPECT_GT(normals, 50000);
  EXPECT_LT(worst_z_m, 0.002);  // Depth is rounded to millimetres.
  EXPECT_LT(worst_normal, 0.01);
  EXPECT_FALSE(BuildSurfaceMap(camera, DepthImageMm(10, 10), nullptr).ok());
}

TEST(RemoveDepthEdges, DropsFlyingPixelsAndKeepsSurfaces) {
  // A slanted plane (2 mm per pixel) with a foreground square 400 mm nearer
  // and one flying pixel halfway between.
  DepthImageMm depth(40, 30);
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) {
      depth.at(x, y) = static_cast<uint16_t>(2000 + 2 * x);
      if (x >= 10 && x < 20 && y >= 10 && y < 20) depth.at(x, y) = 1600;
    }
  }
  depth.at(20, 15) = 1800;  // Flying pixel beside the square.
  depth.at(5, 5) = 0;       // No measurement: not an edge.
  RemoveDepthEdges(30, &depth);
  EXPECT_EQ(depth.at(20, 15), 0);
  EXPECT_EQ(depth.at(15, 15), 1600);  // Inside the square.
  EXPECT_EQ(depth.at(10, 15), 0);     // Its border (next to the plane).
  EXPECT_EQ(depth.at(9, 15), 0);      // The plane beside it.
  EXPECT_EQ(depth.at(30, 25), 2060);  // Plane far from edges.
  EXPECT_EQ(depth.at(4, 5), 2008);    // Next to the hole.
  DepthImageMm unchanged = depth;
  RemoveDepthEdges(0, &unchanged);
  EXPECT_EQ(unchanged, depth);
}

TEST(OpticalFlow, RecoversAShiftOfATexture) {
  std::mt19937 random(3);
  std::uniform_int_distribution<int> value(0, 255);
  RgbImage noise(200, 120);
  for (uint8_t& v : noise.data) v = static_cast<uint8_t>(value(random));
  absl::StatusOr<GreyImage> base = GreyAtSize(noise, 200, 120);
  ASSERT_TRUE(base.ok()) << base.status();
  // Smooth blobs: downscale then shift by (3, -2) pixels.
  GreyImage a(160, 90);
  GreyImage b(160, 90);
  for (int y = 0; y < 90; ++y) {
    for (int x = 0; x < 160; ++x) {
      auto sample = [&](int sx, int sy) {
        int sum = 0;
        for (int dy = 0; dy < 3; ++dy) {
          for (int dx = 0; dx < 3; ++dx) {
            sum += base->at(std::clamp(sx + dx, 0, 199), std::clamp(sy + dy, 0, 119));
          }
        }
        return static_cast<uint8_t>(sum / 9);
      };
      a.at(x, y) = sample(x + 10, y + 10);
      b.at(x, y) = sample(x + 10 - 3, y + 10 + 2);
    }
  }
  absl::StatusOr<FlowField> flow = ComputeOpticalFlow(a, b);
  ASSERT_TRUE(flow.ok()) << flow.status();
  std::vector<float> dx;
  std::vector<float> dy;
  for (int y = 20; y < 70; ++y) {
    for (int x = 20; x < 140; ++x) {
      dx.push_back(flow->at(x, y, 0));
      dy.push_back(flow->at(x, y, 1));
    }
  }
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  EXPECT_NEAR(dx[dx.size() / 2], 3.0, 0.3);
  EXPECT_NEAR(dy[dy.size() / 2], -2.0, 0.3);
  EXPECT_FALSE(ComputeOpticalFlow(a, GreyImage(10, 10)).ok());

  // The same on a crop: NaN outside, the shift inside.
  absl::StatusOr<FlowField> cropped = ComputeOpticalFlow(a, b, {}, PixelBox{30, 20, 130, 75});
  ASSERT_TRUE(cropped.ok()) << cropped.status();
  EXPECT_TRUE(std::isnan(cropped->at(10, 10, 0)));
  EXPECT_TRUE(std::isnan(cropped->at(140, 80, 1)));
  EXPECT_NEAR(cropped->at(80, 45, 0), 3.0, 0.3);
  EXPECT_NEAR(cropped->at(80, 45, 1), -2.0, 0.3);
}

TEST(OpticalFlow, FlowTargetsOfAStillSceneAreThePointsThemselves) {
  const PosedCamera depth_camera =
      LookAtCamera(Eigen::Vector3d(0.3, 0.4, 2.5), Eigen::Vector3d::Zero());
  // The colour camera: the same pose, a quarter of the resolution, no distortion.
  CameraIntrinsics color;
  color.width = 160;
  color.height = 90;
  color.fx = color.fy = 120.0;
  color.cx = 79.5;
  color.cy = 44.5;
  const PosedCamera color_camera = *PosedCamera::Create(color, depth_camera.world_from_camera());
  const SurfaceMap surface =
      *BuildSurfaceMap(depth_camera, RenderDepth(depth_camera, Box(kBoxHalf, kBoxPose)), nullptr);
  const ColorLookup lookup = BuildColorLookup(surface, color_camera);
  const FlowField still(160, 90, 0.0f);
  absl::StatusOr<std::vector<int32_t>> targets =
      FlowTargets(surface, color_camera, lookup, still, lookup);
  ASSERT_TRUE(targets.ok()) << targets.status();
  int matched = 0;
  int points = 0;
  double worst_m = 0.0;
  for (size_t cell = 0; cell < targets->size(); ++cell) {
    points += surface.HasPoint(cell) ? 1 : 0;
    if ((*targets)[cell] < 0) continue;
    ++matched;
    worst_m = std::max(worst_m, double{(surface.points_in_world_m[cell] -
                                        surface.points_in_world_m[(*targets)[cell]])
                                           .norm()});
  }
  EXPECT_GT(matched, 0.5 * points) << "of " << points;
  // A colour pixel (1/4 resolution) covers about 2 cm at 2.5 m.
  EXPECT_LT(worst_m, 0.04);
  EXPECT_FALSE(FlowTargets(surface, color_camera, lookup, FlowField(3, 3), lookup).ok());
}

}  // namespace
}  // namespace reenact::recon::carving
