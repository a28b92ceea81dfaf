#include "server/recon/body/body_method.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/body/model_spec.h"
#include "common/bodyfit/body_fit.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "reenact/v1/segments.pb.h"
#include "server/recon/body/body_cloud.h"
#include "server/recon/body/body_diagnosis.h"
#include "server/recon/body/body_texturing.h"
#include "server/recon/body/live_body.h"
#include "server/recon/carving/sensor_frame.h"
#include "server/recon/method_util.h"

namespace reenact::recon {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Instants with fewer depth points of the actor are not fitted.
constexpr size_t kMinPoints = 200;
// A fit that explains less of its cloud than this (FrameFit::
// explained_fraction) is kept but marked invalid: no hypothesis found the
// body there.
constexpr double kMinExplainedFraction = 0.5;
// Offline, a fit that explains less than this is tried again from the
// frames after it (FitBackward).
constexpr double kDoubtfulFraction = 0.9;

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
  int reinitialised = 0;       // Fits started again from the skeleton.
  double fit_seconds = 0.0;    // Of the fits kept.
  double rms_sum = 0.0;        // Their point RMS, mm.
  double explained_sum = 0.0;  // Their explained fractions.
  int unexplained = 0;         // Fits below kMinExplainedFraction (marked invalid).
  std::array<int, bodyfit::kNumHypotheses> hypotheses{};  // Fits kept, by their start.
  int backward = 0;  // Fits kept from the backward pass (FitBackward).
  // Per instant, how its fit explains each sensor's view (DiagnoseFits).
  std::vector<std::vector<bodyfit::SensorDiagnosis>> diagnoses;
};

// How the atlas was made.
struct AtlasFigures {
  double observed_fraction = 0.0;  // Of its surface texels, seen at least once.
  int views = 0;                   // (instant, sensor) images used.
  double seconds = 0.0;            // Baking and encoding.
  // Per-frame appearance (none when off).
  int appearance_frames = 0;
  double appearance_observed_fraction = 0.0;  // Mean over frames.
  int64_t appearance_bytes = 0;
  double appearance_seconds = 0.0;  // Baking and encoding.
};

