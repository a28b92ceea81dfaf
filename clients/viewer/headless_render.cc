#include "clients/viewer/headless_render.h"

#include <chrono>
#include <filesystem>
#include <memory>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/viewer/viewer_camera.h"
#include "common/base/status_macros.h"
#include "common/io/png.h"
#include "common/io/video_writer.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::viewer {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

absl::Status HeadlessOptions::Validate() const {
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    return absl::InvalidArgumentError("width and height must be 16..8192 pixels");
  }
  if (msaa_samples != 0 && msaa_samples != 2 && msaa_samples != 4 && msaa_samples != 8) {
    return absl::InvalidArgumentError("msaa_samples must be 0, 2, 4 or 8");
  }
  if (first_frame < 0) return absl::InvalidArgumentError("first_frame must be >= 0");
  if (!(background_srgb.minCoeff() >= 0.0f && background_srgb.maxCoeff() <= 1.0f)) {
    return absl::InvalidArgumentError("background colour components must be in [0,1]");
  }
  if (!(video_fps >= 0.0) || video_fps > 1000.0) {
    return absl::InvalidArgumentError("video_fps must be 0..1000");
  }
  return absl::OkStatus();
}

absl::StatusOr<HeadlessSummary> RenderToDir(const Reenactment& data, const std::string& dir,
                                            const HeadlessOptions& options,
                                            const ProgressCallback& progress) {
  const Clock::time_point start = Clock::now();
  RETURN_IF_ERROR(options.Validate());
  const int frame_count = static_cast<int>(data.frames.size());
  const int end = options.end_frame < 0 ? frame_count : std::min(options.end_frame, frame_count);
  ASSIGN_OR_RETURN(std::vector<Shot> shots, CameraShots(options.camera, data, options.width,
                                                        options.height, options.first_frame, end));
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(dir, ": ", ec.message()));

  render::RendererOptions renderer_options;
  renderer_options.max_width = options.width;
  renderer_options.max_height = options.height;
  renderer_options.msaa_samples = options.msaa_samples;
  ASSIGN_OR_RETURN(auto renderer, render::OffscreenRenderer::Create(renderer_options));
  render::ShadingOptions shading;
  shading.background_srgb = options.background_srgb;
  RETURN_IF_ERROR(renderer->SetShading(shading));
  view::ReenactmentRendererOptions view_options;
  view_options.mode = options.mode;
  ASSIGN_OR_RETURN(auto view,
                   view::ReenactmentRenderer::Create(data, renderer.get(), view_options));

  HeadlessSummary summary;
  std::unique_ptr<VideoWriter> video;
  if (options.mp4) {
    const double fps =
        options.video_fps > 0 ? options.video_fps : (data.info.fps > 0 ? data.info.fps : 30.0);
    summary.mp4_path = (std::filesystem::path(dir) / "video.mp4").string();
    VideoWriterOptions video_options;
    video_options.preset = "veryfast";
    absl::StatusOr<std::unique_ptr<VideoWriter>> opened =
        VideoWriter::Open(summary.mp4_path, options.width, options.height, fps, video_options);
    if (opened.ok()) {
      video = std::move(*opened);
    } else {
      summary.mp4_problem = std::string(opened.status().message());
      summary.mp4_path.clear();
    }
  }
  for (size_t i = 0; i < shots.size(); ++i) {
    render::RenderOutputs out;
    out.requested = render::kRenderColour | (options.alpha ? render::kRenderLabel : 0u);
    const Clock::time_point drawn = Clock::now();
    view::FrameStats stats;
    RETURN_IF_ERROR(
        view->Render(data.frames[shots[i].frame].frame_index, shots[i].camera, &out, &stats));
    summary.per_frame_appearance |= stats.per_frame_appearance;
    summary.render_seconds += SecondsSince(drawn);
    const std::string path =
        (std::filesystem::path(dir) / absl::StrFormat("frame_%05d.png", options.name_by_instant
                                                                            ? shots[i].frame
                                                                            : static_cast<int>(i)))
            .string();
    // RGB, or RGBA with the silhouette (label > 0) as alpha.
    RETURN_IF_ERROR(
        WritePng(out.colour, path, {.alpha_mask = options.alpha ? &out.label : nullptr}));
    if (i == 0) summary.first_image = path;
    if (video != nullptr) {
      if (absl::Status appended = video->Append(out.colour); !appended.ok()) {
        summary.mp4_problem = std::string(appended.message());
        video.reset();
      }
    }
    ++summary.images;
    if (progress && !progress({"render", (i + 1.0) / shots.size(), static_cast<int64_t>(i + 1),
                               static_cast<int64_t>(shots.size())})) {
      return absl::CancelledError("rendering cancelled");
    }
  }
  if (video != nullptr) {
    if (absl::Status closed = video->Close(); !closed.ok()) {
      summary.mp4_problem = std::string(closed.message());
    }
  }
  if (!summary.mp4_problem.empty()) summary.mp4_path.clear();
  summary.appearance_note = view->appearance_note();
  summary.total_seconds = SecondsSince(start);
  return summary;
}

}  // namespace reenact::viewer
