// `reenact tracker train` and `reenact tracker eval`: the body tracker's
// forest trained on depth synthesised from the shared motions and body
// models, and measured on motions and shapes it was not trained on.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "common/base/flags.h"
#include "common/body/motion.h"
#include "common/tracking/forest_training.h"
#include "common/tracking/tracker_evaluation.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;

std::string DefaultDataDir() {
  if (const char* env = std::getenv("REENACT_TEST_DATA_DIR"); env && *env) return env;
  return "../shared/data";
}

// Every motion of `dir` that reads (sorted, so a seed picks the same data).
std::vector<std::string> ReadableMotions(const std::string& dir, std::ostream& err, bool quiet) {
  std::vector<std::string> paths;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.path().extension() == ".bvh") paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<std::string> readable;
  for (const std::string& path : paths) {
    if (absl::StatusOr<body::Motion> m = body::ReadMotion(path); m.ok()) {
      readable.push_back(path);
    } else if (!quiet) {
      err << "reenact tracker: skipping " << path << ": " << m.status().message() << "\n";
    }
  }
  return readable;
}

// The held-out motions: mocap/cmu (BVH and ASF/AMC), none of them in cmu-train.
void HeldOutMotions(const std::string& data, tracking::TrainingDataOptions* o) {
  const std::string cmu = data + "/mocap/cmu/";
  for (const char* bvh : {"01_01.bvh", "131_01.bvh", "131_03.bvh"}) {
    o->motion_paths.push_back(cmu + bvh);
    o->asf_paths.push_back("");
  }
  for (auto [amc, asf] : {std::pair{"07_05-walk.amc", "07-walk.asf"},
                          {"09_06-run.amc", "09-run.asf"},
                          {"131_04-dance.amc", "131-dance.asf"}}) {
    o->motion_paths.push_back(cmu + amc);
    o->asf_paths.push_back(cmu + asf);
  }
}

struct CommonFlags {
  std::string data;
  tracking::TrainingDataOptions images;
};

absl::StatusOr<CommonFlags> ParseCommon(const Flags& flags, int default_images,
                                        uint64_t default_seed) {
  CommonFlags c;
  c.data = flags.GetOr("data", DefaultDataDir());
  auto images = flags.GetInt("images", default_images);
  auto seed = flags.GetInt("seed", static_cast<int>(default_seed));
  auto shapes = flags.GetInt("shapes", c.images.shapes_per_body);
  for (const absl::Status& s : {images.status(), seed.status(), shapes.status()}) {
    if (!s.ok()) return s;
  }
  c.images.num_images = *images;
  c.images.seed = static_cast<uint64_t>(*seed);
  c.images.shapes_per_body = *shapes;
  const std::string makehuman = c.data + "/body/makehuman";
  std::string bodies = flags.GetOr("bodies", "");
  if (bodies.empty()) {
    bodies = fs::exists(makehuman) ? "procedural,makehuman:" + makehuman : "procedural";
  }
  c.images.bodies = absl::StrSplit(bodies, ',', absl::SkipEmpty());
  return c;
}

nlohmann::json ErrorsJson(const tracking::TrackerEvaluation& e) {
  nlohmann::json joints = nlohmann::json::object();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    joints[std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)))] =
        e.all.joint_mean_mm[j];
  }
  return {{"frames", e.all.frames},
          {"mpjpe_mm", e.all.mpjpe_mm},
          {"pck_10cm", e.all.pck},
          {"mean_track_ms", e.mean_track_ms},
          {"joint_mean_mm", joints}};
}

}  // namespace