// The mesh of the fitted shape with its atlas.
struct TexturedMesh {
  BodyMesh mesh;
  RgbImage atlas_image;  // The atlas before JPEG.
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

// Merged clouds (thesis 4.3, Fig. 4.3a) of the instants in [first, end);
// the others stay empty.
absl::StatusOr<std::vector<bodyfit::PointCloud>> BuildClouds(const TakeFrames& take,
                                                             const StageProgress& stages, int first,
                                                             int end) {
  ASSIGN_OR_RETURN(const std::unique_ptr<CloudBuilder> builder, CloudBuilder::Create(take));
  const int n = take.num_instants();
  std::vector<bodyfit::PointCloud> clouds(n);
  std::mutex mutex;
  absl::Status first_error;
  std::atomic<int> done{0};
  std::atomic<bool> stop{false};
  const int total = end - first;
  take.pool().ParallelFor(first, end, [&](int i) {
    if (stop) return;
    absl::StatusOr<bodyfit::PointCloud> cloud = builder->Build(i);
    std::lock_guard<std::mutex> lock(mutex);
    if (!cloud.ok()) {
      if (first_error.ok()) first_error = cloud.status();
      stop = true;
      return;
    }
    clouds[i] = std::move(*cloud);
    if (!stages.Report("clouds", ++done, total).ok()) stop = true;
  });
  RETURN_IF_ERROR(first_error);
  RETURN_IF_ERROR(stages.Report("clouds", total, total));
  return clouds;
}

// An instant's merged cloud: built already, or built when first asked for.
using CloudSource = std::function<absl::StatusOr<const bodyfit::PointCloud*>(int instant)>;

// The instants the shape is fitted on: for each of min(shape_frames, n)
// targets spread evenly over the take, the usable instant (a skeleton with
// a torso and enough points) nearest to it, later ones first on a tie. Only
// the clouds of instants looked at are asked for, so that a segmented run
// need not build them all; when every instant is usable the targets
// themselves are chosen.
// False when a sensor's depth at `instant` came without its bytes (a take
// streamed for the prepare phase holds only the instants BodyNeeds names).
bool HasDepthBytes(const Instant& instant) {
  for (const SensorView& view : instant.views) {
    if (view.present && view.depth_data.empty()) return false;
  }
  return true;
}

// The instants whose clouds the shape may be fitted on, in the order
// ChooseShapeInstants looks at them: per target, the first
// kShapeSearchInstants instants with a torso outward from it.
constexpr int kShapeSearchInstants = 8;

int ShapeTarget(int k, int count, int n) {
  return static_cast<int>(int64_t{2 * k + 1} * n / (2 * count));
}

absl::StatusOr<std::vector<int>> ChooseShapeInstants(const TakeFrames& take, int shape_frames,
                                                     const CloudSource& cloud_of) {
  const int n = take.num_instants();
  std::vector<int8_t> usable(n, -1);  // -1: not looked at yet.
  auto is_usable = [&](int i) -> absl::StatusOr<bool> {
    if (usable[i] < 0) {
      bool ok =
          bodyfit::HasTorso(take.instant(i).joints_in_world_m) && HasDepthBytes(take.instant(i));
      if (ok) {
        ASSIGN_OR_RETURN(const bodyfit::PointCloud* cloud, cloud_of(i));
        ok = cloud->size() >= kMinPoints;
      }
      usable[i] = ok ? 1 : 0;
    }
    return usable[i] == 1;
  };
  const int count = std::min(shape_frames, n);
  std::vector<int> chosen;
  std::vector<bool> taken(n, false);
  for (int k = 0; k < count; ++k) {
    const int target = ShapeTarget(k, count, n);
    for (int d = 0; d < n; ++d) {
      int found = -1;
      for (const int i : {target + d, target - d}) {
        if (i < 0 || i >= n || taken[i]) continue;
        ASSIGN_OR_RETURN(const bool ok, is_usable(i));
        if (ok) {
          found = i;
          break;
        }
      }
      if (found >= 0) {
        taken[found] = true;
        chosen.push_back(found);
        break;
      }
    }
  }
  if (chosen.empty()) {
    return absl::InvalidArgumentError(
        "no instant of the take has both a skeleton with a torso and depth points of the actor");
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

// One shape for the take, fitted on instants spread over it; returns them.
absl::StatusOr<std::vector<int>> FitShape(const TakeFrames& take, const CloudSource& cloud_of,
                                          int shape_frames, bodyfit::BodyFitter& fitter,
                                          const StageProgress& stages) {
  ASSIGN_OR_RETURN(const std::vector<int> shape_instants,
                   ChooseShapeInstants(take, shape_frames, cloud_of));
  std::vector<bodyfit::FitInput> inputs;
  for (int i : shape_instants) {
    bodyfit::FitInput input;
    ASSIGN_OR_RETURN(input.cloud, cloud_of(i));
    input.skeleton_m = take.instant(i).joints_in_world_m;
    inputs.push_back(input);
  }
  RETURN_IF_ERROR(stages.Report("shape", 0, 1));
  RETURN_IF_ERROR(fitter.FitShapeFromSkeletons(inputs));
  RETURN_IF_ERROR(stages.Report("shape", 1, 1));
  return shape_instants;
}

// Look-ahead, for a job that has the whole take (the live follow stays
// causal): the instants of [range.first, range.end) that the forward pass
// could not fit (no skeleton yet and no fit before them: a tracker that has
// not found the body) or that it fitted doubtfully (explaining less than
// kDoubtfulFraction of their points), are fitted again backwards, each from
// the fit of the instant after it, hypotheses included (FitNext); the fit
// that explains the points better is kept. A doubtful stretch is thus
// repaired from the frames after it, as the forward pass could only use the
// frames before it. The thesis's sliding window (Eq. 4.7) looks one frame
// each way; this looks as far as the stretch goes, and costs nothing where
// every frame explained its points.
absl::Status FitBackward(const TakeFrames& take, const std::vector<bodyfit::PointCloud>& clouds,
                         bodyfit::BodyFitter& fitter, const SegmentRange& range, FrameFits* out) {
  std::optional<body::BodyPose> next;
  for (int i = range.end - 1; i >= range.first; --i) {
    std::optional<bodyfit::FrameFit>& kept = out->fits[i];
    const bool doubtful = !kept.has_value() || kept->explained_fraction < kDoubtfulFraction;
    if (!doubtful || !next.has_value() || clouds[i].size() < kMinPoints) {
      if (kept.has_value()) next = kept->pose;
      continue;
    }
    bodyfit::FitInput input;
    input.cloud = &clouds[i];
    input.skeleton_m = take.instant(i).joints_in_world_m;
    const auto frame_start = std::chrono::steady_clock::now();
    ASSIGN_OR_RETURN(std::optional<bodyfit::BodyFitter::SequenceFit> back,
                     fitter.FitNext(input, &*next));
    out->fit_seconds += SecondsSince(frame_start);
    if (!back.has_value()) continue;
    if (kept.has_value() && !(back->fit.explanation_cost < kept->explanation_cost)) {
      next = kept->pose;
      continue;
    }
    if (kept.has_value()) {
      // The forward fit is replaced: its share of the figures goes.
      out->rms_sum -= kept->point_rms_mm;
      out->explained_sum -= kept->explained_fraction;
      out->unexplained -= kept->explained_fraction < kMinExplainedFraction ? 1 : 0;
    } else {
      ++out->fitted;
      ++out->hypotheses[static_cast<int>(back->hypothesis)];
    }
    ++out->backward;
    out->rms_sum += back->fit.point_rms_mm;
    out->explained_sum += back->fit.explained_fraction;
    out->unexplained += back->fit.explained_fraction < kMinExplainedFraction ? 1 : 0;
    next = back->fit.pose;
    kept = std::move(back->fit);
  }
  return absl::OkStatus();
}

// How each kept fit of [first, end) explains each sensor's view
// (BodyFitter::DiagnoseFit), in parallel.
absl::Status DiagnoseFits(const TakeFrames& take, const std::vector<bodyfit::PointCloud>& clouds,
                          const bodyfit::BodyFitter& fitter, int first, int end, FrameFits* out) {
  // Each sensor's centre and what its depth image holds.
  std::vector<std::shared_ptr<const carving::PosedCamera>> cameras;
  std::vector<bodyfit::SensorView> views;
  for (const TakeSensor& sensor : take.sensors()) {
    ASSIGN_OR_RETURN(
        carving::PosedCamera camera,
        carving::PosedCamera::Create(sensor.depth_intrinsics, sensor.world_from_depth));
    auto shared = std::make_shared<const carving::PosedCamera>(std::move(camera));
    bodyfit::SensorView view;
    view.centre_m = sensor.world_from_depth.translation;
    view.sees = [shared](const Eigen::Vector3d& p) {
      Eigen::Vector2f pixel;
      return shared->ProjectCameraPoint(shared->ToCamera(p.cast<float>()), &pixel) &&
             pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() < shared->width() &&
             pixel.y() < shared->height();
    };
    views.push_back(std::move(view));
  }
  out->diagnoses.assign(out->fits.size(), {});
  take.pool().ParallelFor(first, end, [&](int i) {
    if (!out->fits[i]) return;
    out->diagnoses[i] = fitter.DiagnoseFit(*out->fits[i], clouds[i], views);
  });
  return absl::OkStatus();
}

// The instants of `range` in order, each from the previous fit (Eq. 4.6
// against it), beginning at range.warmup_first; the fits before range.first
// only carry the motion into the range and are neither kept nor counted.
absl::StatusOr<FrameFits> FitFrames(const TakeFrames& take,
                                    const std::vector<bodyfit::PointCloud>& clouds,
                                    bodyfit::BodyFitter& fitter, const StageProgress& stages,
                                    const SegmentRange& range, bool look_ahead) {
  const int n = take.num_instants();
  FrameFits out;
  out.fits.resize(n);
  std::optional<body::BodyPose> previous;
  const int total = range.end - range.warmup_first;
  for (int i = range.warmup_first; i < range.end; ++i) {
    RETURN_IF_ERROR(stages.Report("fit", i - range.warmup_first, total));
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
    previous = fit.pose;
    if (i < range.first) continue;
    out.reinitialised += next->restarted ? 1 : 0;
    out.fit_seconds += SecondsSince(frame_start);
    out.rms_sum += fit.point_rms_mm;
    out.explained_sum += fit.explained_fraction;
    out.unexplained += fit.explained_fraction < kMinExplainedFraction ? 1 : 0;
    ++out.hypotheses[static_cast<int>(next->hypothesis)];
    ++out.fitted;
    out.fits[i] = std::move(fit);
  }
  if (look_ahead) RETURN_IF_ERROR(FitBackward(take, clouds, fitter, range, &out));
  RETURN_IF_ERROR(DiagnoseFits(take, clouds, fitter, range.first, range.end, &out));
  RETURN_IF_ERROR(stages.Report("fit", total, total));
  return out;
}

// The whole take's fits: InvalidArgument when no instant could be fitted.
absl::StatusOr<FrameFits> FitAllFrames(const TakeFrames& take,
                                       const std::vector<bodyfit::PointCloud>& clouds,
                                       bodyfit::BodyFitter& fitter, const StageProgress& stages,
                                       bool look_ahead) {
  ASSIGN_OR_RETURN(FrameFits fits, FitFrames(take, clouds, fitter, stages,
                                             {0, take.num_instants(), 0}, look_ahead));
  if (fits.fitted == 0) return absl::InvalidArgumentError("no instant of the take could be fitted");
  return fits;
}

// The posed vertices of every fitted instant (offsets of step 2 added);
// empty for the others.
std::vector<Eigen::Matrix3Xd> PosedVertices(const FrameFits& fits) {
  std::vector<Eigen::Matrix3Xd> posed(fits.fits.size());
  for (size_t i = 0; i < fits.fits.size(); ++i) {
    if (!fits.fits[i]) continue;
    posed[i] = fits.fits[i]->vertices_m;
    if (fits.fits[i]->offsets_m.cols() > 0) posed[i] += fits.fits[i]->offsets_m;
  }
  return posed;
}

// The frame of every fitted instant; none for the others.
std::vector<std::optional<ReenactmentFrame>> FittedFrames(const TakeFrames& take,
                                                          const FrameFits& fits) {
  std::vector<std::optional<ReenactmentFrame>> frames(fits.fits.size());
  for (size_t i = 0; i < fits.fits.size(); ++i) {
    if (!fits.fits[i]) continue;
    const int index = static_cast<int>(i);
    const bool explained = fits.fits[i]->explained_fraction >= kMinExplainedFraction;
    frames[i] = BodyFrame(index, take.instant(index).stamp_ns, *fits.fits[i], explained);
    if (i < fits.diagnoses.size()) {
      for (const bodyfit::SensorDiagnosis& d : fits.diagnoses[i]) {
        frames[i]->body->sensor_fits.push_back(
            {d.sensor, d.points, static_cast<float>(d.explained_fraction()),
             static_cast<float>(d.rms_mm), static_cast<float>(d.surface_seen_fraction())});
      }
    }
  }
  return frames;
}

// Texturing (thesis 4.4): the mesh of the fitted shape with the atlas baked
// from the fitted instants.
absl::StatusOr<TexturedMesh> BakeAtlas(const TakeFrames& take, const LoadedModel& loaded,
                                       const FrameFits& fits, const AtlasOptions& options,
                                       const StageProgress& stages) {
  TexturedMesh out;
  ASSIGN_OR_RETURN(out.mesh, BuildBodyMesh(*loaded.model, loaded.fitter->shape(), ""));
  const auto texture_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const AtlasResult atlas, BakeBodyAtlas(take, out.mesh, PosedVertices(fits),
                                                          options, stages.ForStage("texture")));
  ASSIGN_OR_RETURN(out.mesh.atlas_jpeg, EncodeJpeg(atlas.atlas, 90));
  out.atlas_image = atlas.atlas;
  out.atlas.seconds = SecondsSince(texture_start);
  out.atlas.observed_fraction = atlas.observed_fraction;
  out.atlas.views = atlas.views;
  return out;
}

// Per-frame appearance: every instant's atlas encoded as a video into the
// mesh's AppearanceVideo (BakeAppearanceVideo).
absl::Status BakeAppearance(const TakeFrames& take, const FrameFits& fits,
                            const BodyMethodOptions& o, const StageProgress& stages,
                            TexturedMesh* textured) {
  const auto start = std::chrono::steady_clock::now();
  AppearanceFigures figures;
  RETURN_IF_ERROR(BakeAppearanceVideo(take, PosedVertices(fits), textured->atlas_image, o.atlas,
                                      o.appearance_options, o.appearance_crf, &textured->mesh,
                                      stages.ForStage("appearance"), &figures));
  AtlasFigures& out = textured->atlas;
  out.appearance_frames = figures.frames;
  out.appearance_observed_fraction = figures.mean_observed_fraction;
  out.appearance_bytes = static_cast<int64_t>(textured->mesh.appearance_mp4.size());
  out.appearance_seconds = SecondsSince(start);
  return absl::OkStatus();
}

// What the reenactment's figures sum over the fits.
struct FitFigures {
  int fitted = 0;
  int reinitialised = 0;
  double fit_seconds = 0.0;
  double rms_sum = 0.0;
  double explained_sum = 0.0;
  int unexplained = 0;
  std::array<int, bodyfit::kNumHypotheses> hypotheses{};
};

FitFigures FiguresOf(const FrameFits& fits) {
  return {fits.fitted,        fits.reinitialised, fits.fit_seconds, fits.rms_sum,
          fits.explained_sum, fits.unexplained,   fits.hypotheses};
}

// The reenactment: the mesh and a frame for every instant (`frames`: those
// of the fitted instants), with the run's figures.
Reenactment AssembleReenactment(const TakeFrames& take, const body::BodyModel& model, BodyMesh mesh,
                                const std::vector<std::optional<ReenactmentFrame>>& f,
                                const FitFigures& fits, const StageSeconds& seconds,
                                const AtlasFigures& atlas) {
  const int n = take.num_instants();
  Reenactment data;
  data.body = std::move(mesh);
  int nearest_fit = -1;
  for (int i = 0; i < n; ++i) {
    if (f[i]) nearest_fit = i;
  }
  for (int i = 0; i < n; ++i) {
    if (f[i]) {
      data.frames.push_back(*f[i]);
      continue;
    }
    // Instants without a fit take the nearest fitted one's pose, marked invalid.
    int best = -1;
    for (int d = 1; d < n && best < 0; ++d) {
      if (i - d >= 0 && f[i - d])
        best = i - d;
      else if (i + d < n && f[i + d])
        best = i + d;
    }
    ReenactmentFrame frame = *f[best >= 0 ? best : nearest_fit];
    frame.frame_index = i;
    frame.stamp_ns = take.instant(i).stamp_ns;
    frame.body->valid = false;
    frame.body->sensor_fits.clear();
    data.frames.push_back(std::move(frame));
  }
  ReenactmentInfo& info = data.info;
  info.fps = take.fps();
  auto& figures = info.figures;
  // Where the sensors contradict the fits (body_diagnosis.h).
  std::vector<std::string> sensor_ids;
  for (const TakeSensor& sensor : take.sensors()) sensor_ids.push_back(sensor.sensor_id);
  info.doubtful_spans = FindDoubtfulSpans(data.frames, sensor_ids);
  AddDiagnosisFigures(data.frames, sensor_ids, info.doubtful_spans, &figures);
  figures["fitted_frames"] = fits.fitted;
  figures["reinitialised_frames"] = fits.reinitialised;
  figures["point_rms_mm"] = fits.rms_sum / fits.fitted;
  // How well the fits explain what the sensors saw: the mean share of
  // points within explained_m of the body, the frames that explain too
  // little (marked invalid), and where the kept fits started.
  figures["explained_fraction"] = fits.explained_sum / fits.fitted;
  figures["unexplained_frames"] = fits.unexplained;
  for (int h = 0; h < bodyfit::kNumHypotheses; ++h) {
    figures[absl::StrCat("hypothesis_",
                         bodyfit::HypothesisName(static_cast<bodyfit::Hypothesis>(h)))] =
        fits.hypotheses[h];
  }
  figures["fit_ms_per_frame"] = 1000.0 * fits.fit_seconds / fits.fitted;
  figures["model_seconds"] = seconds.model;
  figures["clouds_seconds"] = seconds.clouds;
  figures["shape_seconds"] = seconds.shape;
  figures["fit_seconds"] = fits.fit_seconds;
  figures["texture_seconds"] = atlas.seconds;
  figures["atlas_observed_fraction"] = atlas.observed_fraction;
  if (atlas.appearance_frames > 0) {
    figures["appearance_seconds"] = atlas.appearance_seconds;
    figures["appearance_observed_fraction"] = atlas.appearance_observed_fraction;
    figures["appearance_bytes_per_second"] =
        static_cast<double>(atlas.appearance_bytes) * take.fps() / atlas.appearance_frames;
  }
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

// The log line of the look-ahead (FitBackward), of a run or a segment.
std::string LookAheadLine(int backward) {
  return absl::StrFormat(
      "body: look-ahead: %d frames fitted again backwards from the frames after them", backward);
}

// The log line of the whole run.
std::string SummaryLine(int instants, const FitFigures& fits, int atlas_px,
                        const AtlasFigures& atlas) {
  return absl::StrFormat(
      "body: %d of %d instants fitted (%d started again from the skeleton, %d from arms and %d "
      "from legs swapped, %d from the previous fit alone), %.1f ms per frame, point RMS %.2f mm, "
      "%.1f%% of points explained, %d frames explaining too little; atlas %d px from %d images "
      "(%.0f%% of texels seen) in %.1f s",
      fits.fitted, instants, fits.reinitialised,
      fits.hypotheses[static_cast<int>(bodyfit::Hypothesis::kArmsSwapped)],
      fits.hypotheses[static_cast<int>(bodyfit::Hypothesis::kLegsSwapped)],
      fits.hypotheses[static_cast<int>(bodyfit::Hypothesis::kPrevious)],
      1000.0 * fits.fit_seconds / fits.fitted, fits.rms_sum / fits.fitted,
      100.0 * fits.explained_sum / fits.fitted, fits.unexplained, atlas_px, atlas.views,
      100.0 * atlas.observed_fraction, atlas.seconds);
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
  RETURN_IF_ERROR(reader.Bool("hypotheses", &fit.hypotheses,
                              "start each frame from several poses (the previous fit, the "
                              "skeleton, its arms or legs swapped) and keep the fit that explains "
                              "the points best"));
  RETURN_IF_ERROR(reader.Double("explained_m", &fit.explained_m, 0.005, 0.5,
                                "a point within this of the body is explained, metres"));
  RETURN_IF_ERROR(reader.Bool("look_ahead", &look_ahead,
                              "fit the frames the forward pass could not fit, or fitted "
                              "doubtfully, again backwards from the frames after them"));
  RETURN_IF_ERROR(reader.Int("atlas_px", &atlas.size_px, 16, 8192, "atlas side, pixels"));
  RETURN_IF_ERROR(reader.Double("visibility_m", &atlas.visibility_threshold_m, 1e-4, 10,
                                "visibility threshold T of thesis 4.4, metres"));
  RETURN_IF_ERROR(
      reader.Int("texture_every", &atlas.every, 1, 10000, "use every k-th instant for the atlas"));
  RETURN_IF_ERROR(reader.Int("texture_scale", &atlas.colour_denominator, 1, 8,
                             "decode colour at 1/k for the atlas"));
  RETURN_IF_ERROR(reader.Double("texture_sharpness", &atlas.frontality_power, 0, 64,
                                "p of the cos^p frontality weight of observations"));
  RETURN_IF_ERROR(
      reader.Double("measured_m", &atlas.measured_threshold_m, 0, 10,
                    "texels must lie this near the sensor's own depth, metres (0: off)"));
  RETURN_IF_ERROR(reader.Bool("appearance", &appearance,
                              "per-frame appearance: every instant's atlas from what the sensors "
                              "saw then, stored as an H.264 video (off: the static atlas alone)"));
  RETURN_IF_ERROR(reader.Int("appearance_px", &appearance_options.size_px, 16, 4096,
                             "side of each instant's atlas in the appearance video, pixels"));
  RETURN_IF_ERROR(reader.Int("appearance_window", &appearance_options.window, 0, 16,
                             "instants either side blended into each instant's atlas"));
  RETURN_IF_ERROR(reader.Double("appearance_prior", &appearance_options.prior_weight, 1e-6, 1e6,
                                "weight of the static atlas in each instant's, in frontal "
                                "observations"));
  RETURN_IF_ERROR(reader.Int("appearance_crf", &appearance_crf, 0, 51,
                             "H.264 constant rate factor of the appearance video"));
  return reader.Double("segment_warmup_s", &segment_warmup_s, 0, 60,
                       "a take split across workers: each segment's fit starts this long "
                       "before its first instant, seconds (those fits are not kept)");
}

int64_t BodyMethodOptions::MemoryBytes(const TakeSize& take) const {
  // A body model of up to 30,000 vertices (the MakeHuman assets have
  // fewer), with its shape and pose blend data.
  constexpr int64_t kVertices = 30000;
  constexpr int64_t kModelBytes = 128 * memory::kMiB;
  const int64_t instants = take.Instants(0);
  const int64_t sensors = std::max(take.sensors, 1);
  // Each instant's fit: pose, joints and the posed mesh with its vertex
  // offsets (positions, normals, offsets).
  const int64_t fits = instants * (kVertices * 36 + 16 * 1024);
  // The shape's instants: every sensor's cloud (a point and a normal for
  // each depth pixel) and the fit's correspondences.
  const int64_t shape = int64_t{fit.shape_frames} * sensors * memory::kDepthPixels * 24 +
                        int64_t{fit.max_points} * fit.rounds * 256;
  // The atlas: colour sums and weights, the texel-to-surface map, the image
  // and its JPEG; each thread decodes its colour at 1/texture_scale.
  const int64_t side = atlas.size_px;
  const int64_t atlas_bytes = side * side * 40;
  // The appearance: a window of instants' observations (sparse, at most a
  // texel each), the sums and the frame, and the video (measured 2-6 kB a
  // frame at 512 px and rate factor 23; counted as a byte per 16 texels).
  const int64_t frame_side = appearance_options.size_px;
  const int64_t appearance_bytes =
      appearance
          ? frame_side * frame_side * (24 * (2 * appearance_options.window + 1) * sensors + 24) +
                frame_side * frame_side * instants / 16
          : 0;
  return kModelBytes + fits + shape + atlas_bytes + appearance_bytes;
}

absl::Status BodyMethodOptions::Validate() const {
  if (!body::IsAssetModelSpec(model)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "option model: expected 'procedural' or 'makehuman:NAME' (an asset folder of the "
        "server, no path), got '",
        model.substr(0, 80), "'"));
  }
  RETURN_IF_ERROR(fit.Validate());
  RETURN_IF_ERROR(appearance_options.Validate());
  if (appearance_crf < 0 || appearance_crf > 51) {
    return absl::InvalidArgumentError("appearance_crf outside [0, 51]");
  }
  return atlas.Validate();
}

ReenactmentFrame BodyFrame(int frame_index, int64_t stamp_ns, const bodyfit::FrameFit& fit,
                           bool valid) {
  ReenactmentFrame frame;
  frame.frame_index = frame_index;
  frame.stamp_ns = stamp_ns;
  BodyFramePose& pose = frame.body.emplace();
  pose.pose = fit.pose;
  pose.valid = valid;
  pose.point_rms_mm = static_cast<float>(fit.point_rms_mm);
  if (fit.offsets_m.cols() > 0) pose.SetOffsetsMetres(fit.offsets_m);
  frame.joints_in_world_m.assign(fit.joints_m.begin(), fit.joints_m.end());
  return frame;
}

absl::StatusOr<Reenactment> RunBody(const TakeFrames& take, const BodyMethodOptions& o,
                                    const MethodContext& context) {
  RETURN_IF_ERROR(o.Validate());
  std::vector<std::pair<std::string, double>> stage_weights = {
      {"model", 0.05}, {"clouds", 0.15}, {"shape", 0.1}, {"fit", 0.45}, {"texture", 0.25}};
  if (o.appearance) stage_weights.emplace_back("appearance", 0.15);
  const StageProgress stages(context.progress, std::move(stage_weights));
  // Stage times from one clock: each is the time since the previous ended.
  const auto start = std::chrono::steady_clock::now();
  StageSeconds seconds;
  ASSIGN_OR_RETURN(const LoadedModel loaded, LoadModel(o, context, stages));
  seconds.model = SecondsSince(start);
  ASSIGN_OR_RETURN(const std::vector<bodyfit::PointCloud> clouds,
                   BuildClouds(take, stages, 0, take.num_instants()));
  seconds.clouds = SecondsSince(start) - seconds.model;
  const CloudSource cloud_of = [&clouds](int i) -> absl::StatusOr<const bodyfit::PointCloud*> {
    return &clouds[i];
  };
  ASSIGN_OR_RETURN(const std::vector<int> shape_instants,
                   FitShape(take, cloud_of, o.fit.shape_frames, *loaded.fitter, stages));
  seconds.shape = SecondsSince(start) - seconds.model - seconds.clouds;
  if (context.log) {
    context.log(ShapeLine(o.model, loaded, shape_instants.size(), seconds.shape));
  }
  ASSIGN_OR_RETURN(const FrameFits fits,
                   FitAllFrames(take, clouds, *loaded.fitter, stages, o.look_ahead));
  if (context.log && fits.backward > 0) context.log(LookAheadLine(fits.backward));
  ASSIGN_OR_RETURN(TexturedMesh textured, BakeAtlas(take, loaded, fits, o.atlas, stages));
  if (o.appearance) RETURN_IF_ERROR(BakeAppearance(take, fits, o, stages, &textured));
  Reenactment data =
      AssembleReenactment(take, *loaded.model, std::move(textured.mesh), FittedFrames(take, fits),
                          FiguresOf(fits), seconds, textured.atlas);
  if (context.log) {
    context.log(SummaryLine(take.num_instants(), FiguresOf(fits), o.atlas.size_px, textured.atlas));
  }
  return data;
}

absl::StatusOr<std::string> PrepareBody(const TakeFrames& take, const BodyMethodOptions& o,
                                        const MethodContext& context) {
  RETURN_IF_ERROR(o.Validate());
  const StageProgress stages(context.progress, {{"model", 0.2}, {"clouds", 0.4}, {"shape", 0.4}});
  const auto start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const LoadedModel loaded, LoadModel(o, context, stages));
  const double model_s = SecondsSince(start);
  ASSIGN_OR_RETURN(const std::unique_ptr<CloudBuilder> builder, CloudBuilder::Create(take));
  // Only the clouds of the instants looked at for the shape.
  std::map<int, bodyfit::PointCloud> clouds;
  const CloudSource cloud_of = [&](int i) -> absl::StatusOr<const bodyfit::PointCloud*> {
    auto it = clouds.find(i);
    if (it == clouds.end()) {
      ASSIGN_OR_RETURN(bodyfit::PointCloud cloud, builder->Build(i));
      it = clouds.emplace(i, std::move(cloud)).first;
      RETURN_IF_ERROR(stages.Report("clouds", static_cast<int64_t>(clouds.size()),
                                    std::min(take.num_instants(), o.fit.shape_frames)));
    }
    return &it->second;
  };
  ASSIGN_OR_RETURN(const std::vector<int> shape_instants,
                   FitShape(take, cloud_of, o.fit.shape_frames, *loaded.fitter, stages));
  v1::BodyShapePart part;
  part.set_model(o.model);
  for (int k = 0; k < loaded.fitter->shape().size(); ++k) part.add_shape(loaded.fitter->shape()[k]);
  for (int i : shape_instants) part.add_shape_instants(i);
  part.set_num_instants(take.num_instants());
  part.set_model_seconds(model_s);
  part.set_shape_seconds(SecondsSince(start) - model_s);
  if (context.log) {
    context.log(ShapeLine(o.model, loaded, shape_instants.size(), part.shape_seconds()));
  }
  return part.SerializeAsString();
}

