#include "clients/viewer/ar_view.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/viewer/hud.h"
#include "common/base/status_macros.h"
#include "common/board/board_detector.h"
#include "common/board/intrinsics_file.h"
#include "common/io/png.h"
#include "common/io/video_writer.h"
#include "common/render/image_window.h"
#include "common/render/intrinsics_camera.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::viewer {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

absl::StatusOr<cv::VideoCapture> OpenVideo(const std::string& video) {
  cv::VideoCapture capture;
  if (absl::StartsWith(video, "webcam:")) {
    int index = 0;
    if (!absl::SimpleAtoi(video.substr(7), &index) || index < 0) {
      return absl::InvalidArgumentError(absl::StrCat("--ar webcam:N: bad camera '", video, "'"));
    }
    capture.open(index);
  } else {
    if (!std::filesystem::exists(video)) {
      return absl::NotFoundError(absl::StrCat(video, ": no such video file"));
    }
    capture.open(video);
  }
  if (!capture.isOpened()) {
    return absl::NotFoundError(absl::StrCat("cannot open the video ", video));
  }
  return capture;
}

RgbImage FromBgr(const cv::Mat& bgr) {
  RgbImage image(bgr.cols, bgr.rows);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* row = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = row[x][2 - c];
    }
  }
  return image;
}

// Where the board lies in the reenactment's world (see the file comment).
Eigen::Isometry3d WorldFromBoard(const Reenactment& data, bool anchored) {
  Eigen::Isometry3d world_from_board = Eigen::Isometry3d::Identity();
  if (anchored) return world_from_board;
  if (absl::StatusOr<Eigen::Vector3d> actor = view::MeanActorPosition(data); actor.ok()) {
    world_from_board.translation() = Eigen::Vector3d(actor->x(), 0.0, actor->z());
  }
  return world_from_board;
}

// The session's state: sources, tracker, renderer and outputs.
struct ArRun {
  cv::VideoCapture capture;
  CameraIntrinsics intrinsics;
  std::unique_ptr<board::BoardTracker> tracker;
  std::unique_ptr<render::OffscreenRenderer> renderer;
  std::unique_ptr<view::ReenactmentRenderer> view;
  std::unique_ptr<VideoWriter> video;
  std::unique_ptr<render::ImageWindow> window;
  std::ofstream poses;
  Eigen::Isometry3d world_from_board = Eigen::Isometry3d::Identity();
};

absl::StatusOr<CameraIntrinsics> VideoIntrinsics(const ArOptions& options, int width, int height) {
  if (options.intrinsics_file.empty()) {
    return board::IntrinsicsFromFieldOfView(width, height, options.fov_deg);
  }
  ASSIGN_OR_RETURN(CameraIntrinsics intrinsics, board::LoadIntrinsicsFile(options.intrinsics_file));
  if (intrinsics.width != width || intrinsics.height != height) {
    return absl::InvalidArgumentError(absl::StrCat(options.intrinsics_file, ": intrinsics of ",
                                                   intrinsics.width, "x", intrinsics.height,
                                                   " for a video of ", width, "x", height));
  }
  return intrinsics;
}

absl::Status OpenOutputs(const ArOptions& options, const Reenactment& data, double fps, ArRun* run,
                         ArSummary* summary) {
  const int width = run->intrinsics.width, height = run->intrinsics.height;
  if (options.render_to.empty()) {
    RETURN_IF_ERROR(run->renderer->ReleaseCurrent());
    ASSIGN_OR_RETURN(
        run->window,
        render::ImageWindow::Open("reenact-viewer AR " + data.info.reenactment_id, width, height));
    return absl::OkStatus();
  }
  std::error_code ec;
  std::filesystem::create_directories(options.render_to, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(options.render_to, ": ", ec.message()));
  summary->poses_csv = (std::filesystem::path(options.render_to) / "poses.csv").string();
  run->poses.open(summary->poses_csv);
  if (!run->poses) return absl::PermissionDeniedError(summary->poses_csv + ": cannot write");
  run->poses << "video_frame,instant,found,markers,rms_px,tx_m,ty_m,tz_m,qw,qx,qy,qz\n";
  if (options.mp4) {
    summary->mp4_path = (std::filesystem::path(options.render_to) / "video.mp4").string();
    auto opened = VideoWriter::Open(summary->mp4_path, width, height, fps);
    if (opened.ok()) {
      run->video = std::move(*opened);
    } else {
      summary->mp4_problem = std::string(opened.status().message());
      summary->mp4_path.clear();
    }
  }
  return absl::OkStatus();
}

