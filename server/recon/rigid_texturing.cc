#include "server/recon/rigid_texturing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::recon {

absl::Status RigidTexturingOptions::Read(OptionReader& reader) {
  RETURN_IF_ERROR(reader.Int("keyframe_stride", &keyframe_stride, 0, 1000000,
                             "keep every k-th instant as a texture keyframe (0: by take length)"));
  RETURN_IF_ERROR(reader.Int("color_scale", &color_scale, 1, 8,
                             "decode colour at 1/k before cropping (1, 2, 4 or 8)"));
  RETURN_IF_ERROR(
      reader.Bool("bake", &bake, "bake static per-part textures (glTF, viewers without VDTM)"));
  RETURN_IF_ERROR(reader.Int("texture_size_px", &baking.texture_size_px, 16, 8192,
                             "side of each part's baked texture, pixels"));
  RETURN_IF_ERROR(reader.Int("keyframe_jpeg_quality", &keyframe.jpeg_quality, 1, 100,
                             "JPEG quality of the keyframe crops"));
  RETURN_IF_ERROR(reader.Int("max_crop_side_px", &keyframe.max_crop_side_px, 0, 16384,
                             "downscale keyframe crops to this longer side (0: never)"));
  return Validate();
}

absl::Status RigidTexturingOptions::Validate() const {
  if (keyframe_stride < 0) return absl::InvalidArgumentError("keyframe_stride must be >= 0");
  if (color_scale != 1 && color_scale != 2 && color_scale != 4 && color_scale != 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("color_scale must be 1, 2, 4 or 8, not ", color_scale));
  }
  RETURN_IF_ERROR(keyframe.Validate());
  if (bake) RETURN_IF_ERROR(baking.Validate());
  return absl::OkStatus();
}

int DefaultKeyframeStride(const TakeFrames& take) {
  constexpr double kAllFramesUpToS = 20.0;
  constexpr int kMaxKeyframes = 600;
  if (take.duration_s() <= kAllFramesUpToS) return 1;
  int64_t views = 0;
  for (const Instant& instant : take.instants()) {
    for (const SensorView& view : instant.views) views += view.color_jpeg.empty() ? 0 : 1;
  }
  return std::max<int>(1, static_cast<int>((views + kMaxKeyframes - 1) / kMaxKeyframes));
}

namespace {

struct KeyframeJob {
  int instant = 0;
  int sensor = 0;
  const ReenactmentFrame* frame = nullptr;
};

// One keyframe: decode the view and call MakeTextureKeyframe (texturing.h).
// nullopt when the view has nothing to crop (NotFound).
absl::StatusOr<std::optional<TextureKeyframe>> MakeKeyframe(const TakeFrames& take,
                                                            const RigidTexturingOptions& options,
                                                            const std::vector<PartMesh>& geometry,
                                                            const KeyframeJob& job) {
  const std::vector<reenact::PartPose>& poses = job.frame->parts;
  ASSIGN_OR_RETURN(RgbImage colour, take.LoadColor(job.instant, job.sensor, options.color_scale));
  ASSIGN_OR_RETURN(DepthImageMm depth, take.LoadDepth(job.instant, job.sensor));
  ASSIGN_OR_RETURN(MaskImage mask, take.LoadActorMask(job.instant, job.sensor));
  const TakeSensor& sensor = take.sensors()[job.sensor];
  const SensorImages images{sensor.calibration, colour, mask, depth};
  auto keyframe = MakeTextureKeyframe(geometry, poses, images, job.frame->frame_index,
                                      job.frame->stamp_ns, sensor.sensor_id, options.keyframe);
  if (absl::IsNotFound(keyframe.status())) return std::optional<TextureKeyframe>();
  if (!keyframe.ok()) return keyframe.status();
  return std::optional<TextureKeyframe>(std::move(*keyframe));
}

}  // namespace