namespace {

// Little-endian float32 r, g, b, w per texel, compressed with zstd.
std::string PackAtlasSums(const AtlasSums& sums) {
  const size_t raw_bytes = sums.sums.size() * sizeof(Eigen::Vector4f);
  std::string packed(ZSTD_compressBound(raw_bytes), '\0');
  const size_t n =
      ZSTD_compress(packed.data(), packed.size(), sums.sums.data(), raw_bytes, /*level=*/1);
  packed.resize(ZSTD_isError(n) ? 0 : n);
  return packed;
}

// The sums of a segment part; DataLoss for sums that do not unpack to the
// side the part states (checked before anything is allocated).
absl::StatusOr<AtlasSums> UnpackAtlasSums(const v1::BodySegmentPart& part) {
  if (part.atlas_px() < 16 || part.atlas_px() > 8192) {
    return absl::DataLossError(absl::StrCat("segment ", part.index(), ": atlas side ",
                                            part.atlas_px(), " outside [16, 8192]"));
  }
  AtlasSums sums;
  sums.size_px = part.atlas_px();
  sums.views = part.atlas_views();
  const size_t texels = static_cast<size_t>(sums.size_px) * sums.size_px;
  const size_t raw_bytes = texels * sizeof(Eigen::Vector4f);
  const std::string& packed = part.atlas_sums_zstd();
  if (ZSTD_getFrameContentSize(packed.data(), packed.size()) != raw_bytes) {
    return absl::DataLossError(absl::StrCat("segment ", part.index(), ": atlas sums are not of a ",
                                            sums.size_px, " px atlas"));
  }
  sums.sums.resize(texels);
  const size_t n = ZSTD_decompress(sums.sums.data(), raw_bytes, packed.data(), packed.size());
  if (ZSTD_isError(n) || n != raw_bytes) {
    return absl::DataLossError(absl::StrCat("segment ", part.index(), ": atlas sums are corrupt"));
  }
  return sums;
}

absl::StatusOr<v1::BodyShapePart> ParseShapePart(const std::string& prepared,
                                                 const TakeFrames& take,
                                                 const BodyMethodOptions& o) {
  v1::BodyShapePart shape;
  if (!shape.ParseFromString(prepared)) {
    return absl::DataLossError("the prepared shape of the body method does not parse");
  }
  if (shape.num_instants() != take.num_instants()) {
    return absl::InvalidArgumentError(absl::StrCat("the shape was fitted on a take of ",
                                                   shape.num_instants(), " instants; this one has ",
                                                   take.num_instants()));
  }
  if (shape.model() != o.model) {
    return absl::InvalidArgumentError(
        absl::StrCat("the shape is of model ", shape.model(), "; the options name ", o.model));
  }
  return shape;
}

// The loaded model with the prepared shape set.
absl::StatusOr<LoadedModel> ShapedModel(const v1::BodyShapePart& shape, const BodyMethodOptions& o,
                                        const MethodContext& context, const StageProgress& stages) {
  ASSIGN_OR_RETURN(LoadedModel loaded, LoadModel(o, context, stages));
  Eigen::VectorXd betas(shape.shape_size());
  for (int k = 0; k < shape.shape_size(); ++k) betas[k] = shape.shape(k);
  RETURN_IF_ERROR(loaded.fitter->set_shape(betas));
  return loaded;
}

}  // namespace