// Draws the teacher over `frame` where the board puts them.
absl::Status Composite(const Reenactment& data, int instant,
                       const Eigen::Isometry3d& camera_from_board, ArRun* run, RgbImage* frame) {
  const Eigen::Isometry3d world_from_camera = run->world_from_board * camera_from_board.inverse();
  render::RenderOutputs out;
  out.requested = render::kRenderColour | render::kRenderLabel;
  RETURN_IF_ERROR(run->view->Render(
      data.frames[instant].frame_index,
      render::RenderCameraFromIntrinsics(run->intrinsics, world_from_camera, 0.05, 50.0), &out));
  for (size_t i = 0; i < out.label.data.size(); ++i) {
    if (out.label.data[i] == 0) continue;
    for (int c = 0; c < 3; ++c) frame->data[3 * i + c] = out.colour.data[3 * i + c];
  }
  return absl::OkStatus();
}

void WritePose(int k, int instant, const absl::StatusOr<board::BoardDetection>& found,
               std::ofstream* poses) {
  if (!found.ok()) {
    *poses << k << "," << instant << ",0,0,,,,,,,,\n";
    return;
  }
  const Eigen::Vector3d t = found->camera_from_board.translation();
  const Eigen::Quaterniond q(found->camera_from_board.linear());
  *poses << absl::StrFormat("%d,%d,1,%d,%.4f,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f,%.9f\n", k, instant,
                            found->num_markers, found->reprojection_rms_px, t.x(), t.y(), t.z(),
                            q.w(), q.x(), q.y(), q.z());
}

}  // namespace

absl::Status ArOptions::Validate() const {
  if (video.empty()) return absl::InvalidArgumentError("--ar needs a video file or webcam:N");
  if (!(fov_deg > 1.0 && fov_deg < 179.0)) {
    return absl::InvalidArgumentError("--fov must be 1..179 degrees");
  }
  if (!(speed > 0.0) || speed > 8.0) return absl::InvalidArgumentError("--speed must be in (0, 8]");
  if (max_frames < 0 || !(run_seconds >= 0.0)) {
    return absl::InvalidArgumentError("frame and time limits must be >= 0");
  }
  return absl::OkStatus();
}

std::string AnchoredBoard(const Reenactment& data) {
  std::string spec;
  for (const SensorCalibration& sensor : data.info.sensors) {
    if (!absl::StartsWith(sensor.world_anchor, "board:")) return "";
    const std::string this_spec = sensor.world_anchor.substr(6);
    if (!spec.empty() && this_spec != spec) return "";
    spec = this_spec;
  }
  return spec;
}

