// End-to-end novel-view benchmark (a command, not a Google Benchmark: it
// measures accuracy). For every held-out motion x wardrobe it synthesises a
// 2-sensor take of a random-shape MakeHuman body (sensor skeletons: the
// jittered truth, or with --skeleton tracked none, so that the job tracks
// it as the server does), runs each method configuration in-process as the worker
// does (recon::RunMethod) and measures the reenactment as `reenact eval`
// does (view::EvaluateReenactment: PSNR90, SSIM90 and IoU90 of the view 90
// degrees from sensor 0), beside the ceiling of the same take: a reenactment
// made from the ground truth (clients/view/truth_reenactment.h) of the same
// kind, measured the same way.
//
//   build/bench/novel_view_e2e [--motions 131_04-dance,01_01,09_06-run]
//       [--wardrobes default,solid,print,stripes]
//       [--methods body-same,body-procedural,rigid-carved,rigid-cylinders]
//       [--seconds 2] [--fps 15] [--every 2] [--color-width 1920 --color-height 1080]
//       [--shape random:5] [--work DIR] [--data DIR] [--json FILE]
//       [--skeleton truth|tracked]  (the sensors' skeletons: the jittered
//                        truth, or none, so that the job tracks the take)
//       [--option k=v,...]  (extra options of the body method, e.g. texture_scale=1)
//       [--no-ceilings]  (the methods alone, for quick comparisons)
//       [--figures]  (print each method run's own figures, e.g. part_restarts)
//       [--images DIR]  (every evaluated novel view, reenactment left and truth
//                        right, under DIR/TAKE/WHAT/)
//
// Motions are CMU clips under DATA/mocap/cmu named without extension: NAME.bvh,
// or NAME.amc with the ASF of its subject (the file name's prefix before the
// first '_', e.g. 09_06-run.amc -> 09-run.asf). The defaults are a dance
// (131_04), playground jumps (01_01, its first 2 s) and a run across the
// room (09_06, 1.2 s long); they leave out 131_01, the clip of
// tests/body_fidelity_test.cc, and 131_03 (the body method's segment test).
// Configurations:
//   body-same        method body, model makehuman:makehuman (the model that
//                    made the body); ceiling: the true body with the true
//                    albedo as its atlas (MakeTruthBodyReenactment);
//   body-procedural  method body, model procedural (our template on the
//                    MakeHuman body); same ceiling as body-same;
//   rigid-carved     ceiling: the true mesh cut into 15 rigid parts moving
//                    with the true joints, textured by VDTM from every
//                    colour image (MakeTruthReenactment);
//   rigid-cylinders  the same ceiling with the cylinders' keyframe ranking.
// The body's ceiling draws the true albedo unlit while the truth is lit, so
// a baked atlas (which holds the light the sensors saw) can pass it. Body
// configurations therefore also get "truth geometry": the true posed mesh
// with the atlas our texturing (server/recon/body/body_texturing.h) bakes
// on it from the take, which parts texturing errors from geometry errors
// (geoP, geoS), and the same with the per-frame appearance video baked on
// it too (geoAP, geoAS). Body methods run with their default options, so
// with the appearance video; --option appearance=false measures the static
// atlas alone.
// Takes are cached in --work under a name that holds every synthesis
// setting. A quick run: --seconds 1 --fps 10 --color-width 960
// --color-height 540 --motions 09_06-run --wardrobes solid.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/synthetic_takes.h"
#include "clients/view/evaluation.h"
#include "clients/view/truth_reenactment.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/model_spec.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/synth/synthesizer.h"
#include "server/recon/body/body_texturing.h"
#include "server/recon/methods.h"
#include "server/recon/take_frames.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

struct Settings : bench::TakeSettings {
  std::vector<std::string> motions;
  std::vector<std::string> wardrobes;
  std::vector<std::string> methods;
  // "truth": the sensors carry the jittered true skeleton (a vendor SDK
  // stand-in); "tracked": none, and the job tracks the take with the capture
  // daemon's tracker as the server does (recon::LoadTakeForMethod).
  std::string skeleton = "truth";
  bool ceilings = true;  // False (--no-ceilings): the methods alone.
  bool figures = false;  // --figures: print each run's method figures.
  std::string images;    // Where novel views go (--images); empty: nowhere.
};

