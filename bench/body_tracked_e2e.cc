// End-to-end benchmark of the body method on the skeletons a real capture
// has (a command, not a Google Benchmark: it measures accuracy). For every
// held-out CMU motion it synthesises a 2-sensor take of a random-shape
// MakeHuman body in up to three versions:
//   tracked    the sensors carry no skeleton, as real depth cameras: the job
//              tracks the take with the capture daemon's tracker, as the
//              server does for every take without skeletons
//              (recon::LoadTakeForMethod);
//   truth      the jittered true skeleton (a vendor SDK stand-in): the
//              reference the tracked runs are compared with;
//   perturbed  that skeleton made worse on purpose: 80 mm of noise on the
//              limbs, the arms swapped in 10 % of the frames, the left leg
//              lost for 0.5 s.
// It runs the body method on each with the MakeHuman model ("makehuman",
// the model that made the body) and the procedural model, in-process as a
// worker does (recon::RunMethod), and measures the reenactment as
// `reenact eval` does (view::EvaluateReenactment): MPJPE, surface distance
// and PSNR90 of the view 90 degrees from sensor 0; beside them the share of
// frames whose fitted body faces away from the truth ("turned"), the MPJPE
// of the fitted frames alone split into the six hand joints and the other
// 19 ("hands", "rest"; MPJPE also counts the frames the job could not fit,
// which hold the nearest fit's pose), the mean
// error of the skeletons the job got, the fit time per frame and the
// frames the job marked doubtful (body_diagnosis.h). It prints one row per
// run, then the means and the targets:
//   makehuman, tracked:   MPJPE <= 20 mm, surface <= 6 mm, PSNR90 within
//                         1 dB of the same model on the truth skeleton;
//   procedural, tracked:  MPJPE <= 30 mm, surface <= 9 mm;
//   makehuman, perturbed: MPJPE <= 30 mm.
//
//   build/bench/body_tracked_e2e [--motions 131_04-dance,01_01,09_06-run]
//       [--skeletons tracked,truth,perturbed] [--models makehuman,procedural]
//       [--shape random:5] [--seconds 2] [--fps 15] [--every 2]
//       [--color-width 960 --color-height 540] [--work DIR] [--data DIR]
//       [--json FILE] [--option k=v,...]  (extra options of the body method)
//
// Motions are CMU clips under DATA/mocap/cmu named without extension, as
// novel_view_e2e takes them; the defaults leave out 131_01 and 131_03, the
// clips the body method's tests use. Takes are cached in --work under a
// name that holds every synthesis setting, and a tracked take keeps its
// tracked skeletons beside it.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/synthetic_takes.h"
#include "clients/view/evaluation.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/synth/synthesizer.h"
#include "server/recon/methods.h"
#include "server/recon/take_tracking.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

struct Settings : bench::TakeSettings {
  std::vector<std::string> motions;
  std::vector<std::string> skeletons;
  std::vector<std::string> models;
};

absl::StatusOr<Settings> ParseSettings(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  std::set<std::string> names = bench::kTakeFlags;
  names.insert({"motions", "skeletons", "models"});
  ASSIGN_OR_RETURN(Flags flags, Flags::Parse(args, names, {}));
  Settings s;
  s.color_width = 960;
  s.color_height = 540;
  s.work = "/tmp/reenact_body_tracked_e2e";
  s.data = REENACT_TEST_DATA_DIR;
  RETURN_IF_ERROR(bench::ReadTakeSettings(flags, &s));
  s.motions = bench::SplitList(flags.GetOr("motions", "131_04-dance,01_01,09_06-run"));
  s.skeletons = bench::SplitList(flags.GetOr("skeletons", "tracked,truth,perturbed"));
  s.models = bench::SplitList(flags.GetOr("models", "makehuman,procedural"));
  for (const std::string& k : s.skeletons) {
    if (k != "tracked" && k != "truth" && k != "perturbed") {
      return absl::InvalidArgumentError("unknown skeletons " + k);
    }
  }
  for (const std::string& m : s.models) {
    if (m != "makehuman" && m != "procedural") {
      return absl::InvalidArgumentError("unknown model " + m);
    }
  }
  return s;
}

// The synthesis options of `motion` with `skeletons`.
absl::StatusOr<synth::SynthOptions> TakeOptions(const Settings& s, const std::string& motion,
                                                const std::string& skeletons) {
  synth::SynthOptions options;
  RETURN_IF_ERROR(bench::SetCmuMotion(s.data, motion, &options));
  options.body = "makehuman:" + (fs::path(s.data) / "body" / "makehuman").string();
  options.shape = s.shape;
  options.num_sensors = 2;
  options.seconds = s.seconds;
  options.fps = s.fps;
  options.color_width = s.color_width;
  options.color_height = s.color_height;
  options.sensor_skeleton = skeletons == "tracked" ? synth::SynthOptions::SensorSkeleton::kNone
                                                   : synth::SynthOptions::SensorSkeleton::kTruth;
  if (skeletons == "perturbed") {
    options.skeleton_errors.limb_noise_m = 0.08;
    options.skeleton_errors.arm_swap_fraction = 0.1;
    options.skeleton_errors.leg_drop_s = 0.5;
  }
  return options;
}

