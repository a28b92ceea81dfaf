#include "clients/viewer/viewer_cli.h"

#include <cmath>
#include <iostream>
#include <limits>
#include <memory>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/sdk/reenactment_source.h"
#include "clients/viewer/ar_view.h"
#include "clients/viewer/headless_render.h"
#include "clients/viewer/viewer_app.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/rpc/channel.h"

namespace reenact::viewer {

const char kViewerUsage[] =
    "usage: reenact-viewer (--server HOST:PORT | --in FILE.reen|DIR) [--reenactment ID]\n"
    "                      [--tls-ca PEM] [--token-file FILE] (else $REENACT_TLS_CA,\n"
    "                       $REENACT_TOKEN)\n"
    "                      [--cache DIR] [--list]\n"
    "                      [--render-to DIR [--camera orbit|orbit:DEG|sensor:N|path:FILE]\n"
    "                       [--frames A:B] [--alpha] [--no-mp4] [--fps F]]\n"
    "                      [--width W] [--height H] [--mode vdtm|baked]\n"
    "                      [--speed X] [--no-loop] [--seconds S] [--json]\n"
    "                      [--ar VIDEO|webcam:N [--intrinsics FILE.json | --fov DEG]\n"
    "                       [--board SPEC] [--max-frames N]]\n"
    "  Without --render-to: a window (orbit: drag to turn, wheel to zoom, space play/pause,\n"
    "  left/right step, up/down speed, L loop, R reset view, click the timeline to scrub,\n"
    "  Esc quits). --ar: the teacher over the video where they stood, placed by the printed\n"
    "  board (reenact board --out board.png) seen in each frame; with --render-to, the\n"
    "  composited frames, video.mp4 and poses.csv (the camera against the board) are written.\n"
    "  Reenactments from a server are cached in --cache (default\n"
    "  ~/.cache/reenact).";

namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

int Fail(const absl::Status& status, std::ostream& err) {
  err << "reenact-viewer: " << status.message() << "\n";
  if (status.code() == absl::StatusCode::kInvalidArgument) {
    err << kViewerUsage << "\n";
    return kExitUsage;
  }
  return kExitFailure;
}

absl::StatusOr<std::unique_ptr<client::ReenactmentSource>> OpenSource(const Flags& flags) {
  if (flags.Has("server") == flags.Has("in")) {
    return absl::InvalidArgumentError("give one of --server HOST:PORT or --in FILE|DIR");
  }
  if (flags.Has("in")) return client::OpenReenactmentSource(*flags.Get("in"));
  auto security = rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", ""));
  if (!security.ok()) return security.status();
  return client::OpenReenactmentSource(absl::StrCat("grpc:", *flags.Get("server")),
                                       flags.GetOr("cache", client::DefaultReenactmentCacheDir()),
                                       *security);
}

// The reenactment to show: --reenactment ID, or the source's only one.
absl::StatusOr<Reenactment> LoadChosen(const client::ReenactmentSource& source, const Flags& flags,
                                       bool skip_keyframes, std::ostream& err) {
  std::string id = flags.GetOr("reenactment", "");
  if (id.empty()) {
    ASSIGN_OR_RETURN(std::vector<v1::ReenactmentSummary> list, source.List());
    if (list.size() != 1) {
      return absl::InvalidArgumentError(
          absl::StrCat("--reenactment ID is required: ", source.Describe(), " has ", list.size(),
                       " reenactments (--list shows them)"));
    }
    id = list.front().info().reenactment_id();
  }
  int last_percent = -1;
  return source.Load(id, skip_keyframes, [&](const Progress& p) {
    const int percent = static_cast<int>(100 * p.fraction);
    if (percent / 10 != last_percent / 10) {
      err << "reenact-viewer: loading " << id << " " << percent << "%\n";
      last_percent = percent;
    }
    return true;
  });
}

int List(const client::ReenactmentSource& source, bool json, std::ostream& out, std::ostream& err) {
  absl::StatusOr<std::vector<v1::ReenactmentSummary>> list = source.List();
  if (!list.ok()) return Fail(list.status(), err);
  nlohmann::json array = nlohmann::json::array();
  for (const v1::ReenactmentSummary& s : *list) {
    if (json) {
      array.push_back({{"reenactment_id", s.info().reenactment_id()},
                       {"method", s.info().method()},
                       {"take_id", s.info().take_id()},
                       {"frames", s.info().frame_count()}});
    } else {
      out << absl::StrFormat("%-28s %-16s %5d instants  take %s\n", s.info().reenactment_id(),
                             s.info().method(), s.info().frame_count(), s.info().take_id());
    }
  }
  if (json) out << array.dump() << "\n";
  return kExitOk;
}

absl::StatusOr<HeadlessOptions> HeadlessFromFlags(const Flags& flags, const Reenactment& data,
                                                  view::TextureMode mode) {
  HeadlessOptions options;
  ASSIGN_OR_RETURN(options.width, flags.GetInt("width", 1280));
  ASSIGN_OR_RETURN(options.height, flags.GetInt("height", 720));
  options.camera = flags.GetOr("camera", "orbit");
  options.mode = mode;
  options.alpha = flags.Has("alpha");
  options.mp4 = !flags.Has("no-mp4");
  ASSIGN_OR_RETURN(options.video_fps, flags.GetDouble("fps", 0.0));
  if (flags.Has("frames")) {
    ASSIGN_OR_RETURN(auto range,
                     ParseFrameRange(*flags.Get("frames"), static_cast<int>(data.frames.size())));
    options.first_frame = range.first;
    options.end_frame = range.second;
  }
  RETURN_IF_ERROR(options.Validate());
  return options;
}

int RenderHeadless(const Flags& flags, const Reenactment& data, view::TextureMode mode,
                   std::ostream& out, std::ostream& err) {
  absl::StatusOr<HeadlessOptions> options = HeadlessFromFlags(flags, data, mode);
  if (!options.ok()) return Fail(options.status(), err);
  const std::string dir = *flags.Get("render-to");
  absl::StatusOr<HeadlessSummary> summary = RenderToDir(data, dir, *options);
  if (!summary.ok()) return Fail(summary.status(), err);
  const double fps = summary->render_seconds > 0 ? summary->images / summary->render_seconds : 0.0;
  if (flags.Has("json")) {
    out << nlohmann::json{{"images", summary->images},
                          {"dir", dir},
                          {"mp4", summary->mp4_path},
                          {"mp4_problem", summary->mp4_problem},
                          {"render_fps", fps},
                          {"seconds", summary->total_seconds},
                          {"per_frame_appearance", summary->per_frame_appearance},
                          {"appearance_note", summary->appearance_note}}
               .dump()
        << "\n";
  }
  err << absl::StrFormat("reenact-viewer: %d frames in %s (%.1f frames/s drawn, %.1f s in all)\n",
                         summary->images, dir, fps, summary->total_seconds);
  if (!summary->mp4_path.empty()) err << "reenact-viewer: video " << summary->mp4_path << "\n";
  if (!summary->mp4_problem.empty()) {
    err << "reenact-viewer: no MP4: " << summary->mp4_problem << "\n";
  }
  if (!summary->appearance_note.empty()) {
    err << "reenact-viewer: " << summary->appearance_note << "\n";
  }
  return kExitOk;
}

int RunWindow(const Flags& flags, const Reenactment& data, view::TextureMode mode,
              std::ostream& out, std::ostream& err) {
  WindowOptions options;
  options.mode = mode;
  absl::Status parsed = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(options.width, flags.GetInt("width", 1280));
    ASSIGN_OR_RETURN(options.height, flags.GetInt("height", 720));
    ASSIGN_OR_RETURN(options.speed, flags.GetDouble("speed", 1.0));
    ASSIGN_OR_RETURN(options.run_seconds, flags.GetDouble("seconds", 0.0));
    options.loop = !flags.Has("no-loop");
    return absl::OkStatus();
  }();
  if (!parsed.ok()) return Fail(parsed, err);
  absl::StatusOr<WindowSummary> summary = RunOrbitWindow(data, options);
  if (!summary.ok()) return Fail(summary.status(), err);
  if (flags.Has("json")) {
    out << nlohmann::json{{"frames_shown", summary->frames_shown},
                          {"seconds", summary->seconds},
                          {"fps", summary->fps},
                          {"render_ms_mean", summary->render_ms_mean}}
               .dump()
        << "\n";
  }
  err << absl::StrFormat("reenact-viewer: %d frames in %.1f s (%.1f fps; drawing %.1f ms each)\n",
                         summary->frames_shown, summary->seconds, summary->fps,
                         summary->render_ms_mean);
  return kExitOk;
}

