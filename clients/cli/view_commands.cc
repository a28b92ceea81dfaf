// `reenact render` (headless frames of a reenactment from any camera, VDTM or
// baked) and `reenact eval` (a reenactment against its synthetic take's
// ground truth: surface, novel-view PSNR/IoU, MPJPE). Both read the
// reenactment from a server (--server, --reenactment) or a file (--in).
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <ostream>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "clients/sdk/reenactments_client.h"
#include "clients/sdk/takes_client.h"
#include "clients/view/evaluation.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::cli {
namespace {

// Where the reenactment comes from: --in FILE, or --reenactment ID on
// --server.
absl::StatusOr<ReenactmentData> LoadReenactment(const Flags& flags, bool skip_keyframes,
                                                ProgressBar* bar) {
  if (flags.Has("in")) {
    if (flags.Has("reenactment")) {
      return absl::InvalidArgumentError("give either --in FILE or --reenactment ID, not both");
    }
    return ReadReenactmentFile(*flags.Get("in"), skip_keyframes);
  }
  if (!flags.Has("reenactment")) {
    return absl::InvalidArgumentError("--reenactment ID (with --server) or --in FILE is required");
  }
  ASSIGN_OR_RETURN(client::ConnectionOptions connection,
                   ConnectionFromFlags(flags, "server", kDefaultServer, 60.0));
  return client::ReenactmentsClient(connection)
      .Fetch(*flags.Get("reenactment"), skip_keyframes,
             [bar](const Progress& p) { return bar->Update(p); });
}

// A reenactment fetch or read that failed: usage errors stay usage errors.
int ReportLoadError(const absl::Status& status, std::ostream& err) {
  ReportError(status, err);
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitUsage : kExitFailure;
}

struct FrameRange {
  int begin = 0;
  int end = std::numeric_limits<int>::max();  // Exclusive.
};

// "A:B" (A..B-1), "A:" (A to the end), ":B", or "A" (one frame).
absl::StatusOr<FrameRange> ParseFrames(const std::string& text, int frame_count) {
  FrameRange range;
  const std::vector<std::string> pieces = absl::StrSplit(text, ':');
  auto number = [&](const std::string& s, int fallback) -> absl::StatusOr<int> {
    if (s.empty()) return fallback;
    int value = 0;
    if (!absl::SimpleAtoi(s, &value) || value < 0) {
      return absl::InvalidArgumentError(absl::StrCat("--frames: bad frame number '", s, "'"));
    }
    return value;
  };
  if (pieces.size() == 1) {
    ASSIGN_OR_RETURN(range.begin, number(pieces[0], 0));
    range.end = range.begin + 1;
  } else if (pieces.size() == 2) {
    ASSIGN_OR_RETURN(range.begin, number(pieces[0], 0));
    ASSIGN_OR_RETURN(range.end, number(pieces[1], frame_count));
  } else {
    return absl::InvalidArgumentError(absl::StrCat("--frames: expected A:B, got '", text, "'"));
  }
  range.end = std::min(range.end, frame_count);
  if (range.begin >= range.end) {
    return absl::InvalidArgumentError(
        absl::StrCat("--frames ", text, " selects none of the ", frame_count, " frames"));
  }
  return range;
}

// --camera orbit:DEG (sensor 0 turned DEG about the vertical through the
// actor's mean position) or sensor:N (sensor N's colour camera).
absl::StatusOr<render::RenderCamera> ParseCamera(const std::string& spec,
                                                 const ReenactmentData& data, int width,
                                                 int height) {
  const std::vector<std::string> pieces = absl::StrSplit(spec, absl::MaxSplits(':', 1));
  if (pieces.size() != 2 || (pieces[0] != "orbit" && pieces[0] != "sensor")) {
    return absl::InvalidArgumentError(
        absl::StrCat("--camera: expected orbit:DEG or sensor:N, got '", spec, "'"));
  }
  if (data.info.sensors_size() == 0) {
    return absl::FailedPreconditionError("the reenactment names no sensor to place a camera by");
  }
  if (pieces[0] == "sensor") {
    int n = 0;
    if (!absl::SimpleAtoi(pieces[1], &n) || n < 0 || n >= data.info.sensors_size()) {
      return absl::InvalidArgumentError(
          absl::StrCat("--camera sensor:N: N must be 0..", data.info.sensors_size() - 1));
    }
    return view::SensorRenderCamera(data.info.sensors(n), width, height);
  }
  double degrees = 0;
  if (!absl::SimpleAtod(pieces[1], &degrees) || !std::isfinite(degrees)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--camera orbit:DEG: bad angle '", pieces[1], "'"));
  }
  ASSIGN_OR_RETURN(render::RenderCamera base,
                   view::SensorRenderCamera(data.info.sensors(0), width, height));
  ASSIGN_OR_RETURN(Eigen::Vector3d pivot, view::MeanActorPosition(data));
  return view::OrbitCamera(base, pivot, degrees);
}

absl::Status WritePng(const RgbImage& image, const std::string& path) {
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) bgr.at<cv::Vec3b>(y, x)[2 - c] = image.at(x, y, c);
    }
  }
  if (!cv::imwrite(path, bgr))
    return absl::PermissionDeniedError(absl::StrCat(path, ": cannot write"));
  return absl::OkStatus();
}