absl::StatusOr<std::string> EnsureTake(const Settings& s, const std::string& motion,
                                       const std::string& skeletons) {
  ASSIGN_OR_RETURN(const synth::SynthOptions options, TakeOptions(s, motion, skeletons));
  const std::string path =
      absl::StrFormat("%s/%s-%s-%s-%gs-%gfps-%dx%d.mcap", s.work, motion, skeletons, s.shape,
                      s.seconds, s.fps, s.color_width, s.color_height);
  if (fs::exists(path)) return path;
  std::fprintf(stderr, "body_tracked_e2e: synthesising %s\n", path.c_str());
  RETURN_IF_ERROR(synth::SynthesizeTake(options, path).status());
  return path;
}

// The mean distance of the skeletons a job gets (tracked, or the take's
// own) to the true joints, mm, over every joint they place.
absl::StatusOr<double> SkeletonErrorMm(const std::string& take_path) {
  ASSIGN_OR_RETURN(const auto frames, recon::LoadTakeForMethod(take_path));
  ASSIGN_OR_RETURN(const auto take, TakeReader::Open(take_path));
  ASSIGN_OR_RETURN(const GroundTruth truth, ReadGroundTruth(*take, {}));
  double sum = 0.0;
  int64_t n = 0;
  for (int i = 0; i < frames->num_instants(); ++i) {
    const auto t = truth.joints.find(i);
    if (t == truth.joints.end()) continue;
    const auto& joints = frames->instant(i).joints_in_world_m;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      if (!joints[j].allFinite()) continue;
      sum += 1000.0 * (joints[j] - t->second[j]).norm();
      ++n;
    }
  }
  return n > 0 ? sum / static_cast<double>(n) : NAN;
}

// The share of `data`'s fitted frames whose body faces more than 90
// degrees away from the truth: the torso's forward direction (up x the hips'
// and shoulders' left-to-right) against the true one, about the vertical.
double TurnedAroundShare(const Reenactment& data, const GroundTruth& truth) {
  using J = body::KinectV2Joint;
  const auto forward = [](const auto& joints) {
    const auto at = [&](J j) -> Eigen::Vector3d { return joints[body::Index(j)]; };
    Eigen::Vector3d right =
        at(J::kHipRight) - at(J::kHipLeft) + at(J::kShoulderRight) - at(J::kShoulderLeft);
    return Eigen::Vector3d(-right.z(), 0.0, right.x());  // +Y x right, horizontal.
  };
  int turned = 0, n = 0;
  for (const ReenactmentFrame& frame : data.frames) {
    if (!frame.body || !frame.body->valid || frame.joints_in_world_m.size() != 25) continue;
    const auto t = truth.joints.find(frame.frame_index);
    if (t == truth.joints.end()) continue;
    ++n;
    turned += forward(frame.joints_in_world_m).dot(forward(t->second)) < 0.0 ? 1 : 0;
  }
  return n > 0 ? static_cast<double>(turned) / n : NAN;
}

// The hand joints: hand, hand tip and thumb of each side.
bool IsHandJoint(int j) {
  using J = body::KinectV2Joint;
  for (J hand : {J::kHandLeft, J::kHandRight, J::kHandTipLeft, J::kHandTipRight, J::kThumbLeft,
                 J::kThumbRight}) {
    if (body::Index(hand) == j) return true;
  }
  return false;
}

// MPJPE of `data`'s fitted frames (every `every`-th instant, as the
// evaluation takes them) over the hand joints and over the others, mm.
std::pair<double, double> HandsAndRestMm(const Reenactment& data, const GroundTruth& truth,
                                         int every) {
  double sum[2] = {0.0, 0.0};
  int64_t n[2] = {0, 0};
  for (const ReenactmentFrame& frame : data.frames) {
    if (!frame.body || !frame.body->valid || frame.joints_in_world_m.size() != 25) continue;
    if (frame.frame_index % every != 0) continue;
    const auto t = truth.joints.find(frame.frame_index);
    if (t == truth.joints.end()) continue;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      const int group = IsHandJoint(j) ? 0 : 1;
      sum[group] += 1000.0 * (frame.joints_in_world_m[j] - t->second[j]).norm();
      ++n[group];
    }
  }
  return {n[0] > 0 ? sum[0] / n[0] : NAN, n[1] > 0 ? sum[1] / n[1] : NAN};
}