int RunTrackerTrain(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args,
                            {"out", "data", "images", "seed", "shapes", "bodies", "trees", "depth",
                             "pixels", "features", "threads", "min-samples-leaf", "arm-poses"},
                            {"json", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto common = ParseCommon(*flags, 3000, 1);
  if (!common.ok()) return ReportError(common.status(), err);
  tracking::ForestTrainingOptions forest;
  auto trees = flags->GetInt("trees", forest.num_trees);
  auto depth = flags->GetInt("depth", forest.max_depth);
  auto pixels = flags->GetInt("pixels", forest.pixels_per_image);
  auto features = flags->GetInt("features", forest.features_per_node);
  auto threads = flags->GetInt("threads", forest.threads);
  auto min_leaf = flags->GetInt("min-samples-leaf", forest.min_samples_leaf);
  for (const absl::Status& s : {trees.status(), depth.status(), pixels.status(), features.status(),
                                threads.status(), min_leaf.status()}) {
    if (!s.ok()) return ReportError(s, err);
  }
  forest.min_samples_leaf = *min_leaf;
  forest.num_trees = *trees, forest.max_depth = *depth, forest.pixels_per_image = *pixels;
  forest.features_per_node = *features, forest.threads = *threads;
  forest.seed = common->images.seed;
  auto arm_poses = flags->GetDouble("arm-poses", common->images.arm_pose_fraction);
  if (!arm_poses.ok()) return ReportError(arm_poses.status(), err);
  common->images.arm_pose_fraction = *arm_poses;
  const bool quiet = flags->Has("quiet") || flags->Has("json");
  const std::string out_path = flags->GetOr("out", "models/tracker/body_parts.rtf");
  common->images.motion_paths = ReadableMotions(common->data + "/mocap/cmu-train", err, quiet);
  if (common->images.motion_paths.empty()) {
    return ReportError(absl::NotFoundError(absl::StrCat("no readable motions in ", common->data,
                                                        "/mocap/cmu-train (--data DIR)")),
                       err);
  }
  ProgressBar bar(err, !quiet);
  const auto start = std::chrono::steady_clock::now();
  auto images = tracking::SynthesizeTrainingImages(common->images, false, bar.AsCallback());
  if (!images.ok()) return ReportError(images.status(), err);
  const double synth_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::vector<std::string> names;
  for (const auto& p : common->images.motion_paths) names.push_back(fs::path(p).stem().string());
  const std::string description = absl::StrCat(
      "reenact tracker train: ", images->size(), " images, seed ", common->images.seed, ", bodies ",
      absl::StrJoin(common->images.bodies, " "), " x ", common->images.shapes_per_body,
      " shapes, motions ", absl::StrJoin(names, " "), ", arms posed at random in ",
      common->images.arm_pose_fraction, "; ", forest.num_trees, " trees, depth ", forest.max_depth,
      ", ", forest.pixels_per_image, " px/image, ", forest.features_per_node,
      " features/node, leaves of >= ", forest.min_samples_leaf, " samples");
  tracking::ForestTrainingSummary summary;
  auto trained = tracking::TrainForest(*images, forest, description, &summary, bar.AsCallback());
  if (!trained.ok()) return ReportError(trained.status(), err);
  bar.Finish();
  std::error_code ec;
  if (fs::path(out_path).has_parent_path())
    fs::create_directories(fs::path(out_path).parent_path(), ec);
  if (absl::Status s = trained->Save(out_path); !s.ok()) return ReportError(s, err);
  const nlohmann::json result = {{"out", out_path},
                                 {"images", images->size()},
                                 {"motions", names.size()},
                                 {"samples_per_tree", summary.samples},
                                 {"nodes", summary.nodes},
                                 {"leaves", summary.leaves},
                                 {"max_depth", summary.max_depth},
                                 {"synthesis_s", synth_s},
                                 {"training_s", summary.seconds},
                                 {"bytes", fs::file_size(out_path, ec)},
                                 {"description", description}};
  if (flags->Has("json")) {
    out << result.dump(2) << "\n";
  } else {
    out << "forest " << out_path << ": " << summary.nodes << " nodes, " << summary.leaves
        << " leaves, depth " << summary.max_depth << ", " << result["bytes"] << " bytes\n"
        << images->size() << " images from " << names.size() << " motions synthesised in "
        << synth_s << " s, trained in " << summary.seconds << " s\n";
  }
  return kExitOk;
}

int RunTrackerEval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  for (const std::string& a : args) {
    if (a == "--real" || a.rfind("--real=", 0) == 0) return RunTrackerEvalReal(args, out, err);
  }
  auto flags =
      Flags::Parse(args,
                   {"forest", "model", "data", "images", "seed", "shapes", "bodies", "min-distance",
                    "max-distance", "stride", "motions-dir", "frame-stride"},
                   {"json", "quiet", "sequence", "refine", "no-refine"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto common = ParseCommon(*flags, 300, 1001);
  if (!common.ok()) return ReportError(common.status(), err);
  auto min_d = flags->GetDouble("min-distance", 1.5);
  auto max_d = flags->GetDouble("max-distance", 3.5);
  auto stride = flags->GetInt("stride", 2);
  for (const absl::Status& s : {min_d.status(), max_d.status(), stride.status()}) {
    if (!s.ok()) return ReportError(s, err);
  }
  common->images.min_distance_m = *min_d, common->images.max_distance_m = *max_d;
  common->images.close_up_fraction = 0, common->images.off_centre_fraction = 0;
  common->images.arm_pose_fraction = 0;  // The held-out motions as they are.
  if (flags->Has("motions-dir")) {
    common->images.motion_paths = ReadableMotions(*flags->Get("motions-dir"), err, true);
  } else {
    HeldOutMotions(common->data, &common->images);
  }
  tracking::BodyTrackerOptions options;
  if (const std::optional<std::string> forest = flags->Get("forest")) {
    options.method = tracking::TrackerMethod::kForest;
    options.forest_path = *forest;
  }
  options.model_path = flags->GetOr("model", "");
  options.pixel_stride = *stride;
  options.refine = flags->Has("refine") && !flags->Has("no-refine");
  common->images.sequence = flags->Has("sequence");
  auto frame_stride = flags->GetInt("frame-stride", common->images.frame_stride);
  if (!frame_stride.ok()) return ReportError(frame_stride.status(), err);
  common->images.frame_stride = *frame_stride;
  auto tracker = tracking::BodyTracker::Create(options);
  if (!tracker.ok()) return ReportError(tracker.status(), err);
  auto images = tracking::SynthesizeTrainingImages(common->images, true);
  if (!images.ok()) return ReportError(images.status(), err);
  auto evaluation = tracking::EvaluateTracker(**tracker, *images, common->images.sequence);
  if (!evaluation.ok()) return ReportError(evaluation.status(), err);
  const nlohmann::json result = ErrorsJson(*evaluation);
  if (flags->Has("json")) {
    out << result.dump(2) << "\n";
  } else {
    out << "held-out frames " << evaluation->all.frames << ": MPJPE " << evaluation->all.mpjpe_mm
        << " mm, PCK@10cm " << 100.0 * evaluation->all.pck << " %, " << evaluation->mean_track_ms
        << " ms per frame\n";
    for (const auto& [name, mm] : result["joint_mean_mm"].items()) {
      out << "  " << name << " " << mm.get<double>() << " mm\n";
    }
  }
  return kExitOk;
}

}  // namespace reenact::cli
