#include "server/recon/body/body_method.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/body/model_spec.h"
#include "common/bodyfit/body_fit.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "server/recon/body/body_cloud.h"
#include "server/recon/body/body_texturing.h"
#include "server/recon/body/live_body.h"
#include "server/recon/method_util.h"

namespace reenact::recon {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

v1::Vector3 ToProto(const Eigen::Vector3d& p) {
  v1::Vector3 out;
  out.set_x(p.x());
  out.set_y(p.y());
  out.set_z(p.z());
  return out;
}

// Instants with fewer depth points of the actor are not fitted.
constexpr size_t kMinPoints = 200;

// The body model and its fitter. The fitter refers to the model, which is
// therefore held where it does not move.
struct LoadedModel {
  std::unique_ptr<const body::BodyModel> model;
  std::unique_ptr<bodyfit::BodyFitter> fitter;
};

// The fit of every instant (none where no fit was kept) and its figures.
struct FrameFits {
  std::vector<std::optional<bodyfit::FrameFit>> fits;
  int fitted = 0;
  int reinitialised = 0;     // Fits started again from the skeleton.
  double fit_seconds = 0.0;  // Of the fits kept.
  double rms_sum = 0.0;      // Their point RMS, mm.
};

// How the atlas was made.
struct AtlasFigures {
  double observed_fraction = 0.0;  // Of its surface texels, seen at least once.
  int views = 0;                   // (instant, sensor) images used.
  double seconds = 0.0;            // Baking and encoding.
};

// The mesh of the fitted shape with its atlas.
struct TexturedMesh {
  v1::BodyMesh mesh;
  AtlasFigures atlas;
};

// Wall time of the stages before the fit, seconds.
struct StageSeconds {
  double model = 0.0;
  double clouds = 0.0;
  double shape = 0.0;
};

// The model named by the options and its fitter.
absl::StatusOr<LoadedModel> LoadModel(const BodyMethodOptions& o, const MethodContext& context,
                                      const StageProgress& stages) {
  RETURN_IF_ERROR(stages.Report("model", 0, 1));
  ASSIGN_OR_RETURN(body::BodyModel model, body::LoadAssetModelSpec(o.model, context.asset_roots));
  LoadedModel loaded;
  loaded.model = std::make_unique<const body::BodyModel>(std::move(model));
  ASSIGN_OR_RETURN(loaded.fitter, bodyfit::BodyFitter::Create(*loaded.model, o.fit));
  RETURN_IF_ERROR(stages.Report("model", 1, 1));
  return loaded;
}

// Merged clouds of every instant (thesis 4.3, Fig. 4.3a).
absl::StatusOr<std::vector<bodyfit::PointCloud>> BuildClouds(const TakeFrames& take,
                                                             const StageProgress& stages) {
  ASSIGN_OR_RETURN(const std::unique_ptr<CloudBuilder> builder, CloudBuilder::Create(take));
  const int n = take.num_instants();
  std::vector<bodyfit::PointCloud> clouds(n);
  std::mutex mutex;
  absl::Status first_error;
  std::atomic<int> done{0};
  std::atomic<bool> stop{false};
  take.pool().ParallelFor(0, n, [&](int i) {
    if (stop) return;
    absl::StatusOr<bodyfit::PointCloud> cloud = builder->Build(i);
    std::lock_guard<std::mutex> lock(mutex);
    if (!cloud.ok()) {
      if (first_error.ok()) first_error = cloud.status();
      stop = true;
      return;
    }
    clouds[i] = std::move(*cloud);
    if (!stages.Report("clouds", ++done, n).ok()) stop = true;
  });
  RETURN_IF_ERROR(first_error);
  RETURN_IF_ERROR(stages.Report("clouds", n, n));
  return clouds;
}

// One shape for the take, fitted on instants spread over it; returns them.
absl::StatusOr<std::vector<int>> FitShape(const TakeFrames& take,
                                          const std::vector<bodyfit::PointCloud>& clouds,
                                          int shape_frames, bodyfit::BodyFitter& fitter,
                                          const StageProgress& stages) {
  std::vector<int> usable;
  for (int i = 0; i < take.num_instants(); ++i) {
    if (clouds[i].size() >= kMinPoints && bodyfit::HasTorso(take.instant(i).joints_in_world_m)) {
      usable.push_back(i);
    }
  }
  if (usable.empty()) {
    return absl::InvalidArgumentError(
        "no instant of the take has both a skeleton with a torso and depth points of the actor");
  }
  std::vector<int> shape_instants;
  const int shape_count = std::min<int>(shape_frames, static_cast<int>(usable.size()));
  for (int k = 0; k < shape_count; ++k) {
    shape_instants.push_back(usable[(2 * k + 1) * usable.size() / (2 * shape_count)]);
  }
  std::vector<bodyfit::FitInput> inputs;
  for (int i : shape_instants) {
    bodyfit::FitInput input;
    input.cloud = &clouds[i];
    input.skeleton_m = take.instant(i).joints_in_world_m;
    inputs.push_back(input);
  }
  RETURN_IF_ERROR(stages.Report("shape", 0, 1));
  RETURN_IF_ERROR(fitter.FitShapeFromSkeletons(inputs));
  RETURN_IF_ERROR(stages.Report("shape", 1, 1));
  return shape_instants;
}

// Every instant in order, each from the previous fit (Eq. 4.6 against it).
// InvalidArgument when no instant could be fitted.
absl::StatusOr<FrameFits> FitFrames(const TakeFrames& take,
                                    const std::vector<bodyfit::PointCloud>& clouds,
                                    bodyfit::BodyFitter& fitter, const StageProgress& stages) {
  const int n = take.num_instants();
  FrameFits out;
  out.fits.resize(n);
  std::optional<body::BodyPose> previous;
  for (int i = 0; i < n; ++i) {
    RETURN_IF_ERROR(stages.Report("fit", i, n));
    if (clouds[i].size() < kMinPoints) continue;
    bodyfit::FitInput input;
    input.cloud = &clouds[i];
    input.skeleton_m = take.instant(i).joints_in_world_m;
    const auto frame_start = std::chrono::steady_clock::now();
    // Initialised from the previous frame carried to this instant's
    // skeleton, or from the skeleton alone; started again from the skeleton
    // when the fit lost the body.
    ASSIGN_OR_RETURN(std::optional<bodyfit::BodyFitter::SequenceFit> next,
                     fitter.FitNext(input, previous ? &*previous : nullptr));
    if (!next.has_value()) continue;
    bodyfit::FrameFit fit = std::move(next->fit);
    out.reinitialised += next->restarted ? 1 : 0;
    out.fit_seconds += SecondsSince(frame_start);
    out.rms_sum += fit.point_rms_mm;
    ++out.fitted;
    previous = fit.pose;
    out.fits[i] = std::move(fit);
  }
  RETURN_IF_ERROR(stages.Report("fit", n, n));
  if (out.fitted == 0) return absl::InvalidArgumentError("no instant of the take could be fitted");
  return out;
}

// Texturing (thesis 4.4): the mesh of the fitted shape with the atlas baked
// from the fitted instants.
absl::StatusOr<TexturedMesh> BakeAtlas(const TakeFrames& take, const LoadedModel& loaded,
                                       const FrameFits& fits, const AtlasOptions& options,
                                       const StageProgress& stages) {
  TexturedMesh out;
  ASSIGN_OR_RETURN(out.mesh, MakeBodyMesh(*loaded.model, loaded.fitter->shape(), ""));
  ASSIGN_OR_RETURN(const DecodedBodyMesh decoded, DecodeBodyMesh(out.mesh));
  std::vector<Eigen::Matrix3Xd> posed(fits.fits.size());
  for (size_t i = 0; i < fits.fits.size(); ++i) {
    if (!fits.fits[i]) continue;
    posed[i] = fits.fits[i]->vertices_m;
    if (fits.fits[i]->offsets_m.cols() > 0) posed[i] += fits.fits[i]->offsets_m;
  }
  const auto texture_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const AtlasResult atlas,
                   BakeBodyAtlas(take, decoded, posed, options, stages.ForStage("texture")));
  ASSIGN_OR_RETURN(std::string atlas_jpeg, EncodeJpeg(atlas.atlas, 90));
  out.mesh.set_atlas_jpeg(std::move(atlas_jpeg));
  out.atlas.seconds = SecondsSince(texture_start);
  out.atlas.observed_fraction = atlas.observed_fraction;
  out.atlas.views = atlas.views;
  return out;
}