absl::StatusOr<ArSummary> RunAr(const Reenactment& data, const ArOptions& options) {
  const Clock::time_point start = Clock::now();
  RETURN_IF_ERROR(options.Validate());
  if (data.frames.empty()) return absl::InvalidArgumentError("the reenactment has no instant");
  ArSummary summary;
  const std::string anchored_spec = AnchoredBoard(data);
  summary.anchored = !anchored_spec.empty();
  summary.board_spec = !options.board_spec.empty() ? options.board_spec
                       : summary.anchored          ? anchored_spec
                                                   : board::kDefaultBoardSpecText;
  ASSIGN_OR_RETURN(board::BoardSpec spec, board::ParseBoardSpec(summary.board_spec));
  ArRun run;
  ASSIGN_OR_RETURN(run.capture, OpenVideo(options.video));
  const bool webcam = absl::StartsWith(options.video, "webcam:");
  cv::Mat bgr;
  if (!run.capture.read(bgr) || bgr.empty()) {
    return absl::NotFoundError(absl::StrCat(options.video, ": no frame could be read"));
  }
  double video_fps = run.capture.get(cv::CAP_PROP_FPS);
  if (!(video_fps > 0 && video_fps < 1000)) video_fps = 30.0;
  ASSIGN_OR_RETURN(run.intrinsics, VideoIntrinsics(options, bgr.cols, bgr.rows));
  ASSIGN_OR_RETURN(board::BoardTracker tracker, board::BoardTracker::Create(spec, run.intrinsics));
  run.tracker = std::make_unique<board::BoardTracker>(std::move(tracker));
  render::RendererOptions renderer_options;
  renderer_options.max_width = bgr.cols;
  renderer_options.max_height = bgr.rows;
  ASSIGN_OR_RETURN(run.renderer, render::OffscreenRenderer::Create(renderer_options));
  view::ReenactmentRendererOptions view_options;
  view_options.mode = options.mode;
  ASSIGN_OR_RETURN(run.view,
                   view::ReenactmentRenderer::Create(data, run.renderer.get(), view_options));
  run.world_from_board = WorldFromBoard(data, summary.anchored);
  RETURN_IF_ERROR(OpenOutputs(options, data, video_fps, &run, &summary));

  const double reenactment_fps = data.info.fps > 0 ? data.info.fps : 30.0;
  const int instants = static_cast<int>(data.frames.size());
  double rms_sum = 0.0;
  for (int k = 0; !bgr.empty(); ++k) {
    const double t_s = webcam ? SecondsSince(start) : k / video_fps;
    const int instant =
        static_cast<int>(std::floor(t_s * reenactment_fps * options.speed)) % instants;
    RgbImage frame = FromBgr(bgr);
    const absl::StatusOr<board::BoardDetection> found = run.tracker->Track(frame);
    if (found.ok()) {
      ++summary.frames_with_board;
      rms_sum += found->reprojection_rms_px;
      RETURN_IF_ERROR(Composite(data, instant, found->camera_from_board, &run, &frame));
    } else if (found.status().code() != absl::StatusCode::kNotFound) {
      return found.status();
    }
    ++summary.frames;
    if (run.window != nullptr) {
      RETURN_IF_ERROR(run.renderer->ReleaseCurrent());
      DrawStatusLine(found.ok() ? absl::StrFormat("board: %d markers, %.2f px", found->num_markers,
                                                  found->reprojection_rms_px)
                                : std::string("board not found"),
                     0, &frame);
      RETURN_IF_ERROR(run.window->Show(frame));
      const render::WindowInput input = run.window->Poll();
      bool quit = input.close_requested;
      for (int key : input.keys_pressed) quit |= key == render::kKeyEscape || key == 'Q';
      if (quit) break;
    } else {
      WritePose(k, instant, found, &run.poses);
      if (options.png) {
        RETURN_IF_ERROR(WritePng(
            frame, (std::filesystem::path(options.render_to) / absl::StrFormat("frame_%05d.png", k))
                       .string()));
      }
      if (run.video != nullptr) {
        if (absl::Status appended = run.video->Append(frame); !appended.ok()) {
          summary.mp4_problem = std::string(appended.message());
          run.video.reset();
        }
      }
    }
    if (options.max_frames > 0 && summary.frames >= options.max_frames) break;
    if (options.run_seconds > 0 && SecondsSince(start) >= options.run_seconds) break;
    if (!run.capture.read(bgr)) break;
  }
  if (run.video != nullptr) {
    if (absl::Status closed = run.video->Close(); !closed.ok()) {
      summary.mp4_problem = std::string(closed.message());
    }
  }
  if (!summary.mp4_problem.empty()) summary.mp4_path.clear();
  summary.mean_rms_px = summary.frames_with_board > 0 ? rms_sum / summary.frames_with_board : 0.0;
  summary.seconds = SecondsSince(start);
  summary.fps = summary.seconds > 0 ? summary.frames / summary.seconds : 0.0;
  return summary;
}

}  // namespace reenact::viewer