absl::StatusOr<int> RenderFrames(const ReenactmentData& data, const Flags& flags,
                                 view::TextureMode mode, ProgressBar* bar) {
  ASSIGN_OR_RETURN(int width, flags.GetInt("width", 960));
  ASSIGN_OR_RETURN(int height, flags.GetInt("height", 540));
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    return absl::InvalidArgumentError("--width and --height must be 16..8192");
  }
  ASSIGN_OR_RETURN(std::string out_dir, flags.Required("out"));
  ASSIGN_OR_RETURN(render::RenderCamera camera,
                   ParseCamera(flags.GetOr("camera", "orbit:0"), data, width, height));
  const int frame_count = static_cast<int>(data.frames.size());
  ASSIGN_OR_RETURN(FrameRange range, ParseFrames(flags.GetOr("frames", ":"), frame_count));
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(out_dir, ": ", ec.message()));
  render::RendererOptions renderer_options;
  renderer_options.max_width = width;
  renderer_options.max_height = height;
  renderer_options.msaa_samples = 4;  // Smooth edges for viewing.
  ASSIGN_OR_RETURN(auto renderer, render::OffscreenRenderer::Create(renderer_options));
  view::ReenactmentRendererOptions options;
  options.mode = mode;
  ASSIGN_OR_RETURN(auto view, view::ReenactmentRenderer::Create(data, renderer.get(), options));
  for (int f = range.begin; f < range.end; ++f) {
    render::RenderOutputs out;
    out.requested = render::kRenderColour;
    RETURN_IF_ERROR(view->Render(f, camera, &out));
    RETURN_IF_ERROR(
        WritePng(out.colour,
                 (std::filesystem::path(out_dir) / absl::StrFormat("frame_%05d.png", f)).string()));
    bar->Update({"render", (f - range.begin + 1.0) / (range.end - range.begin), f - range.begin + 1,
                 range.end - range.begin});
  }
  return range.end - range.begin;
}

// The take to evaluate against: --take FILE, else downloaded from the server
// by the reenactment's take id into a temporary file (removed by the caller).
absl::StatusOr<std::string> TakePath(const Flags& flags, const ReenactmentData& data,
                                     bool* temporary, ProgressBar* bar) {
  *temporary = false;
  if (flags.Has("take")) return *flags.Get("take");
  if (data.info.take_id().empty()) {
    return absl::InvalidArgumentError("the reenactment names no take; pass --take FILE");
  }
  ASSIGN_OR_RETURN(client::ConnectionOptions connection,
                   ConnectionFromFlags(flags, "server", kDefaultServer, 60.0));
  const std::string path =
      (std::filesystem::temp_directory_path() /
       absl::StrCat("reenact_eval_", data.info.take_id(), "_", ::getpid(), ".mcap"))
          .string();
  *temporary = true;
  RETURN_IF_ERROR(
      client::TakesClient(connection)
          .Download(data.info.take_id(), path, [bar](const Progress& p) { return bar->Update(p); })
          .status());
  return path;
}

