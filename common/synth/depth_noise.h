// A Kinect v2 (time-of-flight) depth noise model for synthetic takes.
//
// Axial noise follows the empirical model of Fankhauser, Bloesch, Rodriguez,
// Kaestner, Hutter and Siegwart, "Kinect v2 for Mobile Robot Navigation:
// Evaluation and Modeling", ICAR 2015:
//   sigma_z(z, theta) = 1.5 - 0.5 z + 0.3 z^2 + 0.1 z^1.5 theta^2 / (pi/2 - theta)^2   [mm]
// with z the distance in metres and theta the incidence angle between the
// surface normal and the viewing ray. The same study finds lateral noise
// roughly constant in the image (about a pixel or less), which we model as a
// Gaussian jitter of the sampling position with sigma_lateral_px.
// Time-of-flight pixels that straddle a depth discontinuity mix the returns of
// both surfaces ("flying pixels"); we place such pixels at a random depth
// between foreground and background. Pixels outside the 0.5-4.5 m operating
// range, or seen at grazing incidence, are invalid (0), as the sensor reports.
#pragma once

#include <cstdint>

#include "absl/status/status.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"

namespace reenact::synth {

struct DepthNoiseOptions {
  bool enabled = true;       // false: only quantise to mm and apply the range.
  double min_range_m = 0.5;  // Kinect v2 operating range.
  double max_range_m = 4.5;
  double max_incidence_deg = 80.0;        // Beyond this the return is too weak: invalid.
  double sigma_lateral_px = 0.5;          // Lateral jitter of the sampling position.
  double edge_jump_m = 0.05;              // A depth step above this is a discontinuity.
  double flying_pixel_probability = 0.5;  // Chance that an edge pixel mixes returns.
  double axial_noise_scale = 1.0;         // Multiplies sigma_z (1 = the published model).

  absl::Status Validate() const;
};

// Axial standard deviation of Fankhauser et al. 2015, in millimetres, for a
// distance `z_m` and incidence angle `theta_rad` in [0, pi/2).
double KinectV2AxialSigmaMm(double z_m, double theta_rad);

// Turns an ideal depth image (z in metres along the optical axis, 0 = nothing)
// seen through `intrinsics` into what a Kinect v2 would report (uint16 mm,
// 0 = invalid). Deterministic for a given `seed`.
DepthImageMm ApplyKinectV2DepthNoise(const FloatImage& ideal_depth_m,
                                     const CameraIntrinsics& intrinsics,
                                     const DepthNoiseOptions& options, uint64_t seed);

// Noise-free quantisation of the same image (for the ground-truth channel):
// rounds to mm, applies the operating range, nothing else.
DepthImageMm QuantizeDepth(const FloatImage& ideal_depth_m, const DepthNoiseOptions& options);

}  // namespace reenact::synth
