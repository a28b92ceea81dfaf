// Test helpers of reenact_board: the board lying on a floor, rendered through
// common/render from known cameras along a handheld path.
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/board/board_image.h"
#include "common/board/board_spec.h"
#include "common/geometry/camera.h"
#include "common/render/intrinsics_camera.h"
#include "common/render/mesh_data.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::board::testing {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// A phone-like camera filming 1280x720: fx = fy = 1000 px (65 degrees
// across), principal point slightly off centre (OpenCV pixel convention).
inline CameraIntrinsics PhoneIntrinsics() {
  CameraIntrinsics intrinsics;
  intrinsics.width = 1280;
  intrinsics.height = 720;
  intrinsics.fx = 1000.0;
  intrinsics.fy = 1000.0;
  intrinsics.cx = 641.3;
  intrinsics.cy = 357.8;
  return intrinsics;
}

// A camera at `eye_in_world` looking at `target_in_world`, rolled by
// `roll_rad` about its optical axis (OpenCV axes: x right, y down, z forward;
// world +Y up).
inline Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye_in_world,
                                const Eigen::Vector3d& target_in_world, double roll_rad) {
  const Eigen::Vector3d z = (target_in_world - eye_in_world).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  world_from_camera.linear() << x, y, z;
  world_from_camera.linear() =
      world_from_camera.linear() * Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitZ());
  world_from_camera.translation() = eye_in_world;
  return world_from_camera;
}

// A handheld walk around the board: `frames` poses 1.0-2.0 m from its centre,
// 30-65 degrees above it, over 270 degrees of azimuth, aimed within a few
// centimetres of the centre with up to 10 degrees of roll.
inline std::vector<Eigen::Isometry3d> HandheldPath(int frames) {
  std::vector<Eigen::Isometry3d> path;
  for (int i = 0; i < frames; ++i) {
    const double t = frames > 1 ? static_cast<double>(i) / (frames - 1) : 0.0;
    const double azimuth_rad = (-100.0 + 270.0 * t) / kDegPerRad;
    const double distance_m = 1.5 + 0.5 * std::sin(2.0 * std::numbers::pi * 1.5 * t);
    const double elevation_rad = (47.5 + 17.5 * std::cos(2.0 * std::numbers::pi * t)) / kDegPerRad;
    const Eigen::Vector3d eye(distance_m * std::cos(elevation_rad) * std::sin(azimuth_rad),
                              distance_m * std::sin(elevation_rad),
                              distance_m * std::cos(elevation_rad) * std::cos(azimuth_rad));
    const Eigen::Vector3d target(0.05 * std::sin(7.0 * t), 0.0, 0.04 * std::cos(5.0 * t));
    path.push_back(LookAt(eye, target, 0.17 * std::sin(4.0 * t)));
  }
  return path;
}

// Renders the board (printed with a 20 mm white border) on a grey floor.
// With `supersampling` s > 1 each image is drawn at s times the resolution and
// box-filtered down in linear light, like a sensor integrating over its
// pixels; this also undoes most of the blur that the renderer's isotropic
// mipmapping adds to a steeply slanted board.
class BoardScene {
 public:
  static std::unique_ptr<BoardScene> Create(const BoardSpec& spec, int max_width, int max_height,
                                            int supersampling = 1) {
    render::RendererOptions options;
    options.max_width = max_width * supersampling;
    options.max_height = max_height * supersampling;
    options.msaa_samples = supersampling > 1 ? 0 : 4;
    auto renderer = render::OffscreenRenderer::Create(options);
    EXPECT_TRUE(renderer.ok()) << renderer.status();
    auto texture = RenderBoardTexture(spec);
    EXPECT_TRUE(texture.ok()) << texture.status();
    if (!renderer.ok() || !texture.ok()) return nullptr;
    auto scene =
        std::unique_ptr<BoardScene>(new BoardScene(std::move(renderer).value(), supersampling));
    return scene->Upload(*texture) ? std::move(scene) : nullptr;
  }