absl::StatusOr<RigidTexturingSummary> AddRigidTextures(const TakeFrames& take,
                                                       const RigidTexturingOptions& options,
                                                       Reenactment* data,
                                                       const ProgressCallback& progress,
                                                       const LogCallback& log) {
  RETURN_IF_ERROR(options.Validate());
  const auto start = std::chrono::steady_clock::now();
  RigidTexturingSummary summary;
  summary.keyframe_stride =
      options.keyframe_stride > 0 ? options.keyframe_stride : DefaultKeyframeStride(take);

  const std::vector<PartMesh>& geometry = data->parts;
  // The planned keyframes: every stride-th instant with a valid frame, every
  // sensor with colour there.
  std::vector<KeyframeJob> jobs;
  for (const ReenactmentFrame& frame : data->frames) {
    const int i = frame.frame_index;
    if (i < 0 || i >= take.num_instants()) {
      return absl::InvalidArgumentError(
          absl::StrCat("frame ", i, " is not an instant of the take"));
    }
    if (i % summary.keyframe_stride != 0) continue;
    const bool any_valid = std::any_of(frame.parts.begin(), frame.parts.end(),
                                       [](const reenact::PartPose& p) { return p.valid; });
    for (int s = 0; s < take.num_sensors(); ++s) {
      const SensorView& view = take.instant(i).views[s];
      if (!view.present || view.color_jpeg.empty() || !any_valid) {
        if (view.present) ++summary.keyframes_skipped;
        continue;
      }
      jobs.push_back({i, s, &frame});
    }
  }

  std::vector<std::optional<TextureKeyframe>> made(jobs.size());
  const int batch = std::max(2, 2 * take.pool().num_threads());
  for (size_t begin = 0; begin < jobs.size(); begin += batch) {
    const size_t end = std::min(jobs.size(), begin + batch);
    std::mutex mu;
    absl::Status first = absl::OkStatus();
    take.pool().ParallelFor(static_cast<int>(begin), static_cast<int>(end), [&](int k) {
      auto result = MakeKeyframe(take, options, geometry, jobs[k]);
      if (result.ok()) {
        made[k] = std::move(*result);
        return;
      }
      std::lock_guard<std::mutex> lock(mu);
      if (first.ok()) first = result.status();
    });
    RETURN_IF_ERROR(first);
    if (progress) {
      const double fraction = options.bake ? 0.8 * end / jobs.size() : 1.0 * end / jobs.size();
      if (!progress({"texture", fraction, static_cast<int64_t>(end),
                     static_cast<int64_t>(jobs.size())})) {
        return absl::CancelledError("cancelled while making texture keyframes");
      }
    }
  }
  for (auto& keyframe : made) {
    if (!keyframe) {
      ++summary.keyframes_skipped;
      continue;
    }
    data->keyframes.push_back(std::move(*keyframe));
    ++summary.keyframes;
  }

  if (options.bake && !data->keyframes.empty()) {
    std::vector<SensorCalibration> sensors;
    for (const TakeSensor& sensor : take.sensors()) sensors.push_back(sensor.calibration);
    const std::vector<PartMesh> before = data->parts;
    RETURN_IF_ERROR(BakePartTextures(data->keyframes, data->frames, sensors, options.baking,
                                     &data->parts, &summary.bake));
    // The keyframes' bits are in the old vertex order (texturing.h).
    RETURN_IF_ERROR(RemapVisibilityBitsToBakedMeshes(before, &data->keyframes));
  }
  if (progress && !progress({"texture", 1.0, static_cast<int64_t>(jobs.size()),
                             static_cast<int64_t>(jobs.size())})) {
    return absl::CancelledError("cancelled while baking textures");
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (log) {
    log(absl::StrCat("texture: ", summary.keyframes, " keyframes (stride ", summary.keyframe_stride,
                     ", ", summary.keyframes_skipped, " skipped), ", summary.bake.parts_baked,
                     " parts baked, ", summary.bake.triangles_unobserved, "/",
                     summary.bake.triangles, " triangles unobserved, ", summary.seconds, " s"));
  }
  return summary;
}

}  // namespace reenact::recon