int RunArMode(const Flags& flags, const Reenactment& data, view::TextureMode mode,
              std::ostream& out, std::ostream& err) {
  ArOptions options;
  options.video = *flags.Get("ar");
  options.intrinsics_file = flags.GetOr("intrinsics", "");
  options.board_spec = flags.GetOr("board", "");
  options.render_to = flags.GetOr("render-to", "");
  options.mp4 = !flags.Has("no-mp4");
  options.mode = mode;
  absl::Status parsed = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(options.fov_deg, flags.GetDouble("fov", 65.0));
    ASSIGN_OR_RETURN(options.speed, flags.GetDouble("speed", 1.0));
    ASSIGN_OR_RETURN(options.max_frames, flags.GetInt("max-frames", 0));
    ASSIGN_OR_RETURN(options.run_seconds, flags.GetDouble("seconds", 0.0));
    return options.Validate();
  }();
  if (!parsed.ok()) return Fail(parsed, err);
  absl::StatusOr<ArSummary> summary = RunAr(data, options);
  if (!summary.ok()) return Fail(summary.status(), err);
  if (flags.Has("json")) {
    out << nlohmann::json{{"frames", summary->frames},
                          {"frames_with_board", summary->frames_with_board},
                          {"mean_rms_px", summary->mean_rms_px},
                          {"anchored", summary->anchored},
                          {"board", summary->board_spec},
                          {"poses_csv", summary->poses_csv},
                          {"mp4", summary->mp4_path},
                          {"mp4_problem", summary->mp4_problem},
                          {"fps", summary->fps}}
               .dump()
        << "\n";
  }
  err << absl::StrFormat(
      "reenact-viewer: AR: board %s found in %d of %d frames (mean %.2f px), %.1f frames/s%s\n",
      summary->board_spec, summary->frames_with_board, summary->frames, summary->mean_rms_px,
      summary->fps,
      summary->anchored ? "" : "; the take was not anchored to a board: the teacher stands on it");
  if (!summary->mp4_path.empty()) err << "reenact-viewer: video " << summary->mp4_path << "\n";
  return kExitOk;
}

}  // namespace

