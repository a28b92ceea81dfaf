// Headless rendering of a reenactment to image files (reenact-viewer
// --render-to DIR): one PNG per shot of a --camera spec (viewer_camera.h),
// drawn by view::ReenactmentRenderer through an EGL context without a
// display, plus an MP4 of the same frames (H.264 through libavcodec).
#pragma once

#include <string>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/progress.h"
#include "common/model/reenactment.h"

namespace reenact::viewer {

struct HeadlessOptions {
  // Image size, pixels.
  int width = 1280;
  int height = 720;
  // --camera spec: orbit, orbit:DEG, sensor:N or path:FILE.
  std::string camera = "orbit";
  // Instants [first_frame, end_frame) for orbit and sensor cameras (indices
  // into the reenactment's frames); end_frame < 0: to the end.
  int first_frame = 0;
  int end_frame = -1;
  // Texturing of rigid-part reenactments (body reenactments use their atlas).
  view::TextureMode mode = view::TextureMode::kVdtm;
  // Multisampling of the colour (0, 2, 4, 8).
  int msaa_samples = 4;
  // PNGs with an alpha channel that is the actor's silhouette (255 where the
  // reenactment is drawn, 0 elsewhere) instead of RGB over the background.
  bool alpha = false;
  // Background, sRGB in [0,1].
  Eigen::Vector3f background_srgb{0.12f, 0.12f, 0.14f};
  // Also write video.mp4 (frame rate: the reenactment's, or `video_fps`
  // when > 0).
  bool mp4 = true;
  double video_fps = 0.0;
  // Number the PNGs by the instant drawn (index into the reenactment's
  // frames) instead of by output image; for orbit and sensor cameras, where
  // each image is a different instant.
  bool name_by_instant = false;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

struct HeadlessSummary {
  int images = 0;
  std::string first_image;  // Path of the first PNG.
  std::string mp4_path;     // Empty when no MP4 was written.
  std::string mp4_problem;  // Why not, when one was asked for.
  // A body's per-frame appearance: whether it was drawn, or why not
  // (ReenactmentRenderer::appearance_note; empty when it was or none exists).
  bool per_frame_appearance = false;
  std::string appearance_note;
  double render_seconds = 0.0;  // Drawing and reading back only.
  double total_seconds = 0.0;   // Everything, files included.
};

// Renders the shots of options.camera into `dir` (created when missing) as
// frame_00000.png, frame_00001.png, ... and video.mp4. InvalidArgument for bad
// options or a bad camera spec; PermissionDenied for an unwritable folder;
// Unavailable when no GL context can be had; Cancelled when `progress`
// returns false. A failed MP4 (e.g. no H.264 or MPEG-4 encoder) does not fail
// the call: mp4_problem says why.
absl::StatusOr<HeadlessSummary> RenderToDir(const Reenactment& data, const std::string& dir,
                                            const HeadlessOptions& options,
                                            const ProgressCallback& progress = {});

}  // namespace reenact::viewer