// The folder of one evaluation's novel views: the take's name and what was
// measured.
std::string ImagesName(const std::string& take_path, const std::string& what) {
  return fs::path(take_path).stem().string() + "/" + what;
}

// The figures of one reenactment.
struct Score {
  double psnr = NAN, ssim = NAN, iou = NAN;
  double seconds = 0;  // Method run time (0 for a ceiling).
  // A body's appearance video, bytes per second of take (0: none).
  double appearance_bytes_per_s = 0;
};

absl::StatusOr<Settings> ParseSettings(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  std::set<std::string> names = bench::kTakeFlags;
  names.insert({"motions", "wardrobes", "methods", "images", "skeleton"});
  ASSIGN_OR_RETURN(Flags flags, Flags::Parse(args, names, {"no-ceilings", "figures"}));
  Settings s;
  s.work = "/tmp/reenact_novel_view_e2e";
  s.data = REENACT_TEST_DATA_DIR;
  RETURN_IF_ERROR(bench::ReadTakeSettings(flags, &s));
  s.motions = bench::SplitList(flags.GetOr("motions", "131_04-dance,01_01,09_06-run"));
  s.wardrobes = bench::SplitList(flags.GetOr("wardrobes", "default,solid,print,stripes"));
  s.methods = bench::SplitList(
      flags.GetOr("methods", "body-same,body-procedural,rigid-carved,rigid-cylinders"));
  s.ceilings = !flags.Has("no-ceilings");
  s.figures = flags.Has("figures");
  s.images = flags.GetOr("images", "");
  s.skeleton = flags.GetOr("skeleton", "truth");
  if (s.skeleton != "truth" && s.skeleton != "tracked") {
    return absl::InvalidArgumentError("--skeleton must be truth or tracked, not " + s.skeleton);
  }
  for (const std::string& m : s.methods) {
    if (m != "body-same" && m != "body-procedural" && m != "rigid-carved" &&
        m != "rigid-cylinders") {
      return absl::InvalidArgumentError("unknown method configuration " + m);
    }
  }
  return s;
}

// The synthesis options of `motion` (a CMU clip's name) in `wardrobe`.
absl::StatusOr<synth::SynthOptions> TakeOptions(const Settings& s, const std::string& motion,
                                                const std::string& wardrobe) {
  synth::SynthOptions options;
  RETURN_IF_ERROR(bench::SetCmuMotion(s.data, motion, &options));
  options.sensor_skeleton = s.skeleton == "tracked" ? synth::SynthOptions::SensorSkeleton::kNone
                                                    : synth::SynthOptions::SensorSkeleton::kTruth;
  options.body = "makehuman:" + (fs::path(s.data) / "body" / "makehuman").string();
  options.shape = s.shape;
  options.wardrobe = wardrobe;
  options.num_sensors = 2;
  options.seconds = s.seconds;
  options.fps = s.fps;
  options.color_width = s.color_width;
  options.color_height = s.color_height;
  return options;
}

absl::StatusOr<std::string> EnsureTake(const Settings& s, const std::string& motion,
                                       const std::string& wardrobe) {
  ASSIGN_OR_RETURN(const synth::SynthOptions options, TakeOptions(s, motion, wardrobe));
  // Takes with the true skeleton keep the names they had before --skeleton.
  const std::string skeleton = s.skeleton == "tracked" ? "-tracked" : "";
  const std::string path =
      absl::StrFormat("%s/%s-%s%s-%s-%gs-%gfps-%dx%d.mcap", s.work, motion, wardrobe, skeleton,
                      s.shape, s.seconds, s.fps, s.color_width, s.color_height);
  if (fs::exists(path)) return path;
  std::fprintf(stderr, "novel_view_e2e: synthesising %s\n", path.c_str());
  RETURN_IF_ERROR(synth::SynthesizeTake(options, path).status());
  return path;
}