void PrintFigures(const view::EvaluationResult& result, const ReenactmentData& data, bool json,
                  std::ostream& out) {
  if (json) {
    nlohmann::json j;
    for (const auto& [name, value] : result.Figures()) {
      if (std::isfinite(value)) {
        j[name] = value;
      } else {
        j[name] = nullptr;
      }
    }
    j["reenactment_id"] = data.info.reenactment_id();
    j["take_id"] = data.info.take_id();
    j["method"] = data.info.method();
    out << j.dump(2) << "\n";
    return;
  }
  out << "reenactment " << data.info.reenactment_id() << " (" << data.info.method() << ") vs take "
      << data.info.take_id() << ", " << result.frames_evaluated << " frames\n";
  out << absl::StrFormat("  surface_mm          %8.2f  (accuracy %.2f, completeness %.2f)\n",
                         result.surface_mm, result.surface_accuracy_mm,
                         result.surface_completeness_mm)
      << absl::StrFormat("  psnr_db_90          %8.2f  (%d pixels)\n", result.psnr_db_90,
                         result.psnr_pixels)
      << absl::StrFormat("  iou_90              %8.3f\n", result.iou_90)
      << absl::StrFormat("  mpjpe_mm            %8.2f  (%d joints)\n", result.mpjpe_mm,
                         result.mpjpe_joints);
}

}  // namespace

int RunRender(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args,
                            {"server", "timeout", "reenactment", "in", "camera", "out", "width",
                             "height", "frames", "mode"},
                            {"quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("render takes no positional arguments"), err);
  }
  auto mode = view::ParseTextureMode(flags->GetOr("mode", "vdtm"));
  if (!mode.ok()) return ReportError(mode.status(), err);
  if (!flags->Has("out"))
    return ReportError(absl::InvalidArgumentError("--out DIR is required"), err);
  ProgressBar bar(err, !flags->Has("quiet"));
  auto data = LoadReenactment(*flags, *mode == view::TextureMode::kBaked, &bar);
  bar.Finish();
  if (!data.ok()) return ReportLoadError(data.status(), err);
  auto frames = RenderFrames(*data, *flags, *mode, &bar);
  bar.Finish();
  if (!frames.ok()) return ReportError(frames.status(), err);
  out << "wrote " << *frames << " frames to " << *flags->Get("out") << "\n";
  return kExitOk;
}

int RunEval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(
      args, {"server", "timeout", "reenactment", "in", "take", "every", "mode", "images", "angle"},
      {"json", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("eval takes no positional arguments"), err);
  }
  view::EvaluationOptions options;
  auto every = flags->GetInt("every", 1);
  if (!every.ok()) return ReportError(every.status(), err);
  options.every = *every;
  auto angle = flags->GetDouble("angle", options.novel_angle_deg);
  if (!angle.ok()) return ReportError(angle.status(), err);
  options.novel_angle_deg = *angle;
  auto mode = view::ParseTextureMode(flags->GetOr("mode", "vdtm"));
  if (!mode.ok()) return ReportError(mode.status(), err);
  options.mode = *mode;
  options.image_dir = flags->GetOr("images", "");
  if (auto status = options.Validate(); !status.ok()) return ReportError(status, err);
  ProgressBar bar(err, !flags->Has("quiet") && !flags->Has("json"));
  auto data = LoadReenactment(*flags, false, &bar);
  bar.Finish();
  if (!data.ok()) return ReportLoadError(data.status(), err);
  bool temporary = false;
  auto take_path = TakePath(*flags, *data, &temporary, &bar);
  bar.Finish();
  auto remove_temporary = [&] {
    std::error_code ec;
    if (temporary && take_path.ok()) std::filesystem::remove(*take_path, ec);
  };
  if (!take_path.ok()) {
    remove_temporary();
    return ReportLoadError(take_path.status(), err);
  }
  auto take = TakeReader::Open(*take_path);
  if (!take.ok()) {
    remove_temporary();
    return ReportLoadError(take.status(), err);
  }
  auto result = view::EvaluateReenactment(*data, **take, options,
                                          [&bar](const Progress& p) { return bar.Update(p); });
  bar.Finish();
  remove_temporary();
  if (!result.ok()) {
    ReportError(result.status(), err);
    return result.status().code() == absl::StatusCode::kInvalidArgument ? kExitUsage : kExitFailure;
  }
  PrintFigures(*result, *data, flags->Has("json"), out);
  return kExitOk;
}

}  // namespace reenact::cli