absl::StatusOr<std::string> FitBodySegment(const TakeFrames& take, const BodyMethodOptions& o,
                                           const MethodContext& context,
                                           const std::string& prepared, int index, int count) {
  RETURN_IF_ERROR(o.Validate());
  if (count < 1 || index < 0 || index >= count) {
    return absl::InvalidArgumentError(
        absl::StrCat("segment ", index, " of ", count, " does not exist"));
  }
  ASSIGN_OR_RETURN(const v1::BodyShapePart shape, ParseShapePart(prepared, take, o));
  const StageProgress stages(context.progress,
                             {{"model", 0.05}, {"clouds", 0.2}, {"fit", 0.5}, {"texture", 0.25}});
  const int warmup = static_cast<int>(std::lround(o.segment_warmup_s * take.fps()));
  const SegmentRange range = SegmentOf(take.num_instants(), index, count, warmup);
  ASSIGN_OR_RETURN(const LoadedModel loaded, ShapedModel(shape, o, context, stages));
  const auto clouds_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const std::vector<bodyfit::PointCloud> clouds,
                   BuildClouds(take, stages, range.warmup_first, range.end));
  const double clouds_s = SecondsSince(clouds_start);
  ASSIGN_OR_RETURN(const FrameFits fits,
                   FitFrames(take, clouds, *loaded.fitter, stages, range, o.look_ahead));
  if (context.log && fits.backward > 0) context.log(LookAheadLine(fits.backward));
  // The segment's share of the atlas.
  const auto texture_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const BodyMesh mesh, BuildBodyMesh(*loaded.model, loaded.fitter->shape(), ""));
  ASSIGN_OR_RETURN(const AtlasSums sums,
                   AccumulateBodyAtlas(take, mesh, PosedVertices(fits), o.atlas,
                                       stages.ForStage("texture"), range.first, range.end));
  v1::BodySegmentPart part;
  part.set_index(index);
  part.set_count(count);
  part.set_first(range.first);
  part.set_end(range.end);
  part.set_warmup_first(range.warmup_first);
  for (const std::optional<ReenactmentFrame>& frame : FittedFrames(take, fits)) {
    if (frame) *part.add_frames() = FrameToProto(*frame);
  }
  part.set_reinitialised(fits.reinitialised);
  part.set_fit_seconds(fits.fit_seconds);
  part.set_rms_sum_mm(fits.rms_sum);
  part.set_explained_sum(fits.explained_sum);
  part.set_unexplained(fits.unexplained);
  for (const int count_of : fits.hypotheses) part.add_hypotheses(count_of);
  part.set_clouds_seconds(clouds_s);
  part.set_atlas_px(sums.size_px);
  part.set_atlas_views(sums.views);
  part.set_atlas_sums_zstd(PackAtlasSums(sums));
  if (part.atlas_sums_zstd().empty()) return absl::InternalError("the atlas sums did not compress");
  part.set_texture_seconds(SecondsSince(texture_start));
  if (context.log) {
    context.log(absl::StrFormat(
        "body: segment %d of %d: instants [%d, %d) from %d, %d fitted, %.1f ms per frame; "
        "atlas sums of %d images",
        index + 1, count, range.first, range.end, range.warmup_first, fits.fitted,
        fits.fitted > 0 ? 1000.0 * fits.fit_seconds / fits.fitted : 0.0, sums.views));
  }
  return part.SerializeAsString();
}

