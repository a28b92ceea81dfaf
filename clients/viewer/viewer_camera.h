// Cameras of the viewer: a look-at pinhole camera, the camera specs of the
// headless renderer (--camera), and the orbit controller of the window.
//
// World: metres, right-handed, +Y up (reenactments' frame). Cameras follow
// the renderer's OpenCV convention (render::RenderCamera: x right, y down,
// z forward).
//
// Camera path files (--camera path:FILE) are JSON:
//
//   {
//     "origin": "world",          // or "actor": eyes and targets are offsets
//                                 // from the actor's mean position
//     "fov_deg": 50,              // horizontal field of view (default 50)
//     "keys": [
//       {"step": 0,  "frame": 0,  "eye": [0, 1.2, 3], "target": [0, 1, 0]},
//       {"step": 90, "frame": 90, "eye": [3, 1.2, 0], "target": [0, 1, 0],
//        "fov_deg": 40}
//     ]
//   }
//
// Output step s (one image each) runs from the first key's step to the last
// key's; between two keys eye, target, field of view and frame are linearly
// interpolated (the frame rounded to the nearest instant). A key without
// "frame" plays along: frame = the previous key's frame + steps since it (the
// first key's frame defaults to 0). "frame" counts instants in the order the
// reenactment stores them (0 = its first PartFrame).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/model/reenactment.h"
#include "common/render/render_types.h"

namespace reenact::viewer {

// A pinhole camera at `eye_in_world` looking at `target_in_world` with image
// rows going down along -up (no roll), the given horizontal field of view
// (degrees, 1..170) and square pixels, principal point at the image centre.
// InvalidArgument when eye and target coincide, the view is along `up`, the
// fov or the size is out of range, or a value is not finite.
absl::StatusOr<render::RenderCamera> LookAtCamera(
    const Eigen::Vector3d& eye_in_world, const Eigen::Vector3d& target_in_world,
    double horizontal_fov_deg, int width, int height,
    const Eigen::Vector3d& up_in_world = Eigen::Vector3d::UnitY());

// One output image of a headless render: the instant to draw (index into
// Reenactment::frames) and the camera.
struct Shot {
  int frame = 0;
  render::RenderCamera camera;
};

// The shots of a --camera spec over the instants [first_frame, end_frame):
//   "orbit"      sensor 0's colour camera turned about the vertical through
//                the actor's mean position, a full turn over the instants;
//   "orbit:DEG"  the same camera turned DEG degrees, every instant;
//   "sensor:N"   sensor N's colour camera (intrinsics scaled to the size);
//   "path:FILE"  a camera path file (see above; the instant range is not
//                used).
// InvalidArgument for a bad spec, an unreadable or malformed path file, or an
// empty range; FailedPrecondition when the reenactment names no sensor (orbit,
// sensor) or has no actor position (orbit, "origin": "actor").
absl::StatusOr<std::vector<Shot>> CameraShots(const std::string& spec, const Reenactment& data,
                                              int width, int height, int first_frame,
                                              int end_frame);

// The shots of a camera path file's text (see above); `actor_in_world` is
// the origin of "origin": "actor" (ignored otherwise).
absl::StatusOr<std::vector<Shot>> ParseCameraPath(const std::string& json_text, int frame_count,
                                                  int width, int height,
                                                  const Eigen::Vector3d& actor_in_world);

// Interactive orbit about a target: the camera sits `distance_m` from the
// target at `yaw_deg` about +Y (0: on the target's +Z side, looking toward
// -Z) and `pitch_deg` above the horizontal.
class OrbitController {
 public:
  OrbitController() = default;
  // Starts where `camera` is, orbiting `target_in_world`, with its
  // horizontal field of view.
  static OrbitController FromCamera(const render::RenderCamera& camera,
                                    const Eigen::Vector3d& target_in_world);

  // A drag of (dx, dy) pixels: yaw and pitch, `degrees_per_pixel` each;
  // pitch stays within +-85 degrees.
  void Rotate(double dx_px, double dy_px, double degrees_per_pixel = 0.3);
  // A scroll of `steps` (positive: closer): the distance shrinks by 10 % per
  // step, within 0.3..30 m.
  void Zoom(double steps);
  // Back to where FromCamera started.
  void Reset();

  // The camera of the current state at width x height.
  absl::StatusOr<render::RenderCamera> Camera(int width, int height) const;

  double yaw_deg() const { return yaw_deg_; }
  double pitch_deg() const { return pitch_deg_; }
  double distance_m() const { return distance_m_; }

 private:
  Eigen::Vector3d target_in_world_ = Eigen::Vector3d(0, 1, 0);
  double yaw_deg_ = 0.0;
  double pitch_deg_ = 10.0;
  double distance_m_ = 3.0;
  double fov_deg_ = 50.0;
  double initial_yaw_deg_ = 0.0;
  double initial_pitch_deg_ = 10.0;
  double initial_distance_m_ = 3.0;
};

}  // namespace reenact::viewer