struct Row {
  std::string motion, skeletons, model;
  double mpjpe_mm = NAN, surface_mm = NAN, psnr_db = NAN;
  // MPJPE of the fitted frames alone, split: the six hand joints (hand,
  // hand tip and thumb of each side) and the other 19.
  double hands_mm = NAN, rest_mm = NAN;
  double turned = NAN;       // Share of fitted frames facing away from the truth.
  double skeleton_mm = NAN;  // The job's skeletons against the truth.
  double fit_ms = NAN;       // Per frame.
  double doubtful_frames = NAN;
  int frames = 0;
};

absl::StatusOr<Row> RunOne(const Settings& s, const std::string& motion,
                           const std::string& skeletons, const std::string& model,
                           const std::string& take_path, double skeleton_mm) {
  recon::MethodInput input;
  input.take_path = take_path;
  input.method = "body";
  input.options = s.body_options;
  input.options["model"] = model == "makehuman" ? "makehuman:makehuman" : "procedural";
  input.asset_roots = {(fs::path(s.data) / "body").string()};
  const std::string out =
      (fs::path(s.work) / absl::StrFormat("%s-%s-%s.reen", motion, skeletons, model)).string();
  ASSIGN_OR_RETURN(const recon::MethodResult result, recon::RunMethod(input, out));
  ASSIGN_OR_RETURN(const Reenactment data, ReadReenactment(out));
  if (!data.info.doubtful_spans.empty()) {
    const DoubtfulSpan& span = data.info.doubtful_spans.front();
    std::fprintf(stderr,
                 "body_tracked_e2e: %s %s %s: %zu doubtful spans, the first frames %d-%d: %s\n",
                 motion.c_str(), skeletons.c_str(), model.c_str(), data.info.doubtful_spans.size(),
                 span.first_frame, span.last_frame, span.reason.c_str());
  }
  ASSIGN_OR_RETURN(const auto take, TakeReader::Open(take_path));
  view::EvaluationOptions options;
  options.every = s.every;
  options.mode = view::TextureMode::kBaked;
  ASSIGN_OR_RETURN(const GroundTruth truth,
                   ReadGroundTruth(*take, view::EvaluationMeshFrames(data, options)));
  ASSIGN_OR_RETURN(const view::EvaluationResult r, view::EvaluateReenactment(data, truth, options));
  Row row{motion, skeletons, model};
  row.turned = TurnedAroundShare(data, truth);
  row.mpjpe_mm = r.mpjpe_mm;
  std::tie(row.hands_mm, row.rest_mm) = HandsAndRestMm(data, truth, s.every);
  row.surface_mm = r.surface_mm;
  row.psnr_db = r.psnr_db_90;
  row.skeleton_mm = skeleton_mm;
  const auto figure = [&](const char* key) {
    const auto it = result.figures.find(key);
    return it == result.figures.end() ? NAN : it->second;
  };
  row.fit_ms = figure("fit_ms_per_frame");
  row.doubtful_frames = figure("doubtful_frames");
  row.frames = result.frames;
  return row;
}

void PrintRow(const Row& r) {
  std::printf("%-13s %-10s %-10s %7.1f %6.1f %6.1f %7.1f %7.2f %6.0f%% %9.1f %7.1f %5.0f/%d\n",
              r.motion.c_str(), r.skeletons.c_str(), r.model.c_str(), r.mpjpe_mm, r.hands_mm,
              r.rest_mm, r.surface_mm, r.psnr_db, 100.0 * r.turned, r.skeleton_mm, r.fit_ms,
              r.doubtful_frames, r.frames);
  std::fflush(stdout);
}

// The mean of `field` over the rows of (skeletons, model); NaN when none.
double Mean(const std::vector<Row>& rows, const std::string& skeletons, const std::string& model,
            double Row::*field) {
  double sum = 0.0;
  int n = 0;
  for (const Row& r : rows) {
    if (r.skeletons != skeletons || r.model != model || !std::isfinite(r.*field)) continue;
    sum += r.*field;
    ++n;
  }
  return n > 0 ? sum / n : NAN;
}

// One target line: "met", "NOT met" or "not measured".
void Target(const char* what, double value, double limit, const char* unit) {
  const char* verdict = !std::isfinite(value) ? "not measured" : value <= limit ? "met" : "NOT met";
  std::printf("  %-52s %7.2f %s (<= %g): %s\n", what, value, unit, limit, verdict);
}