absl::StatusOr<Reenactment> StitchBody(const TakeFrames& take, const BodyMethodOptions& o,
                                       const MethodContext& context, const std::string& prepared,
                                       const std::vector<std::string>& segments) {
  RETURN_IF_ERROR(o.Validate());
  ASSIGN_OR_RETURN(const v1::BodyShapePart shape, ParseShapePart(prepared, take, o));
  const StageProgress stages(context.progress, {{"model", 0.3}, {"stitch", 0.7}});
  ASSIGN_OR_RETURN(const LoadedModel loaded, ShapedModel(shape, o, context, stages));
  const int n = take.num_instants();
  const int count = static_cast<int>(segments.size());
  std::vector<std::optional<ReenactmentFrame>> frames(n);
  ASSIGN_OR_RETURN(BodyMesh mesh, BuildBodyMesh(*loaded.model, loaded.fitter->shape(), ""));
  FitFigures fits;
  StageSeconds seconds{shape.model_seconds(), 0.0, shape.shape_seconds()};
  AtlasFigures atlas;
  AtlasSums sums;
  int next_first = 0;
  for (int k = 0; k < count; ++k) {
    RETURN_IF_ERROR(stages.Report("stitch", k, count + 1));
    v1::BodySegmentPart part;
    if (!part.ParseFromString(segments[k])) {
      return absl::DataLossError(absl::StrCat("segment ", k, " does not parse"));
    }
    RETURN_IF_ERROR(CheckSegmentPart(k, count, n, next_first, part.index(), part.count(),
                                     part.first(), part.end()));
    next_first = part.end();
    for (const v1::PartFrame& message : part.frames()) {
      const int i = message.frame_index();
      if (i < part.first() || i >= part.end() || frames[i]) {
        return absl::InvalidArgumentError(
            absl::StrCat("segment ", k, " holds a frame of instant ", i, " twice or outside it"));
      }
      absl::StatusOr<ReenactmentFrame> frame = FrameFromProto(message, mesh.num_vertices());
      if (!frame.ok() || !frame->body) {
        return absl::InvalidArgumentError(
            absl::StrCat("segment ", k, " frame of instant ", i,
                         " is not a body pose of the model: ", frame.status().message()));
      }
      frames[i] = *std::move(frame);
      ++fits.fitted;
    }
    fits.reinitialised += part.reinitialised();
    fits.fit_seconds += part.fit_seconds();
    fits.rms_sum += part.rms_sum_mm();
    fits.explained_sum += part.explained_sum();
    fits.unexplained += part.unexplained();
    for (int h = 0; h < part.hypotheses_size() && h < bodyfit::kNumHypotheses; ++h) {
      fits.hypotheses[h] += part.hypotheses(h);
    }
    seconds.clouds += part.clouds_seconds();
    atlas.seconds += part.texture_seconds();
    ASSIGN_OR_RETURN(const AtlasSums part_sums, UnpackAtlasSums(part));
    RETURN_IF_ERROR(AddAtlasSums(part_sums, sums));
  }
  if (next_first != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("the segments end at instant ", next_first, " of ", n));
  }
  if (fits.fitted == 0) return absl::InvalidArgumentError("no instant of the take could be fitted");
  const auto finish_start = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const AtlasResult finished, FinishBodyAtlas(mesh, std::move(sums)));
  ASSIGN_OR_RETURN(mesh.atlas_jpeg, EncodeJpeg(finished.atlas, 90));
  atlas.seconds += SecondsSince(finish_start);
  atlas.observed_fraction = finished.observed_fraction;
  atlas.views = finished.views;
  Reenactment data =
      AssembleReenactment(take, *loaded.model, std::move(mesh), frames, fits, seconds, atlas);
  data.info.figures["segments"] = count;
  RETURN_IF_ERROR(stages.Report("stitch", count + 1, count + 1));
  if (context.log) {
    context.log(absl::StrCat("body: stitched ", count, " segments; ",
                             SummaryLine(n, fits, finished.atlas.width, atlas)));
  }
  return data;
}
absl::StatusOr<TakeNeeds> BodyNeeds(const TakeFrames& take, const BodyMethodOptions& o,
                                    MethodPhase phase, int index, int count) {
  RETURN_IF_ERROR(o.Validate());
  TakeNeeds needs;
  const int n = take.num_instants();
  switch (phase) {
    case MethodPhase::kWhole:
      return TakeNeeds::All(take);
    case MethodPhase::kPrepare: {
      // The shape's instants are chosen by their clouds, outward from each
      // target (ChooseShapeInstants): the depth of the first
      // kShapeSearchInstants instants with a torso around each. A take
      // where all of them have too few points gets its shape from farther
      // instants in a whole run, and from fewer here. No colour.
      const int count = std::min(o.fit.shape_frames, n);
      std::vector<bool> added(n, false);
      for (int k = 0; k < count; ++k) {
        const int target = ShapeTarget(k, count, n);
        int found = 0;
        for (int d = 0; d < n && found < kShapeSearchInstants; ++d) {
          for (int side = 0; side < (d == 0 ? 1 : 2) && found < kShapeSearchInstants; ++side) {
            const int i = side == 0 ? target + d : target - d;
            if (i < 0 || i >= n || !bodyfit::HasTorso(take.instant(i).joints_in_world_m)) continue;
            ++found;
            if (!added[i]) needs.depth.push_back(i);
            added[i] = true;
          }
        }
      }
      std::sort(needs.depth.begin(), needs.depth.end());
      return needs;
    }
    case MethodPhase::kSegment: {
      if (count < 1 || index < 0 || index >= count) {
        return absl::InvalidArgumentError(
            absl::StrCat("segment ", index, " of ", count, " does not exist"));
      }
      // As FitBodySegment: the clouds from the warm-up on, the colour of
      // the atlas's instants (every k-th of the whole take) in the segment.
      const int warmup = static_cast<int>(std::lround(o.segment_warmup_s * take.fps()));
      const SegmentRange range = SegmentOf(n, index, count, warmup);
      for (int i = range.warmup_first; i < range.end; ++i) needs.depth.push_back(i);
      for (int i = range.first; i < range.end; ++i) {
        if (i % o.atlas.every == 0) needs.color.push_back(i);
      }
      return needs;
    }
    case MethodPhase::kStitch:
      return needs;  // Part files and the instants' stamps alone.
  }
  return needs;
}

