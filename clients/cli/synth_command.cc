// `reenact synth`: writes a synthetic take (common/synth).
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "common/base/flags.h"
#include "common/board/board_spec.h"
#include "common/synth/synthesizer.h"

namespace reenact::cli {
namespace {

// `--board` may stand without a value (the default board): it then gets
// kDefaultBoardSpecText, so that the flag parser sees `--board=SPEC`.
std::vector<std::string> ExpandBareBoardFlag(std::vector<std::string> args) {
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] != "--board") continue;
    const bool bare = i + 1 == args.size() || args[i + 1].rfind("--", 0) == 0;
    if (bare) args[i] = std::string("--board=") + board::kDefaultBoardSpecText;
  }
  return args;
}

}  // namespace

int RunSynth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(ExpandBareBoardFlag(args),
                            {"motion",
                             "asf",
                             "joint-map",
                             "metres-per-unit",
                             "body",
                             "shape",
                             "sensors",
                             "seconds",
                             "fps",
                             "out",
                             "color-width",
                             "color-height",
                             "jpeg-quality",
                             "seed",
                             "distance",
                             "yaw-deg",
                             "lead-in-s",
                             "board",
                             "board-x-m",
                             "board-z-m",
                             "board-yaw-deg",
                             "sensor-skeleton",
                             "wardrobe",
                             "skeleton-limb-noise-mm",
                             "skeleton-arm-swaps",
                             "skeleton-leg-drop-s",
                             "skeleton-lock-on-s",
                             "calibration-error-cm"},
                            {"json", "quiet", "no-depth-noise", "no-mesh"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  synth::SynthOptions options;
  auto out_path = flags->Required("out");
  auto motion = flags->Required("motion");
  auto sensors = flags->GetInt("sensors", options.num_sensors);
  auto seconds = flags->GetDouble("seconds", options.seconds);
  auto fps = flags->GetDouble("fps", options.fps);
  auto width = flags->GetInt("color-width", options.color_width);
  auto height = flags->GetInt("color-height", options.color_height);
  auto quality = flags->GetInt("jpeg-quality", options.jpeg_quality);
  auto distance = flags->GetDouble("distance", options.sensor_distance_m);
  auto yaw_deg = flags->GetDouble("yaw-deg", options.yaw_deg);
  auto lead_in_s = flags->GetDouble("lead-in-s", options.lead_in_s);
  auto board_x_m = flags->GetDouble("board-x-m", options.board_x_m);
  auto board_z_m = flags->GetDouble("board-z-m", options.board_z_m);
  auto board_yaw_deg = flags->GetDouble("board-yaw-deg", options.board_yaw_deg);
  auto metres_per_unit = flags->GetDouble("metres-per-unit", options.metres_per_unit);
  auto limb_noise_mm = flags->GetDouble("skeleton-limb-noise-mm", 0.0);
  auto arm_swaps = flags->GetDouble("skeleton-arm-swaps", 0.0);
  auto leg_drop_s = flags->GetDouble("skeleton-leg-drop-s", 0.0);
  auto lock_on_s = flags->GetDouble("skeleton-lock-on-s", 0.0);
  auto calibration_error_cm = flags->GetDouble("calibration-error-cm", 0.0);
  for (const absl::Status& s : {out_path.status(),
                                motion.status(),
                                sensors.status(),
                                seconds.status(),
                                fps.status(),
                                width.status(),
                                height.status(),
                                quality.status(),
                                distance.status(),
                                yaw_deg.status(),
                                lead_in_s.status(),
                                board_x_m.status(),
                                board_z_m.status(),
                                board_yaw_deg.status(),
                                metres_per_unit.status(),
                                limb_noise_mm.status(),
                                arm_swaps.status(),
                                leg_drop_s.status(),
                                lock_on_s.status(),
                                calibration_error_cm.status()}) {
    if (!s.ok()) return ReportError(s, err);
  }
  if (flags->Has("metres-per-unit") && !(*metres_per_unit > 0)) {
    return ReportError(
        absl::InvalidArgumentError("--metres-per-unit must be a length > 0 (metres)"), err);
  }
  options.motion = *motion;
  options.asf_path = flags->GetOr("asf", "");
  options.joint_map_path = flags->GetOr("joint-map", "");
  options.metres_per_unit = *metres_per_unit;
  options.body = flags->GetOr("body", options.body);
  options.shape = flags->GetOr("shape", options.shape);
  options.wardrobe = flags->GetOr("wardrobe", options.wardrobe);
  options.num_sensors = *sensors;
  options.seconds = *seconds;
  options.fps = *fps;
  options.color_width = *width;
  options.color_height = *height;
  options.jpeg_quality = *quality;
  if (auto seed = flags->Get("seed"); seed && !absl::SimpleAtoi(*seed, &options.seed)) {
    return ReportError(absl::InvalidArgumentError("--seed: not an unsigned integer: " + *seed),
                       err);
  }
  options.sensor_distance_m = *distance;
  options.yaw_deg = *yaw_deg;
  options.lead_in_s = *lead_in_s;
  options.board = flags->GetOr("board", "");
  options.board_x_m = *board_x_m;
  options.board_z_m = *board_z_m;
  options.board_yaw_deg = *board_yaw_deg;
  options.depth_noise.enabled = !flags->Has("no-depth-noise");
  if (const std::string skeleton = flags->GetOr("sensor-skeleton", "none"); skeleton == "truth") {
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  } else if (skeleton != "none") {
    return ReportError(
        absl::InvalidArgumentError("--sensor-skeleton: none (the daemon tracks) or truth, not \"" +
                                   skeleton + "\""),
        err);
  }
  options.skeleton_errors.limb_noise_m = *limb_noise_mm * 1e-3;
  options.skeleton_errors.arm_swap_fraction = *arm_swaps;
  options.skeleton_errors.leg_drop_s = *leg_drop_s;
  options.skeleton_errors.lock_on_s = *lock_on_s;
  options.calibration_error_m = *calibration_error_cm * 1e-2;
  options.ground_truth_mesh = !flags->Has("no-mesh");
  const bool json = flags->Has("json");
  ProgressBar bar(err, !json && !flags->Has("quiet"));
  auto summary = synth::SynthesizeTake(options, *out_path, bar.AsCallback());
  bar.Finish();
  if (!summary.ok()) return ReportError(summary.status(), err);
  if (json) {
    nlohmann::json j = {{"take", *out_path},
                        {"frames", summary->frames},
                        {"sensors", summary->sensors},
                        {"body_vertices", summary->body_vertices},
                        {"body_shape_components", summary->body_shape_components},
                        {"motion_scale", summary->motion_scale},
                        {"bytes", summary->file_bytes},
                        {"elapsed_s", summary->elapsed_s},
                        {"renderer", summary->renderer}};
    out << j.dump(2) << "\n";
  } else {
    out << "wrote " << *out_path << ": " << summary->frames << " frames x " << summary->sensors
        << " sensors, " << summary->file_bytes / 1e6 << " MB in " << summary->elapsed_s << " s ("
        << summary->frames * summary->sensors / std::max(summary->elapsed_s, 1e-9)
        << " sensor-frames/s); body " << summary->body_vertices << " vertices, "
        << summary->body_shape_components << " shape components\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