// `images`: a name under --images for the novel views (none without it).
absl::StatusOr<Score> Evaluate(const Reenactment& data, const TakeReader& take, const Settings& s,
                               const std::string& images) {
  view::EvaluationOptions options;
  options.every = s.every;
  options.surface = false;
  options.joints = false;
  if (!s.images.empty()) options.image_dir = (fs::path(s.images) / images).string();
  // A body-model reenactment draws its atlas in either mode; rigid parts
  // by view-dependent texture mapping, as the viewers do.
  options.mode = data.is_body() ? view::TextureMode::kBaked : view::TextureMode::kVdtm;
  ASSIGN_OR_RETURN(const GroundTruth truth,
                   ReadGroundTruth(take, view::EvaluationMeshFrames(data, options)));
  ASSIGN_OR_RETURN(const view::EvaluationResult r, view::EvaluateReenactment(data, truth, options));
  return Score{r.psnr_db_90, r.ssim_90, r.iou_90, 0.0};
}

absl::StatusOr<Score> RunConfiguration(const Settings& s, const std::string& take_path,
                                       const std::string& configuration) {
  recon::MethodInput input;
  input.take_path = take_path;
  input.method = configuration.rfind("body", 0) == 0 ? "body" : configuration;
  if (input.method == "body") {
    for (const auto& [key, value] : s.body_options) input.options[key] = value;
  }
  if (configuration == "body-same") input.options["model"] = "makehuman:makehuman";
  if (configuration == "body-procedural") input.options["model"] = "procedural";
  input.asset_roots = {(fs::path(s.data) / "body").string()};
  const std::string out = (fs::path(s.work) / (configuration + ".reen")).string();
  const auto start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const recon::MethodResult result, recon::RunMethod(input, out));
  if (s.figures) {
    for (const auto& [key, value] : result.figures) std::printf("  %s %g\n", key.c_str(), value);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSIGN_OR_RETURN(const Reenactment data, ReadReenactment(out));
  ASSIGN_OR_RETURN(const auto take, TakeReader::Open(take_path));
  ASSIGN_OR_RETURN(Score score, Evaluate(data, *take, s, ImagesName(take_path, configuration)));
  score.seconds = seconds;
  if (data.is_body() && !data.body->appearance_mp4.empty() && !data.frames.empty()) {
    score.appearance_bytes_per_s = static_cast<double>(data.body->appearance_mp4.size()) *
                                   data.info.fps / static_cast<double>(data.frames.size());
  }
  return score;
}

// The ceiling of `configuration` on the take (see the file comment).
absl::StatusOr<Score> Ceiling(const Settings& s, const std::string& take_path,
                              const body::BodyModel& model, const std::string& configuration) {
  ASSIGN_OR_RETURN(const auto take, TakeReader::Open(take_path));
  if (configuration.rfind("body", 0) == 0) {
    ASSIGN_OR_RETURN(const Reenactment data, view::testing::MakeTruthBodyReenactment(*take, model));
    return Evaluate(data, *take, s, ImagesName(take_path, "ceiling-body"));
  }
  view::testing::TruthReenactmentOptions options;
  options.method = configuration;
  ASSIGN_OR_RETURN(const Reenactment data,
                   view::testing::MakeTruthReenactment(*take, model, options));
  return Evaluate(data, *take, s, ImagesName(take_path, "ceiling-" + configuration));
}