// The reenactment: the mesh and a frame for every instant, with the run's
// figures.
ReenactmentData AssembleReenactment(const TakeFrames& take, const body::BodyModel& model,
                                    v1::BodyMesh mesh, const FrameFits& fits,
                                    const StageSeconds& seconds, const AtlasFigures& atlas) {
  const int n = take.num_instants();
  const auto& f = fits.fits;
  ReenactmentData data;
  data.body.push_back(std::move(mesh));
  int nearest_fit = -1;
  for (int i = 0; i < n; ++i) {
    if (f[i]) nearest_fit = i;
  }
  for (int i = 0; i < n; ++i) {
    // Instants without a fit take the nearest fitted one's pose, marked invalid.
    int source = i;
    if (!f[i]) {
      int best = -1;
      for (int d = 1; d < n && best < 0; ++d) {
        if (i - d >= 0 && f[i - d])
          best = i - d;
        else if (i + d < n && f[i + d])
          best = i + d;
      }
      source = best >= 0 ? best : nearest_fit;
    }
    data.frames.push_back(BodyFrameToProto(i, take.instant(i).stamp_ns, *f[source], source == i));
  }
  v1::ReenactmentInfo& info = data.info;
  info.set_fps(take.fps());
  auto& figures = *info.mutable_figures();
  figures["fitted_frames"] = fits.fitted;
  figures["reinitialised_frames"] = fits.reinitialised;
  figures["point_rms_mm"] = fits.rms_sum / fits.fitted;
  figures["fit_ms_per_frame"] = 1000.0 * fits.fit_seconds / fits.fitted;
  figures["model_seconds"] = seconds.model;
  figures["clouds_seconds"] = seconds.clouds;
  figures["shape_seconds"] = seconds.shape;
  figures["fit_seconds"] = fits.fit_seconds;
  figures["texture_seconds"] = atlas.seconds;
  figures["atlas_observed_fraction"] = atlas.observed_fraction;
  figures["model_vertices"] = model.num_vertices();
  return data;
}

