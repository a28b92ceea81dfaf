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
#include "clients/viewer/headless_render.h"
#include "clients/viewer/viewer_cli.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::cli {
namespace {

// Where the reenactment comes from: --in FILE, or --reenactment ID on
// --server.
absl::StatusOr<Reenactment> LoadReenactment(const Flags& flags, bool skip_keyframes,
                                            ProgressBar* bar) {
  if (flags.Has("in")) {
    if (flags.Has("reenactment")) {
      return absl::InvalidArgumentError("give either --in FILE or --reenactment ID, not both");
    }
    return ReadReenactment(*flags.Get("in"), skip_keyframes);
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

// `reenact render`: reenact-viewer's headless renderer (PNGs only, numbered
// by instant, over black).
absl::StatusOr<int> RenderFrames(const Reenactment& data, const Flags& flags,
                                 view::TextureMode mode, ProgressBar* bar) {
  viewer::HeadlessOptions options;
  ASSIGN_OR_RETURN(options.width, flags.GetInt("width", 960));
  ASSIGN_OR_RETURN(options.height, flags.GetInt("height", 540));
  ASSIGN_OR_RETURN(std::string out_dir, flags.Required("out"));
  options.camera = flags.GetOr("camera", "orbit:0");
  if (options.camera == "orbit") options.camera = "orbit:0";  // A full turn is the viewer's.
  if (flags.Has("frames")) {
    ASSIGN_OR_RETURN(auto range, viewer::ParseFrameRange(*flags.Get("frames"),
                                                         static_cast<int>(data.frames.size())));
    options.first_frame = range.first;
    options.end_frame = range.second;
  }
  options.mode = mode;
  options.mp4 = false;
  options.name_by_instant = true;
  options.background_srgb = Eigen::Vector3f::Zero();
  ASSIGN_OR_RETURN(viewer::HeadlessSummary summary,
                   viewer::RenderToDir(data, out_dir, options,
                                       [bar](const Progress& p) { return bar->Update(p); }));
  return summary.images;
}

// The take to evaluate against: --take FILE, else downloaded from the server
// by the reenactment's take id into a temporary file (removed by the caller).
absl::StatusOr<std::string> TakePath(const Flags& flags, const Reenactment& data, bool* temporary,
                                     ProgressBar* bar) {
  *temporary = false;
  if (flags.Has("take")) return *flags.Get("take");
  if (data.info.take_id.empty()) {
    return absl::InvalidArgumentError("the reenactment names no take; pass --take FILE");
  }
  ASSIGN_OR_RETURN(client::ConnectionOptions connection,
                   ConnectionFromFlags(flags, "server", kDefaultServer, 60.0));
  const std::string path =
      (std::filesystem::temp_directory_path() /
       absl::StrCat("reenact_eval_", data.info.take_id, "_", ::getpid(), ".mcap"))
          .string();
  *temporary = true;
  RETURN_IF_ERROR(
      client::TakesClient(connection)
          .Download(data.info.take_id, path, [bar](const Progress& p) { return bar->Update(p); })
          .status());
  return path;
}

void PrintFigures(const view::EvaluationResult& result, const Reenactment& data, bool json,
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
    j["reenactment_id"] = data.info.reenactment_id;
    j["take_id"] = data.info.take_id;
    j["method"] = data.info.method;
    out << j.dump(2) << "\n";
    return;
  }
  out << "reenactment " << data.info.reenactment_id << " (" << data.info.method << ") vs take "
      << data.info.take_id << ", " << result.frames_evaluated << " frames\n";
  out << absl::StrFormat("  surface_mm          %8.2f  (accuracy %.2f, completeness %.2f)\n",
                         result.surface_mm, result.surface_accuracy_mm,
                         result.surface_completeness_mm)
      << absl::StrFormat("  psnr_db_90          %8.2f  (%d pixels)\n", result.psnr_db_90,
                         result.psnr_pixels)
      << absl::StrFormat("  ssim_90             %8.3f\n", result.ssim_90)
      << absl::StrFormat("  iou_90              %8.3f\n", result.iou_90)
      << absl::StrFormat("  mpjpe_mm            %8.2f  (%d joints)\n", result.mpjpe_mm,
                         result.mpjpe_joints);
}

}  // namespace

int RunRender(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args,
                            {"server", "timeout", "tls-ca", "token-file", "reenactment", "in",
                             "camera", "out", "width", "height", "frames", "mode"},
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
  auto flags = Flags::Parse(args,
                            {"server", "timeout", "tls-ca", "token-file", "reenactment", "in",
                             "take", "every", "mode", "images", "angle"},
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
  absl::StatusOr<view::EvaluationResult> result = [&]() -> absl::StatusOr<view::EvaluationResult> {
    ASSIGN_OR_RETURN(const GroundTruth truth,
                     ReadGroundTruth(**take, view::EvaluationMeshFrames(*data, options)));
    return view::EvaluateReenactment(*data, truth, options,
                                     [&bar](const Progress& p) { return bar.Update(p); });
  }();
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
