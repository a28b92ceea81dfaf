// People in a single depth image, without a background model: the tracker's
// own segmentation for sources that give no actor mask (one depth image from
// `reenact track`, a recording that has no mask channel).
//
// 1. Floor: the dominant plane whose normal lies within `max_floor_tilt_deg`
//    of the image's up direction (-y of the camera), found by RANSAC
//    (Fischler and Bolles, CACM 1981) and refined by least squares; points
//    within `floor_distance_m` of it (or under it) are dropped. An image with
//    no such plane (a close-up) keeps every point.
// 2. Components: 8-connected pixels whose depths differ by less than
//    max(depth_step_m, 4 sigma_z) (Kinect-class axial noise), so people are
//    cut from what stands behind them.
// 3. People: a component is a person when its metric extent is a person's
//    (height above the floor, or image extent where no floor was found, and
//    width within the options' bounds) and it has enough points; walls and
//    furniture that are too wide, too flat or too far fail those tests.
//    A component cut by the image border is still a person when what is seen
//    of it fits.
// 4. Pieces: a component that is no person by itself (a head behind a raised
//    arm, a forearm across the chest: a person's parts occlude each other
//    across steps larger than the connection step) joins the person it
//    touches across a depth step of at most `attach_step_m`, when the two
//    together still have a person's size.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"

namespace reenact::tracking {

struct PersonSegmentationOptions {
  double min_range_m = 0.3;  // Depths outside [min, max] are ignored.
  double max_range_m = 6.0;
  double max_floor_tilt_deg = 35.0;  // Floor normal vs the image's up direction.
  double floor_inlier_m = 0.03;      // RANSAC inlier distance.
  double floor_distance_m = 0.04;    // Points this close above the floor are floor.
  double min_floor_fraction = 0.05;  // Inliers needed (fraction of valid points) to accept a floor.
  int floor_iterations = 200;
  double depth_step_m = 0.06;  // Neighbours farther apart are not connected.
  double min_height_m = 0.35;  // Vertical extent of a person (what is seen of one).
  double max_height_m = 2.3;
  double max_width_m = 1.4;         // Horizontal extent (arms out stay below this).
  double max_depth_extent_m = 1.4;  // Extent along the viewing direction.
  int min_points = 400;             // Smallest person, pixels.
  double attach_step_m = 0.3;       // Step 4; 0: pieces stay apart.
  uint64_t seed = 1;                // RANSAC draws (results are deterministic).

  absl::Status Validate() const;
};

struct PersonSegment {
  int label = 0;  // Value in PersonSegmentation::labels, from 1.
  int num_pixels = 0;
  Eigen::Vector3d centroid_in_camera_m = Eigen::Vector3d::Zero();
  // Pixel bounding box, inclusive.
  int min_x = 0, min_y = 0, max_x = 0, max_y = 0;
  bool touches_border = false;
};

struct PersonSegmentation {
  MaskImage labels;                   // 0: not a person; k: the person with label k.
  std::vector<PersonSegment> people;  // Largest first.
  // The floor plane n . p + d = 0 in the camera frame (n unit, pointing up,
  // i.e. towards -y of the image), when one was found.
  std::optional<Eigen::Vector4d> floor_plane;
};

// InvalidArgument for an image whose size does not match `intrinsics`, bad
// intrinsics (non-finite, zero focal length) or bad options; an image with
// nobody gives an empty `people` and an all-zero label image.
absl::StatusOr<PersonSegmentation> SegmentPeople(const DepthImageMm& depth,
                                                 const CameraIntrinsics& intrinsics,
                                                 const PersonSegmentationOptions& options = {});

}  // namespace reenact::tracking