// A live job's follower: the fit FrameSet by FrameSet (live_body.h).
absl::StatusOr<std::unique_ptr<LiveFollower>> MakeLiveBodyFollower(
    const TakeInfo& info, const std::vector<SensorCalibration>& sensors, const OptionMap& options,
    const std::vector<std::string>& asset_roots) {
  ASSIGN_OR_RETURN(std::unique_ptr<LiveBodyFollower> follower,
                   LiveBodyFollower::Create(info, sensors, options, asset_roots));
  return std::unique_ptr<LiveFollower>(std::move(follower));
}

// A model the workers could not find fails at Submit, not after the queue.
absl::Status CheckBodyAssets(const BodyMethodOptions& options,
                             const std::vector<std::string>& asset_roots) {
  return body::ResolveAssetModelSpec(options.model, asset_roots).status();
}

const ReconstructionMethod& BodyMethod() {
  static const TypedMethod<BodyMethodOptions> method(
      {"body",
       "a statistical body model fitted to the merged point clouds, textured into one atlas",
       "ch. 4, Eq. 4.4-4.8",
       /*live=*/true,
       methods::TextureMode::kBodyAtlas,
       {}},
      &RunBody, methods::DescribeOptions<LiveBodyOptions>(),
      SegmentFunctions<BodyMethodOptions>{&PrepareBody, &FitBodySegment, &StitchBody, &BodyNeeds},
      LiveAndAssetFunctions<BodyMethodOptions>{&MakeLiveBodyFollower, &CheckBodyAssets});
  return method;
}

}  // namespace reenact::recon