  // The colour image seen by `camera`, with Gaussian sensor noise of
  // `noise_sigma` grey levels (seeded by `seed`).
  RgbImage Render(const render::RenderCamera& camera, double noise_sigma, unsigned seed) {
    render::RenderCamera fine = camera;
    fine.width *= supersampling_;
    fine.height *= supersampling_;
    fine.fx *= supersampling_;
    fine.fy *= supersampling_;
    fine.cx *= supersampling_;  // Continuous coordinates scale about the image corner.
    fine.cy *= supersampling_;
    render::RenderOutputs out;
    out.requested = render::kRenderColour;
    const absl::Status status = renderer_->Render(fine, items_, &out);
    EXPECT_TRUE(status.ok()) << status;
    RgbImage image = supersampling_ > 1 ? BoxFilter(out.colour, supersampling_) : out.colour;
    std::mt19937 random(seed);
    std::normal_distribution<double> noise(0.0, noise_sigma);
    for (uint8_t& value : image.data) {
      value = static_cast<uint8_t>(std::clamp(std::lround(value + noise(random)), 0L, 255L));
    }
    return image;
  }

 private:
  BoardScene(std::unique_ptr<render::OffscreenRenderer> renderer, int supersampling)
      : renderer_(std::move(renderer)), supersampling_(supersampling) {}

  static double SrgbToLinear(uint8_t value) {
    static const std::vector<double> table = [] {
      std::vector<double> t(256);
      for (int i = 0; i < 256; ++i) {
        const double v = i / 255.0;
        t[i] = v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
      }
      return t;
    }();
    return table[value];
  }
  static uint8_t LinearToSrgb(double v) {
    const double srgb = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
    return static_cast<uint8_t>(std::clamp(std::lround(255.0 * srgb), 0L, 255L));
  }

  // Averages s x s blocks in linear light.
  static RgbImage BoxFilter(const RgbImage& fine, int s) {
    RgbImage coarse(fine.width / s, fine.height / s);
    for (int y = 0; y < coarse.height; ++y) {
      for (int x = 0; x < coarse.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          double sum = 0.0;
          for (int dy = 0; dy < s; ++dy) {
            for (int dx = 0; dx < s; ++dx) sum += SrgbToLinear(fine.at(s * x + dx, s * y + dy, c));
          }
          coarse.at(x, y, c) = LinearToSrgb(sum / (s * s));
        }
      }
    }
    return coarse;
  }

  bool Upload(const BoardTexture& texture) {
    render::ShadingOptions shading;
    shading.background_srgb = {0.25f, 0.27f, 0.3f};
    auto sheet = renderer_->UploadMesh(render::MakeFloorQuad(texture.width_m, texture.depth_m));
    auto floor = renderer_->UploadMesh(render::MakeFloorQuad(8.0, 8.0));
    auto image = renderer_->UploadTexture(texture.image_srgb);
    if (!sheet.ok() || !floor.ok() || !image.ok() || !renderer_->SetShading(shading).ok()) {
      ADD_FAILURE() << "uploading the board scene failed";
      return false;
    }
    render::DrawItem paper;
    paper.mesh = *sheet;
    paper.texture = *image;
    paper.lit = false;
    render::DrawItem ground;
    ground.mesh = *floor;
    ground.colour_srgb = {0.45f, 0.42f, 0.38f};
    ground.lit = false;
    ground.underlay = true;  // The paper wins where both are drawn.
    items_ = {paper, ground};
    return true;
  }

  std::unique_ptr<render::OffscreenRenderer> renderer_;
  int supersampling_ = 1;
  std::vector<render::DrawItem> items_;
};

// Rotation (degrees) and camera-position (millimetres) errors of an estimated
// camera_from_world against the true world_from_camera.
struct PoseError {
  double rotation_deg = 0.0;
  double position_mm = 0.0;
};

inline PoseError ComparePose(const Eigen::Isometry3d& camera_from_world_estimate,
                             const Eigen::Isometry3d& world_from_camera_truth) {
  const Eigen::Isometry3d delta = camera_from_world_estimate * world_from_camera_truth;
  PoseError error;
  error.rotation_deg = Eigen::AngleAxisd(delta.linear()).angle() * kDegPerRad;
  error.position_mm = 1e3 * (camera_from_world_estimate.inverse().translation() -
                             world_from_camera_truth.translation())
                                .norm();
  return error;
}

// Worst and mean of a series of pose errors.
struct PoseErrorStats {
  PoseError worst;
  PoseError mean;
  int count = 0;

  void Add(const PoseError& error) {
    worst.rotation_deg = std::max(worst.rotation_deg, error.rotation_deg);
    worst.position_mm = std::max(worst.position_mm, error.position_mm);
    mean.rotation_deg = (mean.rotation_deg * count + error.rotation_deg) / (count + 1);
    mean.position_mm = (mean.position_mm * count + error.position_mm) / (count + 1);
    ++count;
  }
};

}  // namespace reenact::board::testing
