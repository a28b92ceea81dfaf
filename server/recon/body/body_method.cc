#include "server/recon/body/body_method.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
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
  const LogCallback& log = context.log;
  const StageProgress stages(
      context.progress,
      {{"model", 0.05}, {"clouds", 0.15}, {"shape", 0.1}, {"fit", 0.45}, {"texture", 0.25}});
  const auto start = std::chrono::steady_clock::now();
  const int n = take.num_instants();

  // The model.
  RETURN_IF_ERROR(stages.Report("model", 0, 1));
  ASSIGN_OR_RETURN(const body::BodyModel model,
                   body::LoadAssetModelSpec(o.model, context.asset_roots));
  ASSIGN_OR_RETURN(std::unique_ptr<bodyfit::BodyFitter> fitter,
                   bodyfit::BodyFitter::Create(model, o.fit));
  RETURN_IF_ERROR(stages.Report("model", 1, 1));
  const double model_s = SecondsSince(start);

  // Merged clouds of every instant (thesis 4.3, Fig. 4.3a).
  ASSIGN_OR_RETURN(const std::unique_ptr<CloudBuilder> builder, CloudBuilder::Create(take));
  std::vector<bodyfit::PointCloud> clouds(n);
  {
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
  }
  const double clouds_s = SecondsSince(start) - model_s;
  constexpr size_t kMinPoints = 200;

  // One shape for the take, fitted on instants spread over it.
  std::vector<int> usable;
  for (int i = 0; i < n; ++i) {
    if (clouds[i].size() >= kMinPoints && bodyfit::HasTorso(take.instant(i).joints_in_world_m)) {
      usable.push_back(i);
    }
  }
  if (usable.empty()) {
    return absl::InvalidArgumentError(
        "no instant of the take has both a skeleton with a torso and depth points of the actor");
  }
  std::vector<int> shape_instants;
  const int shape_count = std::min<int>(o.fit.shape_frames, static_cast<int>(usable.size()));
  for (int k = 0; k < shape_count; ++k) {
    shape_instants.push_back(usable[(2 * k + 1) * usable.size() / (2 * shape_count)]);
  }
  {
    std::vector<bodyfit::FitInput> inputs;
    for (int i : shape_instants) {
      bodyfit::FitInput input;
      input.cloud = &clouds[i];
      input.skeleton_m = take.instant(i).joints_in_world_m;
      inputs.push_back(input);
    }
    RETURN_IF_ERROR(stages.Report("shape", 0, 1));
    RETURN_IF_ERROR(fitter->FitShapeFromSkeletons(inputs));
    RETURN_IF_ERROR(stages.Report("shape", 1, 1));
  }
  const double shape_s = SecondsSince(start) - model_s - clouds_s;
  if (log) {
    std::string betas;
    for (int k = 0; k < fitter->shape().size(); ++k) {
      absl::StrAppend(&betas, k ? " " : "", absl::StrFormat("%.2f", fitter->shape()[k]));
    }
    log(absl::StrCat("body: model ", o.model, " (", model.num_vertices(), " vertices), shape [",
                     betas, "] from ", shape_instants.size(), " instants in ",
                     absl::StrFormat("%.2f", shape_s), " s"));
  }

  // Every instant in order, each from the previous fit (Eq. 4.6 against it).
  std::vector<std::optional<bodyfit::FrameFit>> fits(n);
  std::optional<body::BodyPose> previous;
  double fit_seconds = 0.0, rms_sum = 0.0;
  int fitted = 0, reinitialised = 0;
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
                     fitter->FitNext(input, previous ? &*previous : nullptr));
    if (!next.has_value()) continue;
    bodyfit::FrameFit fit = std::move(next->fit);
    reinitialised += next->restarted ? 1 : 0;
    fit_seconds += SecondsSince(frame_start);
    rms_sum += fit.point_rms_mm;
    ++fitted;
    previous = fit.pose;
    fits[i] = std::move(fit);
  }
  RETURN_IF_ERROR(stages.Report("fit", n, n));
  if (fitted == 0) return absl::InvalidArgumentError("no instant of the take could be fitted");

  // Texturing (thesis 4.4).
  ASSIGN_OR_RETURN(v1::BodyMesh body_mesh, MakeBodyMesh(model, fitter->shape(), ""));
  ASSIGN_OR_RETURN(const DecodedBodyMesh decoded, DecodeBodyMesh(body_mesh));
  std::vector<Eigen::Matrix3Xd> posed(n);
  for (int i = 0; i < n; ++i) {
    if (!fits[i]) continue;
    posed[i] = fits[i]->vertices_m;
    if (fits[i]->offsets_m.cols() > 0) posed[i] += fits[i]->offsets_m;
  }
  const auto texture_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const AtlasResult atlas,
                   BakeBodyAtlas(take, decoded, posed, o.atlas, stages.ForStage("texture")));
  ASSIGN_OR_RETURN(std::string atlas_jpeg, EncodeJpeg(atlas.atlas, 90));
  body_mesh.set_atlas_jpeg(std::move(atlas_jpeg));
  const double texture_s = SecondsSince(texture_start);

  // The reenactment.
  ReenactmentData data;
  data.body.push_back(std::move(body_mesh));
  int nearest_fit = -1;
  for (int i = 0; i < n; ++i) {
    if (fits[i]) nearest_fit = i;
  }
  for (int i = 0; i < n; ++i) {
    // Instants without a fit take the nearest fitted one's pose, marked invalid.
    int source = i;
    if (!fits[i]) {
      int best = -1;
      for (int d = 1; d < n && best < 0; ++d) {
        if (i - d >= 0 && fits[i - d])
          best = i - d;
        else if (i + d < n && fits[i + d])
          best = i + d;
      }
      source = best >= 0 ? best : nearest_fit;
    }
    data.frames.push_back(
        BodyFrameToProto(i, take.instant(i).stamp_ns, *fits[source], source == i));
  }
  v1::ReenactmentInfo& info = data.info;
  info.set_fps(take.fps());
  auto& figures = *info.mutable_figures();
  figures["fitted_frames"] = fitted;
  figures["reinitialised_frames"] = reinitialised;
  figures["point_rms_mm"] = rms_sum / fitted;
  figures["fit_ms_per_frame"] = 1000.0 * fit_seconds / fitted;
  figures["model_seconds"] = model_s;
  figures["clouds_seconds"] = clouds_s;
  figures["shape_seconds"] = shape_s;
  figures["fit_seconds"] = fit_seconds;
  figures["texture_seconds"] = texture_s;
  figures["atlas_observed_fraction"] = atlas.observed_fraction;
  figures["model_vertices"] = model.num_vertices();
  if (log) {
    log(absl::StrFormat(
        "body: %d of %d instants fitted (%d started again from the skeleton), %.1f ms per frame, "
        "point RMS %.2f mm; atlas %d px from %d images (%.0f%% of texels seen) in %.1f s",
        fitted, n, reinitialised, 1000.0 * fit_seconds / fitted, rms_sum / fitted, o.atlas.size_px,
        atlas.views, 100.0 * atlas.observed_fraction, texture_s));
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
