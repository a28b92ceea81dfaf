#include "clients/mirror/mirror_cli.h"

#include <cmath>
#include <iostream>
#include <memory>
#include <set>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/mirror/learner_source.h"
#include "clients/mirror/live_learner_source.h"
#include "clients/mirror/mirror_app.h"
#include "clients/sdk/reenactment_source.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/rpc/channel.h"

namespace reenact::mirror {

const char kMirrorUsage[] =
    "usage: reenact-mirror (--teacher ID --server HOST:PORT [--cache DIR]\n"
    "                       | --teacher-file FILE.reen|DIR [--teacher ID])\n"
    "                      (--learner-take FILE.mcap | --daemon HOST:PORT) [--sensor ID]\n"
    "                      [--tls-ca PEM] [--token-file FILE] (server and daemon; else\n"
    "                       $REENACT_TLS_CA, $REENACT_TOKEN)\n"
    "                      [--layout side|ghost] [--ghost-alpha A] [--width W] [--height H]\n"
    "                      [--render-to DIR [--every N] [--no-mp4]] [--report DIR]\n"
    "                      [--repetitions N] [--hold-s S] [--tolerance-deg D]\n"
    "                      [--facing-smoothing-s S] [--dtw]\n"
    "                      [--speed X] [--challenge cycle|hardest [--views DEG,DEG,...]]\n"
    "                      [--seconds S] [--mode vdtm|baked] [--msaa 0|2|4|8] [--fixed-camera]\n"
    "                      [--teacher-joints stored|tracked|tracked-refined]\n"
    "                      [--no-hud] [--json]\n"
    "  The magic mirror: the learner's mirror image with their joints coloured by their\n"
    "  error, beside (side) or under (ghost) the teacher, turned to face the way the\n"
    "  learner faces once they hold still for --hold-s seconds (default 2) within\n"
    "  --tolerance-deg (default 10; the facing is first averaged over\n"
    "  --facing-smoothing-s, default 0.5); then the teacher plays (at --speed) and the\n"
    "  repetition is graded, part by part relative to the spine (--dtw: time-warped).\n"
    "  --report DIR writes rep-NNN.{csv,json,png} per repetition. --repetitions N\n"
    "  (default 1 for a take, 0 = forever for a daemon). --challenge: the mirror picks\n"
    "  the teacher's view (--views, default 0,90,180,-90) in turn or the hardest so far.\n"
    "  Without --render-to: a window (Esc or Q quits); with it, frame_NNNNN.png (every\n"
    "  N-th frame) and video.mp4. --seconds S stops after S seconds of learner time.\n"
    "  --fixed-camera keeps the teacher where the virtual camera puts it instead of\n"
    "  where the learner stands. --msaa (default 4) smooths the teacher's edges; 0 is\n"
    "  about twice as fast on a software OpenGL (llvmpipe). --teacher-joints tracked:\n"
    "  compare with the teacher's joints as the tracker finds them in the teacher drawn\n"
    "  as depth, seen from the learner's side (for a learner tracked from depth: the\n"
    "  same joint definitions on both sides; tracked-refined for reenactd's\n"
    "  --tracker-refine on), instead of the joints the reenactment stores.\n"
    "  --json prints a summary.";

namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

int UsageError(const absl::Status& status, std::ostream& err) {
  err << "reenact-mirror: " << status.message() << "\n" << kMirrorUsage << "\n";
  return kExitUsage;
}

int Failure(const absl::Status& status, std::ostream& err) {
  err << "reenact-mirror: " << status.message() << "\n";
  return kExitFailure;
}

absl::Status CheckSources(const Flags& flags) {
  const bool file = flags.Has("teacher-file");
  if (file == flags.Has("server")) {
    return absl::InvalidArgumentError(
        "give one of --teacher-file FILE.reen or --server HOST:PORT with --teacher ID");
  }
  if (!file && !flags.Has("teacher")) {
    return absl::InvalidArgumentError("--server needs --teacher ID");
  }
  if (flags.Has("learner-take") == flags.Has("daemon")) {
    return absl::InvalidArgumentError("give one of --learner-take FILE.mcap or --daemon HOST:PORT");
  }
  if (!flags.positional().empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("unexpected argument '", flags.positional().front(), "'"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<double>> ParseViews(const std::string& text) {
  std::vector<double> views;
  for (absl::string_view piece : absl::StrSplit(text, ',', absl::SkipEmpty())) {
    double yaw_deg = 0.0;
    if (!absl::SimpleAtod(piece, &yaw_deg) || !std::isfinite(yaw_deg)) {
      return absl::InvalidArgumentError(absl::StrCat("--views: bad angle '", piece, "'"));
    }
    views.push_back(yaw_deg);
  }
  if (views.empty()) return absl::InvalidArgumentError("--views: no angle given");
  return views;
}

absl::StatusOr<ChallengeMode> ParseChallenge(const std::string& name) {
  if (name == "off") return ChallengeMode::kOff;
  if (name == "cycle") return ChallengeMode::kCycle;
  if (name == "hardest") return ChallengeMode::kHardestView;
  return absl::InvalidArgumentError(
      absl::StrCat("--challenge: expected 'cycle' or 'hardest', got '", name, "'"));
}

absl::Status SessionFromFlags(const Flags& flags, MirrorSessionOptions& session) {
  ASSIGN_OR_RETURN(session.repetitions, flags.GetInt("repetitions", flags.Has("daemon") ? 0 : 1));
  ASSIGN_OR_RETURN(session.facing.hold_s, flags.GetDouble("hold-s", session.facing.hold_s));
  ASSIGN_OR_RETURN(session.facing.tolerance_deg,
                   flags.GetDouble("tolerance-deg", session.facing.tolerance_deg));
  ASSIGN_OR_RETURN(session.facing.smoothing_s,
                   flags.GetDouble("facing-smoothing-s", session.facing.smoothing_s));
  ASSIGN_OR_RETURN(session.playback_speed, flags.GetDouble("speed", session.playback_speed));
  session.use_dtw = flags.Has("dtw");
  ASSIGN_OR_RETURN(session.challenge, ParseChallenge(flags.GetOr("challenge", "off")));
  if (flags.Has("views")) {
    ASSIGN_OR_RETURN(session.challenge_view_yaws_deg, ParseViews(*flags.Get("views")));
  }
  session.report_dir = flags.GetOr("report", "");
  return absl::OkStatus();
}

absl::StatusOr<MirrorAppOptions> OptionsFromFlags(const Flags& flags) {
  MirrorAppOptions options;
  RETURN_IF_ERROR(SessionFromFlags(flags, options.session));
  CompositionOptions& composition = options.composition;
  ASSIGN_OR_RETURN(composition.width, flags.GetInt("width", composition.width));
  ASSIGN_OR_RETURN(composition.height, flags.GetInt("height", composition.height));
  ASSIGN_OR_RETURN(composition.layout, ParseMirrorLayout(flags.GetOr("layout", "side")));
  ASSIGN_OR_RETURN(composition.ghost_alpha,
                   flags.GetDouble("ghost-alpha", composition.ghost_alpha));
  composition.hud = !flags.Has("no-hud");
  ASSIGN_OR_RETURN(options.teacher.mode, view::ParseTextureMode(flags.GetOr("mode", "vdtm")));
  ASSIGN_OR_RETURN(options.teacher.msaa_samples,
                   flags.GetInt("msaa", options.teacher.msaa_samples));
  ASSIGN_OR_RETURN(options.teacher_joints,
                   ParseTeacherJoints(flags.GetOr("teacher-joints", "stored")));
  options.follow_learner_position = !flags.Has("fixed-camera");
  options.render_to = flags.GetOr("render-to", "");
  ASSIGN_OR_RETURN(options.png_every, flags.GetInt("every", 1));
  options.mp4 = !flags.Has("no-mp4");
  ASSIGN_OR_RETURN(options.run_seconds, flags.GetDouble("seconds", 0.0));
  RETURN_IF_ERROR(options.Validate());
  return options;
}

absl::StatusOr<Reenactment> LoadTeacher(const Flags& flags, std::ostream& err) {
  std::unique_ptr<client::ReenactmentSource> source;
  if (flags.Has("teacher-file")) {
    ASSIGN_OR_RETURN(source, client::OpenReenactmentSource(*flags.Get("teacher-file")));
  } else {
    ASSIGN_OR_RETURN(
        const rpc::ClientSecurity security,
        rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", "")));
    ASSIGN_OR_RETURN(source,
                     client::OpenReenactmentSource(
                         absl::StrCat("grpc:", *flags.Get("server")),
                         flags.GetOr("cache", client::DefaultReenactmentCacheDir()), security));
  }
  std::string id;
  absl::StatusOr<Reenactment> teacher =
      client::LoadReenactmentOrOnly(*source, flags.GetOr("teacher", ""), "--teacher ID", &id);
  if (teacher.ok())
    err << "reenact-mirror: teacher " << id << " from " << source->Describe() << "\n";
  return teacher;
}

absl::StatusOr<std::unique_ptr<LearnerSource>> OpenLearner(const Flags& flags) {
  const std::string sensor = flags.GetOr("sensor", "");
  if (flags.Has("learner-take")) return OpenTakeLearner(*flags.Get("learner-take"), sensor);
  DaemonFeedOptions options;
  options.connection.address = *flags.Get("daemon");
  ASSIGN_OR_RETURN(
      options.connection.security,
      rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", "")));
  ASSIGN_OR_RETURN(std::unique_ptr<LiveFrameFeed> feed, NewDaemonFrameFeed(options));
  return OpenLiveLearner(std::move(feed), sensor);
}

nlohmann::json OptionalJson(const std::optional<double>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

nlohmann::json CorrectionTexts(const RepetitionReport& report) {
  nlohmann::json texts = nlohmann::json::array();
  if (report.grade) {
    for (const Correction& c : report.grade->corrections) texts.push_back(c.text);
  }
  return texts;
}

nlohmann::json RepetitionsJson(const MirrorAppSummary& summary) {
  nlohmann::json repetitions = nlohmann::json::array();
  for (size_t i = 0; i < summary.reports.size(); ++i) {
    const RepetitionReport& report = summary.reports[i];
    nlohmann::json entry = {{"repetition", report.repetition},
                            {"mean_error_deg", OptionalJson(report.mean_error_deg)},
                            {"coverage", report.coverage},
                            {"corrections", CorrectionTexts(report)},
                            {"learner_facing_yaw_deg", OptionalJson(report.learner_facing_yaw_deg)},
                            {"view_yaw_deg", report.view_yaw_deg},
                            {"teacher_turn_yaw_deg", report.teacher_turn_yaw_deg},
                            {"dtw", report.used_dtw},
                            {"compared_frames", report.frames.size()},
                            {"complete", report.complete},
                            {"learner_frames", report.num_learner_frames},
                            {"input_problems", InputProblems(report)}};
    repetitions.push_back(entry);
  }
  return repetitions;
}

// Mean over the repetitions that compared anything; nullopt when none did.
std::optional<double> OverallMeanDeg(const MirrorAppSummary& summary) {
  double sum = 0.0;
  int count = 0;
  for (const RepetitionReport& report : summary.reports) {
    if (!report.mean_error_deg) continue;
    sum += *report.mean_error_deg;
    ++count;
  }
  if (count == 0) return std::nullopt;
  return sum / count;
}

nlohmann::json SummaryJson(const MirrorAppSummary& summary, const std::string& teacher_id,
                           const std::string& learner) {
  nlohmann::json files = nlohmann::json::array();
  for (const RepetitionFiles& f : summary.report_files) {
    files.push_back(f.csv_path);
    files.push_back(f.json_path);
    files.push_back(f.png_path);
  }
  nlohmann::json means = nlohmann::json::array();
  for (const RepetitionReport& report : summary.reports) {
    means.push_back(OptionalJson(report.mean_error_deg));
  }
  return {{"teacher", teacher_id},
          {"learner", learner},
          {"repetitions_done", summary.reports.size()},
          {"mean_error_deg", OptionalJson(OverallMeanDeg(summary))},
          {"mean_error_deg_per_repetition", means},
          {"repetitions", RepetitionsJson(summary)},
          {"report_files", files},
          {"report_problems", summary.report_problems},
          {"teacher_facing_yaw_world_deg", summary.teacher_facing.facing_yaw_world_deg},
          {"teacher_frames", summary.teacher_frames},
          {"teacher_fps", summary.teacher_fps},
          {"frames", summary.frames},
          {"frames_with_learner", summary.frames_with_learner},
          {"frames_dropped", summary.frames_dropped},
          {"state", std::string(MirrorStateName(summary.final_state))},
          {"stopped", summary.stopped},
          {"pngs", summary.pngs},
          {"first_png", summary.first_png},
          {"mp4", summary.mp4_path},
          {"mp4_problem", summary.mp4_problem},
          {"seconds", summary.seconds},
          {"fps", summary.fps},
          {"render_ms_mean", summary.render_ms_mean},
          {"compose_ms_mean", summary.compose_ms_mean},
          {"output_ms_mean", summary.output_ms_mean},
          {"latency_frames", summary.latency_frames},
          {"teacher_views_tracked", summary.teacher_views_tracked},
          {"teacher_tracking_s", summary.teacher_tracking_s},
          {"latency_ms_mean", summary.latency_ms_mean},
          {"latency_ms_p50", summary.latency_ms_p50},
          {"latency_ms_p95", summary.latency_ms_p95},
          {"latency_ms_max", summary.latency_ms_max},
          {"renderer", summary.renderer}};
}

void PrintSummary(const MirrorAppSummary& summary, std::ostream& err) {
  for (size_t i = 0; i < summary.reports.size(); ++i) {
    const RepetitionReport& report = summary.reports[i];
    err << absl::StrFormat(
        "reenact-mirror: repetition %d%s: mean error %s over %.0f%% of the body seen (facing %s, "
        "teacher turned %+.1f deg)%s\n",
        report.repetition,
        report.complete ? ""
                        : absl::StrFormat(" (cut short after %d of %d teacher frames)",
                                          report.teacher_frames_played, report.num_teacher_frames),
        report.mean_error_deg ? absl::StrFormat("%.1f deg", *report.mean_error_deg) : "-",
        100.0 * report.coverage,
        report.learner_facing_yaw_deg ? absl::StrFormat("%+.1f deg", *report.learner_facing_yaw_deg)
                                      : "-",
        report.teacher_turn_yaw_deg,
        i < summary.report_files.size() ? absl::StrCat(" -> ", summary.report_files[i].json_path)
                                        : "");
    for (const std::string& problem : InputProblems(report)) {
      err << "reenact-mirror:   " << problem << "\n";
    }
    if (!report.grade) continue;
    for (int p = 0; p < kNumBodyParts; ++p) {
      const PartGrade& part = report.grade->parts[p];
      if (!part.graded) {
        err << "reenact-mirror:   not graded: " << PartWords(BodyPartAt(p)) << " ("
            << part.not_graded_reason << ")\n";
      }
    }
    for (const Correction& c : report.grade->corrections) {
      err << "reenact-mirror:   correction: " << c.text << "\n";
    }
  }
  for (const std::string& problem : summary.report_problems) {
    err << "reenact-mirror: report not written: " << problem << "\n";
  }
  err << absl::StrFormat("reenact-mirror: %d frames in %.1f s (%.1f frames/s); stopped: %s\n",
                         summary.frames, summary.seconds, summary.fps, summary.stopped);
  if (summary.latency_frames > 0) {
    err << absl::StrFormat(
        "reenact-mirror: learner to screen %.1f ms median, %.1f ms p95 (from the capture "
        "host's arrival stamp); %d frames dropped\n",
        summary.latency_ms_p50, summary.latency_ms_p95, summary.frames_dropped);
  }
  if (!summary.mp4_path.empty()) err << "reenact-mirror: video " << summary.mp4_path << "\n";
  if (!summary.mp4_problem.empty())
    err << "reenact-mirror: no MP4: " << summary.mp4_problem << "\n";
}

std::set<std::string> ValueFlags() {
  return {"teacher",       "server",     "cache",         "teacher-file",
          "learner-take",  "daemon",     "sensor",        "layout",
          "ghost-alpha",   "width",      "height",        "render-to",
          "every",         "report",     "repetitions",   "hold-s",
          "tolerance-deg", "speed",      "seconds",       "challenge",
          "views",         "mode",       "msaa",          "facing-smoothing-s",
          "tls-ca",        "token-file", "teacher-joints"};
}

std::set<std::string> BoolFlags() {
  return {"dtw", "json", "help", "no-mp4", "fixed-camera", "no-hud"};
}

}  // namespace

int RunMirror(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  absl::StatusOr<Flags> flags = Flags::Parse(args, ValueFlags(), BoolFlags());
  if (!flags.ok()) return UsageError(flags.status(), err);
  if (flags->Has("help")) {
    out << kMirrorUsage << "\n";
    return kExitOk;
  }
  if (absl::Status sources = CheckSources(*flags); !sources.ok()) return UsageError(sources, err);
  absl::StatusOr<MirrorAppOptions> options = OptionsFromFlags(*flags);
  if (!options.ok()) return UsageError(options.status(), err);
  absl::StatusOr<Reenactment> teacher = LoadTeacher(*flags, err);
  if (!teacher.ok()) return Failure(teacher.status(), err);
  absl::StatusOr<std::unique_ptr<LearnerSource>> learner = OpenLearner(*flags);
  if (!learner.ok()) return Failure(learner.status(), err);
  err << "reenact-mirror: learner from " << (*learner)->Describe() << "\n";
  absl::StatusOr<MirrorAppSummary> summary = RunMirrorApp(*teacher, **learner, *options);
  if (!summary.ok()) return Failure(summary.status(), err);
  PrintSummary(*summary, err);
  if (flags->Has("json")) {
    out << SummaryJson(*summary, teacher->info.reenactment_id, (*learner)->Describe()).dump()
        << "\n";
  }
  return kExitOk;
}

}  // namespace reenact::mirror