// The true body (MakeTruthBodyReenactment) with the atlas BakeBodyAtlas
// makes of the take on the true posed mesh: first with that static atlas
// alone, then with the per-frame appearance (BakeAppearanceVideo, default
// options) on it too.
struct TruthGeometryScores {
  Score static_atlas, appearance;
};
absl::StatusOr<TruthGeometryScores> TruthGeometry(const Settings& s, const std::string& take_path,
                                                  const body::BodyModel& model) {
  ASSIGN_OR_RETURN(const auto take, TakeReader::Open(take_path));
  ASSIGN_OR_RETURN(Reenactment data, view::testing::MakeTruthBodyReenactment(*take, model));
  ASSIGN_OR_RETURN(const auto frames, recon::TakeFrames::Load(take_path));
  const BodyMesh& mesh = *data.body;
  std::vector<Eigen::Matrix3Xd> posed(frames->num_instants());
  for (size_t f = 0; f < data.frames.size() && f < posed.size(); ++f) {
    ASSIGN_OR_RETURN(body::PosedBody p, PoseBodyMesh(mesh, *data.frames[f].body));
    posed[f] = std::move(p.vertices_m);
  }
  ASSIGN_OR_RETURN(const recon::AtlasResult atlas, recon::BakeBodyAtlas(*frames, mesh, posed));
  ASSIGN_OR_RETURN(std::string jpeg, EncodeJpeg(atlas.atlas, 90));
  data.body->atlas_jpeg = std::move(jpeg);
  TruthGeometryScores scores;
  ASSIGN_OR_RETURN(scores.static_atlas,
                   Evaluate(data, *take, s, ImagesName(take_path, "truth-geometry")));
  const recon::AppearanceOptions appearance;
  const recon::AtlasOptions atlas_options;
  RETURN_IF_ERROR(recon::BakeAppearanceVideo(*frames, posed, atlas.atlas, atlas_options, appearance,
                                             /*crf=*/23, &*data.body));
  ASSIGN_OR_RETURN(scores.appearance,
                   Evaluate(data, *take, s, ImagesName(take_path, "truth-geometry-appearance")));
  return scores;
}

struct Row {
  std::string motion, wardrobe, configuration;
  Score score, ceiling, truth_geometry, truth_appearance;
};

void PrintRow(const Row& row) {
  std::printf(
      "%-13s %-8s %-16s %7.2f %6.3f %6.3f   %7.2f %6.3f %6.3f   %7.2f %6.3f %7.2f %6.3f  %6.1f\n",
      row.motion.c_str(), row.wardrobe.c_str(), row.configuration.c_str(), row.score.psnr,
      row.score.ssim, row.score.iou, row.ceiling.psnr, row.ceiling.ssim, row.ceiling.iou,
      row.truth_geometry.psnr, row.truth_geometry.ssim, row.truth_appearance.psnr,
      row.truth_appearance.ssim, row.score.seconds);
  std::fflush(stdout);
}

// Means per configuration over the rows.
void PrintMeans(const Settings& s, const std::vector<Row>& rows) {
  std::printf("\nmean over %zu motions x %zu wardrobes:\n", s.motions.size(), s.wardrobes.size());
  for (const std::string& configuration : s.methods) {
    Row mean{"all", "all", configuration, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}};
    int n = 0;
    for (const Row& row : rows) {
      if (row.configuration != configuration) continue;
      for (auto [to, from] :
           {std::pair{&mean.score, &row.score}, std::pair{&mean.ceiling, &row.ceiling},
            std::pair{&mean.truth_geometry, &row.truth_geometry},
            std::pair{&mean.truth_appearance, &row.truth_appearance}}) {
        to->psnr += from->psnr, to->ssim += from->ssim, to->iou += from->iou;
        to->seconds += from->seconds;
      }
      ++n;
    }
    if (n == 0) continue;
    for (Score* score :
         {&mean.score, &mean.ceiling, &mean.truth_geometry, &mean.truth_appearance}) {
      score->psnr /= n, score->ssim /= n, score->iou /= n, score->seconds /= n;
    }
    PrintRow(mean);
    double video_bytes_per_s = 0.0;
    for (const Row& row : rows) {
      if (row.configuration == configuration) video_bytes_per_s += row.score.appearance_bytes_per_s;
    }
    if (video_bytes_per_s > 0) {
      std::printf("  %s: appearance video %.0f kB per second of take\n", configuration.c_str(),
                  video_bytes_per_s / n / 1000.0);
    }
  }
}

