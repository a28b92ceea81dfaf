#include "server/recon/rigid_texturing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_convert.h"
#include "reenact/v1/segments.pb.h"
#include "server/recon/body_parts.h"

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

int64_t RigidTexturingOptions::MemoryBytes(const TakeSize& take,
                                           const std::vector<int64_t>& part_triangles,
                                           int64_t vertices) const {
  // DefaultKeyframeStride's rule, from the catalog's figures.
  const int64_t views = std::max<int64_t>(take.frame_sets, 1) * std::max(take.sensors, 1);
  int64_t keyframes = views;
  if (keyframe_stride > 0) {
    keyframes = (views + keyframe_stride - 1) / keyframe_stride;
  } else if (take.duration_s > 20.0) {
    keyframes = std::min<int64_t>(views, 600 + take.sensors);
  }
  int64_t bytes =
      memory::KeyframesBytes(keyframes, color_scale, keyframe.max_crop_side_px, vertices);
  if (bake) {
    for (const int64_t triangles : part_triangles) {
      bytes +=
          memory::BakedTextureBytes(memory::GrownTextureSide(baking.texture_size_px, triangles)) +
          memory::MeshBytes(triangles);
    }
  }
  return bytes;
}

int DefaultKeyframeStride(const TakeFrames& take) {
  constexpr double kAllFramesUpToS = 20.0;
  constexpr int kMaxKeyframes = 600;
  if (take.duration_s() <= kAllFramesUpToS) return 1;
  int64_t views = 0;
  for (const Instant& instant : take.instants()) {
    for (const SensorView& view : instant.views) views += view.has_color ? 1 : 0;
  }
  return std::max<int>(1, static_cast<int>((views + kMaxKeyframes - 1) / kMaxKeyframes));
}

int KeyframeStride(const TakeFrames& take, const RigidTexturingOptions& options) {
  return options.keyframe_stride > 0 ? options.keyframe_stride : DefaultKeyframeStride(take);
}