absl::StatusOr<std::pair<int, int>> ParseFrameRange(const std::string& text, int frame_count) {
  const std::vector<std::string> pieces = absl::StrSplit(text, ':');
  auto number = [&](const std::string& s, int fallback) -> absl::StatusOr<int> {
    if (s.empty()) return fallback;
    int value = 0;
    if (!absl::SimpleAtoi(s, &value) || value < 0) {
      return absl::InvalidArgumentError(absl::StrCat("--frames: bad instant '", s, "'"));
    }
    return value;
  };
  int begin = 0, end = 0;
  if (pieces.size() == 1) {
    ASSIGN_OR_RETURN(begin, number(pieces[0], 0));
    end = begin + 1;
  } else if (pieces.size() == 2) {
    ASSIGN_OR_RETURN(begin, number(pieces[0], 0));
    ASSIGN_OR_RETURN(end, number(pieces[1], frame_count));
  } else {
    return absl::InvalidArgumentError(absl::StrCat("--frames: expected A:B, got '", text, "'"));
  }
  end = std::min(end, frame_count);
  if (begin >= end) {
    return absl::InvalidArgumentError(
        absl::StrCat("--frames ", text, " selects none of the ", frame_count, " instants"));
  }
  return std::make_pair(begin, end);
}

int RunViewer(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  absl::StatusOr<Flags> flags = Flags::Parse(
      args, {"server",     "in",    "reenactment", "cache",      "render-to", "camera",    "frames",
             "fps",        "width", "height",      "mode",       "speed",     "seconds",   "ar",
             "intrinsics", "fov",   "board",       "max-frames", "tls-ca",    "token-file"},
      {"list", "alpha", "no-mp4", "no-loop", "json", "help"});
  if (!flags.ok()) return Fail(flags.status(), err);
  if (flags->Has("help")) {
    out << kViewerUsage << "\n";
    return kExitOk;
  }
  if (!flags->positional().empty()) {
    return Fail(absl::InvalidArgumentError(
                    absl::StrCat("unexpected argument '", flags->positional().front(), "'")),
                err);
  }
  absl::StatusOr<view::TextureMode> mode = view::ParseTextureMode(flags->GetOr("mode", "vdtm"));
  if (!mode.ok()) return Fail(mode.status(), err);
  absl::StatusOr<std::unique_ptr<client::ReenactmentSource>> source = OpenSource(*flags);
  if (!source.ok()) return Fail(source.status(), err);
  if (flags->Has("list")) return List(**source, flags->Has("json"), out, err);
  const bool skip_keyframes = *mode == view::TextureMode::kBaked;
  absl::StatusOr<Reenactment> data = LoadChosen(**source, *flags, skip_keyframes, err);
  if (!data.ok()) return Fail(data.status(), err);
  if (flags->Has("ar")) return RunArMode(*flags, *data, *mode, out, err);
  if (flags->Has("render-to")) return RenderHeadless(*flags, *data, *mode, out, err);
  return RunWindow(*flags, *data, *mode, out, err);
}

}  // namespace reenact::viewer