// The log line of the fitted shape.
std::string ShapeLine(const std::string& model_name, const LoadedModel& loaded,
                      size_t shape_instants, double shape_s) {
  const Eigen::VectorXd& shape = loaded.fitter->shape();
  std::string betas;
  for (int k = 0; k < shape.size(); ++k) {
    absl::StrAppend(&betas, k ? " " : "", absl::StrFormat("%.2f", shape[k]));
  }
  return absl::StrCat("body: model ", model_name, " (", loaded.model->num_vertices(),
                      " vertices), shape [", betas, "] from ", shape_instants, " instants in ",
                      absl::StrFormat("%.2f", shape_s), " s");
}

// The log line of the whole run.
std::string SummaryLine(int instants, const FrameFits& fits, int atlas_px,
                        const AtlasFigures& atlas) {
  return absl::StrFormat(
      "body: %d of %d instants fitted (%d started again from the skeleton), %.1f ms per frame, "
      "point RMS %.2f mm; atlas %d px from %d images (%.0f%% of texels seen) in %.1f s",
      fits.fitted, instants, fits.reinitialised, 1000.0 * fits.fit_seconds / fits.fitted,
      fits.rms_sum / fits.fitted, atlas_px, atlas.views, 100.0 * atlas.observed_fraction,
      atlas.seconds);
}

}  // namespace

absl::Status BodyMethodOptions::Read(OptionReader& reader) {
  RETURN_IF_ERROR(reader.String("model", &model,
                                "body model: procedural, or makehuman:NAME (an asset folder of "
                                "the server's --assets)"));
  RETURN_IF_ERROR(reader.Double("point_weight", &fit.point_weight, 1e-6, 1e6, "w_z of Eq. 4.7"));
  RETURN_IF_ERROR(reader.Double("smoothness_weight", &fit.smoothness_weight, 0, 1e6,
                                "w_r of Eq. 4.7 (pose smoothness, Eq. 4.6)"));
  RETURN_IF_ERROR(reader.Double("skeleton_weight", &fit.skeleton_weight, 0, 1e6,
                                "weight of the sensors' skeleton prior per joint"));
  RETURN_IF_ERROR(
      reader.Int("shape_frames", &fit.shape_frames, 1, 100, "instants the shape is fitted on"));
  RETURN_IF_ERROR(reader.Int("rounds", &fit.rounds, 1, 100, "correspondence rounds per frame"));
  RETURN_IF_ERROR(reader.Int("iterations", &fit.iterations_per_round, 1, 1000,
                             "Levenberg-Marquardt iterations per round"));
  RETURN_IF_ERROR(reader.Int("max_points", &fit.max_points, 10, 1000000, "points per round"));
  RETURN_IF_ERROR(reader.Bool("refine_vertices", &fit.refine_vertices,
                              "fit the free-form mesh of step 2 (Eq. 4.7)"));
  RETURN_IF_ERROR(reader.Int("atlas_px", &atlas.size_px, 16, 8192, "atlas side, pixels"));
  RETURN_IF_ERROR(reader.Double("visibility_m", &atlas.visibility_threshold_m, 1e-4, 10,
                                "visibility threshold T of thesis 4.4, metres"));
  RETURN_IF_ERROR(
      reader.Int("texture_every", &atlas.every, 1, 10000, "use every k-th instant for the atlas"));
  RETURN_IF_ERROR(reader.Int("texture_scale", &atlas.colour_denominator, 1, 8,
                             "decode colour at 1/k for the atlas"));
  RETURN_IF_ERROR(reader.Double("texture_sharpness", &atlas.frontality_power, 0, 64,
                                "p of the cos^p frontality weight of observations"));
  return reader.Double("measured_m", &atlas.measured_threshold_m, 0, 10,
                       "texels must lie this near the sensor's own depth, metres (0: off)");
}