std::vector<int> KeyframeInstants(int num_instants, int keyframe_stride, int first, int end) {
  std::vector<int> instants;
  const int stride = std::max(1, keyframe_stride);
  for (int i = std::max(0, first); i < std::min(num_instants, end); ++i) {
    if (i % stride == 0) instants.push_back(i);
  }
  return instants;
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

absl::StatusOr<RigidKeyframes> MakeRigidKeyframes(const TakeFrames& take,
                                                  const RigidTexturingOptions& options,
                                                  int keyframe_stride, const Reenactment& data,
                                                  int first, int end,
                                                  const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  if (keyframe_stride < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("keyframe stride ", keyframe_stride, " is not positive"));
  }
  const auto start = std::chrono::steady_clock::now();
  RigidKeyframes result;
  const std::vector<PartMesh>& geometry = data.parts;
  // The planned keyframes: every stride-th instant in [first, end) with a
  // valid frame, every sensor with colour there.
  std::vector<KeyframeJob> jobs;
  for (const ReenactmentFrame& frame : data.frames) {
    const int i = frame.frame_index;
    if (i < 0 || i >= take.num_instants()) {
      return absl::InvalidArgumentError(
          absl::StrCat("frame ", i, " is not an instant of the take"));
    }
    if (i < first || i >= end || i % keyframe_stride != 0) continue;
    const bool any_valid = std::any_of(frame.parts.begin(), frame.parts.end(),
                                       [](const reenact::PartPose& p) { return p.valid; });
    for (int s = 0; s < take.num_sensors(); ++s) {
      const SensorView& view = take.instant(i).views[s];
      if (!view.present || view.color_jpeg.empty() || !any_valid) {
        if (view.present) ++result.skipped;
        continue;
      }
      jobs.push_back({i, s, &frame});
    }
  }

  result.planned = static_cast<int>(jobs.size());
  std::vector<std::optional<TextureKeyframe>> made(jobs.size());
  const int batch = std::max(2, 2 * take.pool().num_threads());
  for (size_t begin = 0; begin < jobs.size(); begin += batch) {
    const size_t batch_end = std::min(jobs.size(), begin + batch);
    std::mutex mu;
    absl::Status first_error = absl::OkStatus();
    take.pool().ParallelFor(static_cast<int>(begin), static_cast<int>(batch_end), [&](int k) {
      auto made_one = MakeKeyframe(take, options, geometry, jobs[k]);
      if (made_one.ok()) {
        made[k] = std::move(*made_one);
        return;
      }
      std::lock_guard<std::mutex> lock(mu);
      if (first_error.ok()) first_error = made_one.status();
    });
    RETURN_IF_ERROR(first_error);
    if (progress &&
        !progress({"texture", static_cast<double>(batch_end) / jobs.size(),
                   static_cast<int64_t>(batch_end), static_cast<int64_t>(jobs.size())})) {
      return absl::CancelledError("cancelled while making texture keyframes");
    }
  }
  for (auto& keyframe : made) {
    if (!keyframe) {
      ++result.skipped;
      continue;
    }
    result.keyframes.push_back(std::move(*keyframe));
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

absl::Status BakeRigidTextures(const TakeFrames& take, const RigidTexturingOptions& options,
                               Reenactment* data, BakeSummary* summary) {
  RETURN_IF_ERROR(options.Validate());
  if (!options.bake || data->keyframes.empty()) return absl::OkStatus();
  std::vector<SensorCalibration> sensors;
  for (const TakeSensor& sensor : take.sensors()) sensors.push_back(sensor.calibration);
  const std::vector<PartMesh> before = data->parts;
  RETURN_IF_ERROR(BakePartTextures(data->keyframes, data->frames, sensors, options.baking,
                                   &data->parts, summary));
  // The keyframes' bits are in the old vertex order (texturing.h).
  return RemapVisibilityBitsToBakedMeshes(before, &data->keyframes);
}

void AddTexturingFigures(const RigidTexturingSummary& summary,
                         std::map<std::string, double>* figures) {
  (*figures)["keyframes"] = summary.keyframes;
  (*figures)["keyframe_stride"] = summary.keyframe_stride;
  (*figures)["texture_seconds"] = summary.seconds;
  if (summary.bake.triangles > 0) {
    (*figures)["baked_unobserved_fraction"] =
        static_cast<double>(summary.bake.triangles_unobserved) / summary.bake.triangles;
  }
}

std::string TexturingLine(const RigidTexturingSummary& summary) {
  return absl::StrCat("texture: ", summary.keyframes, " keyframes (stride ",
                      summary.keyframe_stride, ", ", summary.keyframes_skipped, " skipped), ",
                      summary.bake.parts_baked, " parts baked, ", summary.bake.triangles_unobserved,
                      "/", summary.bake.triangles, " triangles unobserved, ", summary.seconds,
                      " s");
}

absl::StatusOr<RigidTexturingSummary> AddRigidTextures(const TakeFrames& take,
                                                       const RigidTexturingOptions& options,
                                                       Reenactment* data,
                                                       const ProgressCallback& progress,
                                                       const LogCallback& log) {
  RETURN_IF_ERROR(options.Validate());
  const auto start = std::chrono::steady_clock::now();
  RigidTexturingSummary summary;
  summary.keyframe_stride = KeyframeStride(take, options);
  // Keyframes are 80 % of the stage when baking follows.
  const double share = options.bake ? 0.8 : 1.0;
  ProgressCallback keyframe_progress;
  if (progress) {
    keyframe_progress = [&](const Progress& p) {
      Progress scaled = p;
      scaled.fraction = share * p.fraction;
      return progress(scaled);
    };
  }
  ASSIGN_OR_RETURN(RigidKeyframes made,
                   MakeRigidKeyframes(take, options, summary.keyframe_stride, *data, 0,
                                      take.num_instants(), keyframe_progress));
  summary.keyframes = static_cast<int>(made.keyframes.size());
  summary.keyframes_skipped = made.skipped;
  const int planned = made.planned;
  for (TextureKeyframe& keyframe : made.keyframes) data->keyframes.push_back(std::move(keyframe));
  RETURN_IF_ERROR(BakeRigidTextures(take, options, data, &summary.bake));
  if (progress && !progress({"texture", 1.0, planned, planned})) {
    return absl::CancelledError("cancelled while baking textures");
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  AddTexturingFigures(summary, &data->info.figures);
  if (log) log(TexturingLine(summary));
  return summary;
}

// ---------------------------------------------- a rigid method split --

namespace {

constexpr int kPoseValues = 13;  // Rotation (row-major), translation, scale.

// ValidateReenactment with the take's sensors (keyframes name them).
absl::Status ValidateWithSensors(const TakeFrames& take, Reenactment* data) {
  data->info.sensors.clear();
  for (const TakeSensor& sensor : take.sensors()) data->info.sensors.push_back(sensor.calibration);
  absl::Status status = ValidateReenactment(*data);
  data->info.sensors.clear();  // RunMethod fills the bookkeeping.
  return status;
}

}  // namespace

std::string PackUntexturedRigid(const Reenactment& data, int keyframe_stride) {
  v1::RigidUntexturedPart part;
  part.set_num_instants(static_cast<int>(data.frames.size()));
  part.set_keyframe_stride(keyframe_stride);
  for (const PartMesh& mesh : data.parts) *part.add_parts() = PartMeshToProto(mesh);
  for (const ReenactmentFrame& frame : data.frames) {
    v1::RigidFrame* message = part.add_frames();
    message->set_frame_index(frame.frame_index);
    message->set_stamp_ns(frame.stamp_ns);
    message->mutable_poses()->Reserve(kPoseValues * static_cast<int>(frame.parts.size()));
    for (const reenact::PartPose& pose : frame.parts) {
      const Eigen::Matrix3d rotation = pose.world_from_part.linear();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) message->add_poses(rotation(r, c));
      }
      for (int k = 0; k < 3; ++k) message->add_poses(pose.world_from_part.translation()[k]);
      message->add_poses(pose.scale);
      message->add_valid(pose.valid);
    }
    for (const Eigen::Vector3d& joint : frame.joints_in_world_m) {
      for (int k = 0; k < 3; ++k) message->add_joints_in_world_m(joint[k]);
    }
  }
  for (const auto& [name, value] : data.info.figures) (*part.mutable_figures())[name] = value;
  return part.SerializeAsString();
}

absl::StatusOr<Reenactment> UnpackUntexturedRigid(const std::string& prepared,
                                                  const TakeFrames& take, int* keyframe_stride) {
  v1::RigidUntexturedPart part;
  if (!part.ParseFromString(prepared)) {
    return absl::DataLossError("the prepared part of the rigid method does not parse");
  }
  const int n = take.num_instants();
  if (part.num_instants() != n || part.frames_size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("the prepared part is of a take of ", part.num_instants(), " instants with ",
                     part.frames_size(), " frames; this take has ", n));
  }
  if (part.keyframe_stride() < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("the prepared keyframe stride ", part.keyframe_stride(), " is not positive"));
  }
  *keyframe_stride = part.keyframe_stride();
  Reenactment data;
  for (const v1::PartMesh& message : part.parts()) {
    absl::StatusOr<PartMesh> mesh = PartMeshFromProto(message);
    if (!mesh.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("a prepared mesh does not unpack: ", mesh.status().message()));
    }
    data.parts.push_back(*std::move(mesh));
  }
  const size_t num_parts = data.parts.size();
  for (int i = 0; i < n; ++i) {
    const v1::RigidFrame& message = part.frames(i);
    if (message.frame_index() != i || message.valid_size() != static_cast<int>(num_parts) ||
        message.poses_size() != kPoseValues * static_cast<int>(num_parts) ||
        message.joints_in_world_m_size() % 3 != 0 ||
        message.joints_in_world_m_size() > 3 * body::kNumKinectV2Joints) {
      return absl::InvalidArgumentError(absl::StrCat(
          "the prepared frame ", i, " is not a frame of instant ", i, " with ", num_parts,
          " poses (frame_index ", message.frame_index(), ", ", message.valid_size(), " poses)"));
    }
    ReenactmentFrame frame;
    frame.frame_index = i;
    frame.stamp_ns = message.stamp_ns();
    for (size_t p = 0; p < num_parts; ++p) {
      const double* v = message.poses().data() + kPoseValues * p;
      reenact::PartPose pose;
      Eigen::Matrix3d rotation;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) rotation(r, c) = v[3 * r + c];
      }
      const Eigen::Vector3d translation(v[9], v[10], v[11]);
      if (!rotation.allFinite() || !translation.allFinite() || !std::isfinite(v[12]) ||
          !(v[12] > 0.0) ||
          !(rotation * rotation.transpose()).isApprox(Eigen::Matrix3d::Identity(), 1e-6) ||
          !(rotation.determinant() > 0.0)) {
        return absl::InvalidArgumentError(
            absl::StrCat("the prepared pose of part ", p, " at instant ", i, " is not rigid"));
      }
      pose.world_from_part.linear() = rotation;
      pose.world_from_part.translation() = translation;
      pose.scale = v[12];
      pose.valid = message.valid(static_cast<int>(p));
      frame.parts.push_back(pose);
    }
    for (int j = 0; j + 2 < message.joints_in_world_m_size(); j += 3) {
      frame.joints_in_world_m.emplace_back(message.joints_in_world_m(j),
                                           message.joints_in_world_m(j + 1),
                                           message.joints_in_world_m(j + 2));
    }
    data.frames.push_back(std::move(frame));
  }
  for (const auto& [name, value] : part.figures()) data.info.figures[name] = value;
  data.info.frame_count = n;
  data.info.fps = take.fps();
  data.info.part_names = BodyPartNames();
  RETURN_IF_ERROR(ValidateWithSensors(take, &data));
  return data;
}