nlohmann::json ToJson(const Settings& s, const std::vector<Row>& rows) {
  nlohmann::json j = {{"seconds", s.seconds},
                      {"fps", s.fps},
                      {"every", s.every},
                      {"color_width", s.color_width},
                      {"color_height", s.color_height},
                      {"shape", s.shape},
                      {"skeleton", s.skeleton},
                      {"rows", nlohmann::json::array()}};
  const auto finite = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; };
  for (const Row& row : rows) {
    j["rows"].push_back(
        {{"motion", row.motion},
         {"wardrobe", row.wardrobe},
         {"method", row.configuration},
         {"psnr_db_90", finite(row.score.psnr)},
         {"ssim_90", finite(row.score.ssim)},
         {"iou_90", finite(row.score.iou)},
         {"ceiling_psnr_db_90", finite(row.ceiling.psnr)},
         {"ceiling_ssim_90", finite(row.ceiling.ssim)},
         {"ceiling_iou_90", finite(row.ceiling.iou)},
         {"truth_geometry_psnr_db_90", finite(row.truth_geometry.psnr)},
         {"truth_geometry_ssim_90", finite(row.truth_geometry.ssim)},
         {"truth_geometry_appearance_psnr_db_90", finite(row.truth_appearance.psnr)},
         {"truth_geometry_appearance_ssim_90", finite(row.truth_appearance.ssim)},
         {"method_s", row.score.seconds},
         {"appearance_bytes_per_s", row.score.appearance_bytes_per_s}});
  }
  return j;
}

// One take: every configuration and its ceiling.
absl::Status RunTake(const Settings& s, const body::BodyModel& model, const std::string& motion,
                     const std::string& wardrobe, std::vector<Row>* rows) {
  ASSIGN_OR_RETURN(const std::string take, EnsureTake(s, motion, wardrobe));
  std::map<std::string, Score> ceilings;  // Body configurations share one.
  std::optional<TruthGeometryScores> truth_geometry;
  for (const std::string& configuration : s.methods) {
    const std::string kind = configuration.rfind("body", 0) == 0 ? "body" : configuration;
    if (!ceilings.count(kind) && s.ceilings) {
      ASSIGN_OR_RETURN(ceilings[kind], Ceiling(s, take, model, configuration));
    }
    if (kind == "body" && !truth_geometry && s.ceilings) {
      ASSIGN_OR_RETURN(truth_geometry, TruthGeometry(s, take, model));
    }
    Row row{motion, wardrobe, configuration, {}, ceilings[kind], Score{}, Score{}};
    if (truth_geometry && kind == "body") {
      row.truth_geometry = truth_geometry->static_atlas;
      row.truth_appearance = truth_geometry->appearance;
    }
    ASSIGN_OR_RETURN(row.score, RunConfiguration(s, take, configuration));
    PrintRow(row);
    rows->push_back(row);
  }
  return absl::OkStatus();
}

int Run(int argc, char** argv) {
  auto settings = ParseSettings(argc, argv);
  if (!settings.ok()) {
    std::cerr << "novel_view_e2e: " << settings.status().message() << "\n";
    return 2;
  }
  const Settings& s = *settings;
  fs::create_directories(s.work);
  auto model =
      body::LoadBodyModelSpec("makehuman:" + (fs::path(s.data) / "body" / "makehuman").string());
  if (!model.ok()) {
    std::cerr << "novel_view_e2e: the MakeHuman body: " << model.status().message() << "\n";
    return 1;
  }
  std::printf(
      "novel view 90 deg, 2 sensors, %g s at %g fps, colour %dx%d, every %d-th instant, %s "
      "skeletons\n",
      s.seconds, s.fps, s.color_width, s.color_height, s.every, s.skeleton.c_str());
  std::printf("%-13s %-8s %-16s %7s %6s %6s   %7s %6s %6s   %7s %6s %7s %6s  %6s\n", "motion",
              "wardrobe", "method", "PSNR90", "SSIM90", "IoU90", "ceilP", "ceilS", "ceilI", "geoP",
              "geoS", "geoAP", "geoAS", "run_s");
  std::vector<Row> rows;
  for (const std::string& motion : s.motions) {
    for (const std::string& wardrobe : s.wardrobes) {
      if (absl::Status status = RunTake(s, *model, motion, wardrobe, &rows); !status.ok()) {
        std::cerr << "novel_view_e2e: " << motion << " " << wardrobe << ": " << status << "\n";
        return 1;
      }
    }
  }
  PrintMeans(s, rows);
  if (!s.json.empty()) std::ofstream(s.json) << ToJson(s, rows).dump(2) << "\n";
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