int Run(int argc, char** argv) {
  auto settings = ParseSettings(argc, argv);
  if (!settings.ok()) {
    std::cerr << "body_tracked_e2e: " << settings.status().message() << "\n";
    return 2;
  }
  const Settings& s = *settings;
  fs::create_directories(s.work);
  std::printf(
      "body method, MakeHuman body (%s), 2 sensors, %g s at %g fps, colour %dx%d; novel view 90 "
      "deg, every %d-th instant\n",
      s.shape.c_str(), s.seconds, s.fps, s.color_width, s.color_height, s.every);
  std::printf("%-13s %-10s %-10s %7s %6s %6s %7s %7s %7s %9s %7s %s\n", "motion", "skeletons",
              "model", "MPJPE", "hands", "rest", "surface", "PSNR90", "turned", "skeleton",
              "fit_ms", "doubtful");
  std::vector<Row> rows;
  for (const std::string& motion : s.motions) {
    for (const std::string& skeletons : s.skeletons) {
      auto take = EnsureTake(s, motion, skeletons);
      if (!take.ok()) {
        std::cerr << "body_tracked_e2e: " << motion << ": " << take.status() << "\n";
        return 1;
      }
      auto skeleton_mm = SkeletonErrorMm(*take);
      if (!skeleton_mm.ok()) {
        std::cerr << "body_tracked_e2e: " << motion << " " << skeletons << ": "
                  << skeleton_mm.status() << "\n";
        return 1;
      }
      for (const std::string& model : s.models) {
        auto row = RunOne(s, motion, skeletons, model, *take, *skeleton_mm);
        if (!row.ok()) {
          std::cerr << "body_tracked_e2e: " << motion << " " << skeletons << " " << model << ": "
                    << row.status() << "\n";
          return 1;
        }
        PrintRow(*row);
        rows.push_back(*row);
      }
    }
  }
  std::printf("\nmeans over %zu motions:\n", s.motions.size());
  for (const std::string& skeletons : s.skeletons) {
    for (const std::string& model : s.models) {
      Row mean{"all", skeletons, model};
      mean.mpjpe_mm = Mean(rows, skeletons, model, &Row::mpjpe_mm);
      mean.hands_mm = Mean(rows, skeletons, model, &Row::hands_mm);
      mean.rest_mm = Mean(rows, skeletons, model, &Row::rest_mm);
      mean.surface_mm = Mean(rows, skeletons, model, &Row::surface_mm);
      mean.psnr_db = Mean(rows, skeletons, model, &Row::psnr_db);
      mean.turned = Mean(rows, skeletons, model, &Row::turned);
      mean.skeleton_mm = Mean(rows, skeletons, model, &Row::skeleton_mm);
      mean.fit_ms = Mean(rows, skeletons, model, &Row::fit_ms);
      mean.doubtful_frames = Mean(rows, skeletons, model, &Row::doubtful_frames);
      int frames = 0, n = 0;
      for (const Row& r : rows) {
        if (r.skeletons == skeletons && r.model == model) frames += r.frames, ++n;
      }
      mean.frames = n > 0 ? frames / n : 0;
      PrintRow(mean);
    }
  }
  std::printf("\ntargets:\n");
  Target("makehuman, tracked: MPJPE", Mean(rows, "tracked", "makehuman", &Row::mpjpe_mm), 20.0,
         "mm");
  Target("makehuman, tracked: surface", Mean(rows, "tracked", "makehuman", &Row::surface_mm), 6.0,
         "mm");
  Target("makehuman, tracked: PSNR90 below the truth skeleton's",
         Mean(rows, "truth", "makehuman", &Row::psnr_db) -
             Mean(rows, "tracked", "makehuman", &Row::psnr_db),
         1.0, "dB");
  Target("procedural, tracked: MPJPE", Mean(rows, "tracked", "procedural", &Row::mpjpe_mm), 30.0,
         "mm");
  Target("procedural, tracked: surface", Mean(rows, "tracked", "procedural", &Row::surface_mm), 9.0,
         "mm");
  Target("makehuman, perturbed: MPJPE", Mean(rows, "perturbed", "makehuman", &Row::mpjpe_mm), 30.0,
         "mm");
  if (!s.json.empty()) {
    nlohmann::json j = nlohmann::json::array();
    const auto finite = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; };
    for (const Row& r : rows) {
      j.push_back({{"motion", r.motion},
                   {"skeletons", r.skeletons},
                   {"model", r.model},
                   {"mpjpe_mm", finite(r.mpjpe_mm)},
                   {"hands_mpjpe_mm", finite(r.hands_mm)},
                   {"rest_mpjpe_mm", finite(r.rest_mm)},
                   {"surface_mm", finite(r.surface_mm)},
                   {"psnr_db_90", finite(r.psnr_db)},
                   {"turned_around_share", finite(r.turned)},
                   {"skeleton_mm", finite(r.skeleton_mm)},
                   {"fit_ms_per_frame", finite(r.fit_ms)},
                   {"doubtful_frames", finite(r.doubtful_frames)},
                   {"frames", r.frames}});
    }
    std::ofstream(s.json) << j.dump(2) << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