absl::StatusOr<std::string> RigidTextureSegment(const TakeFrames& take,
                                                const RigidTexturingOptions& options,
                                                const MethodContext& context,
                                                const std::string& prepared, int index, int count) {
  RETURN_IF_ERROR(options.Validate());
  if (count < 1 || index < 0 || index >= count) {
    return absl::InvalidArgumentError(
        absl::StrCat("segment ", index, " of ", count, " does not exist"));
  }
  int stride = 0;
  ASSIGN_OR_RETURN(const Reenactment data, UnpackUntexturedRigid(prepared, take, &stride));
  const SegmentRange range = SegmentOf(take.num_instants(), index, count, 0);
  ASSIGN_OR_RETURN(
      const RigidKeyframes made,
      MakeRigidKeyframes(take, options, stride, data, range.first, range.end, context.progress));
  v1::RigidKeyframesPart part;
  part.set_index(index);
  part.set_count(count);
  part.set_first(range.first);
  part.set_end(range.end);
  for (const TextureKeyframe& keyframe : made.keyframes) {
    *part.add_keyframes() = KeyframeToProto(keyframe);
  }
  part.set_keyframes_skipped(made.skipped);
  part.set_seconds(made.seconds);
  if (context.log) {
    context.log(absl::StrCat("texture: segment ", index + 1, " of ", count, ": instants [",
                             range.first, ", ", range.end, "), ", made.keyframes.size(),
                             " keyframes (stride ", stride, ", ", made.skipped, " skipped), ",
                             made.seconds, " s"));
  }
  return part.SerializeAsString();
}