absl::Status BodyMethodOptions::Validate() const {
  if (!body::IsAssetModelSpec(model)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "option model: expected 'procedural' or 'makehuman:NAME' (an asset folder of the "
        "server, no path), got '",
        model.substr(0, 80), "'"));
  }
  RETURN_IF_ERROR(fit.Validate());
  return atlas.Validate();
}

v1::PartFrame BodyFrameToProto(int frame_index, int64_t stamp_ns, const bodyfit::FrameFit& fit,
                               bool valid) {
  v1::PartFrame frame;
  frame.set_frame_index(frame_index);
  frame.set_stamp_ns(stamp_ns);
  *frame.mutable_body() = BodyPoseToProto(fit.pose);
  frame.mutable_body()->set_valid(valid);
  frame.mutable_body()->set_point_rms_mm(static_cast<float>(fit.point_rms_mm));
  if (fit.offsets_m.cols() > 0) SetBodyPoseOffsets(fit.offsets_m, frame.mutable_body());
  for (const Eigen::Vector3d& j : fit.joints_m) *frame.add_joints_in_world_m() = ToProto(j);
  return frame;
}

absl::StatusOr<ReenactmentData> RunBody(const TakeFrames& take, const BodyMethodOptions& o,
                                        const MethodContext& context) {
  RETURN_IF_ERROR(o.Validate());
  const StageProgress stages(
      context.progress,
      {{"model", 0.05}, {"clouds", 0.15}, {"shape", 0.1}, {"fit", 0.45}, {"texture", 0.25}});
  // Stage times from one clock: each is the time since the previous ended.
  const auto start = std::chrono::steady_clock::now();
  StageSeconds seconds;
  ASSIGN_OR_RETURN(const LoadedModel loaded, LoadModel(o, context, stages));
  seconds.model = SecondsSince(start);
  ASSIGN_OR_RETURN(const std::vector<bodyfit::PointCloud> clouds, BuildClouds(take, stages));
  seconds.clouds = SecondsSince(start) - seconds.model;
  ASSIGN_OR_RETURN(const std::vector<int> shape_instants,
                   FitShape(take, clouds, o.fit.shape_frames, *loaded.fitter, stages));
  seconds.shape = SecondsSince(start) - seconds.model - seconds.clouds;
  if (context.log) {
    context.log(ShapeLine(o.model, loaded, shape_instants.size(), seconds.shape));
  }
  ASSIGN_OR_RETURN(const FrameFits fits, FitFrames(take, clouds, *loaded.fitter, stages));
  ASSIGN_OR_RETURN(TexturedMesh textured, BakeAtlas(take, loaded, fits, o.atlas, stages));
  ReenactmentData data = AssembleReenactment(take, *loaded.model, std::move(textured.mesh), fits,
                                             seconds, textured.atlas);
  if (context.log) {
    context.log(SummaryLine(take.num_instants(), fits, o.atlas.size_px, textured.atlas));
  }
  return data;
}

const ReconstructionMethod& BodyMethod() {
  static const TypedMethod<BodyMethodOptions> method(
      {"body",
       "a statistical body model fitted to the merged point clouds, textured into one atlas",
       "ch. 4, Eq. 4.4-4.8",
       /*live=*/true,
       methods::TextureMode::kBodyAtlas,
       {}},
      &RunBody, methods::DescribeOptions<LiveBodyOptions>());
  return method;
}

}  // namespace reenact::recon