absl::StatusOr<Reenactment> StitchRigidTextures(const TakeFrames& take,
                                                const RigidTexturingOptions& options,
                                                const MethodContext& context,
                                                const std::string& prepared,
                                                const std::vector<std::string>& segments) {
  RETURN_IF_ERROR(options.Validate());
  const StageProgress stages(context.progress, {{"stitch", 0.2}, {"texture", 0.8}});
  int stride = 0;
  ASSIGN_OR_RETURN(Reenactment data, UnpackUntexturedRigid(prepared, take, &stride));
  const int n = take.num_instants();
  const int count = static_cast<int>(segments.size());
  RigidTexturingSummary summary;
  summary.keyframe_stride = stride;
  int next_first = 0;
  for (int k = 0; k < count; ++k) {
    RETURN_IF_ERROR(stages.Report("stitch", k, count));
    v1::RigidKeyframesPart part;
    if (!part.ParseFromString(segments[k])) {
      return absl::DataLossError(absl::StrCat("segment ", k, " does not parse"));
    }
    RETURN_IF_ERROR(CheckSegmentPart(k, count, n, next_first, part.index(), part.count(),
                                     part.first(), part.end()));
    next_first = part.end();
    int last_instant = -1;
    for (const v1::TextureKeyframe& message : part.keyframes()) {
      const int i = message.frame_index();
      if (i < part.first() || i >= part.end() || i < last_instant || i % stride != 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "segment ", k, " holds a keyframe of instant ", i, " outside it or out of order"));
      }
      last_instant = i;
      data.keyframes.push_back(KeyframeFromProto(message));
    }
    summary.keyframes += part.keyframes_size();
    summary.keyframes_skipped += part.keyframes_skipped();
    summary.seconds += part.seconds();
  }
  if (next_first != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("the segments end at instant ", next_first, " of ", n));
  }
  RETURN_IF_ERROR(stages.Report("stitch", count, count));
  // The keyframes came from files: their frames, sensors and visibility
  // bits are checked before baking reads them.
  RETURN_IF_ERROR(ValidateWithSensors(take, &data));
  const auto bake_start = std::chrono::steady_clock::now();
  RETURN_IF_ERROR(BakeRigidTextures(take, options, &data, &summary.bake));
  summary.seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - bake_start).count();
  RETURN_IF_ERROR(stages.Report("texture", 1, 1));
  AddTexturingFigures(summary, &data.info.figures);
  data.info.figures["segments"] = count;
  if (context.log) {
    context.log(absl::StrCat("texture: stitched ", count, " segments; ", TexturingLine(summary)));
  }
  return data;
}

TakeNeeds RigidTextureSegmentNeeds(const TakeFrames& take, const RigidTexturingOptions& options,
                                   int index, int count) {
  const int n = take.num_instants();
  const int stride = KeyframeStride(take, options);
  const SegmentRange range = SegmentOf(n, index, count, 0);
  TakeNeeds needs;
  needs.depth = KeyframeInstants(n, stride, range.first, range.end);
  needs.color = needs.depth;
  return needs;
}

}  // namespace reenact::recon
