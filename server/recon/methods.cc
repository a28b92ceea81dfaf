#include "server/recon/methods.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "reenact/v1/sensor.pb.h"
#include "server/recon/body_parts.h"
#include "server/recon/registry.h"
#include "server/recon/take_frames.h"
#include "server/recon/take_tracking.h"

namespace reenact::recon {
namespace {

constexpr char kGenerator[] = "reenact-recon 0.1.0";

// Splits the load options (LoadOptions' keys) from the method's.
void SplitLoadOptions(const OptionMap& options, OptionMap* load, OptionMap* method) {
  static const std::vector<methods::OptionSpec> load_keys = methods::DescribeOptions<LoadOptions>();
  *method = options;
  for (const methods::OptionSpec& key : load_keys) {
    if (auto it = method->find(key.name); it != method->end()) {
      load->insert(*it);
      method->erase(it);
    }
  }
}

// Maps a method's own fractions (0..1, its stage names) into
// [begin, end] of the whole run.
ProgressCallback SubRange(const ProgressCallback& progress, double begin, double end) {
  if (!progress) return {};
  return [progress, begin, end](const Progress& inner) {
    Progress p = inner;
    p.fraction = begin + (end - begin) * std::clamp(inner.fraction, 0.0, 1.0);
    return progress(p);
  };
}

int64_t NowUnixNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// kPrepare and kSegment: the method's part file, written atomically.
absl::StatusOr<MethodResult> RunPartPhase(const MethodInput& input,
                                          const ReconstructionMethod& method,
                                          const TakeFrames& take, const OptionMap& options,
                                          const MethodContext& context, const std::string& out_path,
                                          std::chrono::steady_clock::time_point start) {
  std::string part;
  if (input.phase == MethodPhase::kPrepare) {
    ASSIGN_OR_RETURN(part, method.Prepare(take, options, context));
  } else {
    ASSIGN_OR_RETURN(const std::string prepared,
                     ReadFileToString(input.prepared_path, kMaxPartFileBytes));
    ASSIGN_OR_RETURN(part, method.Segment(take, options, context, prepared, input.segment_index,
                                          input.segment_count));
  }
  RETURN_IF_ERROR(WriteFileAtomically(out_path, part));
  MethodResult result;
  result.file_bytes = static_cast<int64_t>(part.size());
  result.figures["seconds"] = SecondsSince(start);
  if (input.phase == MethodPhase::kSegment) {
    const SegmentRange range =
        SegmentOf(take.num_instants(), input.segment_index, input.segment_count, 0);
    result.frames = range.end - range.first;
  }
  if (context.log) {
    context.log(absl::StrCat("write: ", out_path, ", ", result.file_bytes, " bytes, ",
                             result.figures["seconds"], " s"));
  }
  return result;
}

}  // namespace

absl::Status LoadOptions::Read(methods::OptionReader& reader) {
  RETURN_IF_ERROR(reader.Int("threads", &frames.num_threads, 0, 256,
                             "threads decoding the take (0: one per core)"));
  return reader.Int("max_frames", &frames.max_instants, 0, INT_MAX,
                    "use at most this many instants of the take (0: all)");
}

namespace {

// A job's method, its load options (parsed) and its own options, or the
// error CheckJob reports.
struct ParsedJob {
  const ReconstructionMethod* method = nullptr;
  LoadOptions load;
  OptionMap method_options;
};

absl::StatusOr<ParsedJob> ParseJob(const std::string& method, const OptionMap& options) {
  ParsedJob job;
  job.method = FindMethod(method);
  if (job.method == nullptr) return methods::UnknownMethodError(MethodSpecs(), method);
  OptionMap load_options;
  SplitLoadOptions(options, &load_options, &job.method_options);
  RETURN_IF_ERROR(methods::ParseOptions(load_options, &job.load));
  RETURN_IF_ERROR(job.method->CheckOptions(job.method_options));
  return job;
}

}  // namespace

absl::Status CheckJob(const std::string& method, const OptionMap& options,
                      const std::vector<std::string>& asset_roots) {
  ASSIGN_OR_RETURN(const ParsedJob job, ParseJob(method, options));
  return job.method->CheckAssets(job.method_options, asset_roots);
}

absl::StatusOr<int64_t> JobMemoryBytes(const std::string& method, const OptionMap& options,
                                       const TakeSize& take) {
  ASSIGN_OR_RETURN(const ParsedJob job, ParseJob(method, options));
  TakeSize used = take;
  used.frame_sets = take.Instants(job.load.frames.max_instants);
  if (take.frame_sets > used.frame_sets && take.frame_sets > 0) {
    used.duration_s = take.duration_s * static_cast<double>(used.frame_sets) / take.frame_sets;
  }
  ASSIGN_OR_RETURN(const int64_t own, job.method->MemoryBytes(job.method_options, used));
  // A take without skeletons is tracked first: a depth frame and the
  // tracker's buffers per thread, and the skeletons of every frame.
  const int64_t tracking = used.frame_sets * std::max(used.sensors, 1) * 4096;
  return memory::RunBytes(take, job.load.frames.num_threads, 1) + tracking + own;
}

absl::StatusOr<MethodResult> RunMethod(const MethodInput& input, const std::string& out_path,
                                       const ProgressCallback& progress, const LogCallback& log) {
  const auto start = std::chrono::steady_clock::now();
  const ReconstructionMethod* method = FindMethod(input.method);
  if (method == nullptr) return methods::UnknownMethodError(MethodSpecs(), input.method);
  if (out_path.empty()) return absl::InvalidArgumentError("no output path");
  OptionMap load_options, method_options;
  SplitLoadOptions(input.options, &load_options, &method_options);
  LoadOptions load;
  RETURN_IF_ERROR(methods::ParseOptions(load_options, &load));
  // Reject bad options before the (slow) load.
  RETURN_IF_ERROR(method->CheckOptions(method_options));

  // Load; a take without skeletons is tracked first (take_tracking.h), its
  // first job in [0.15, 0.5] of the run.
  bool tracked = false;
  const ProgressCallback track_range = SubRange(progress, 0.15, 0.5);
  const ProgressCallback track_progress = [&tracked, &track_range](const Progress& p) {
    tracked = true;
    return !track_range || track_range(p);
  };
  ASSIGN_OR_RETURN(std::unique_ptr<TakeFrames> take,
                   LoadTakeForMethod(input.take_path, load.frames, SubRange(progress, 0.0, 0.15),
                                     track_progress, log));
  if (take->num_valid_instants() == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(input.take_path, ": no instant of the take has a skeleton"));
  }
  const double load_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (log) {
    log(absl::StrCat(
        "load: ", take->num_instants(), " instants (", take->num_valid_instants(),
        " with a skeleton), ", take->num_sensors(), " sensors, ",
        take->grouped_by_frame_sets() ? "grouped by frame sets" : "grouped by frame index", ", ",
        load_s, " s"));
  }

  // The method.
  const MethodContext context{input.asset_roots, SubRange(progress, tracked ? 0.5 : 0.15, 0.95),
                              log};
  if (input.phase == MethodPhase::kPrepare || input.phase == MethodPhase::kSegment) {
    return RunPartPhase(input, *method, *take, method_options, context, out_path, start);
  }
  absl::StatusOr<Reenactment> made = absl::InternalError("no phase ran");
  if (input.phase == MethodPhase::kStitch) {
    ASSIGN_OR_RETURN(const std::string prepared,
                     ReadFileToString(input.prepared_path, kMaxPartFileBytes));
    std::vector<std::string> segments;
    for (const std::string& path : input.segment_paths) {
      ASSIGN_OR_RETURN(std::string segment, ReadFileToString(path, kMaxPartFileBytes));
      segments.push_back(std::move(segment));
    }
    made = method->Stitch(*take, method_options, context, prepared, segments);
  } else {
    made = method->Run(*take, method_options, context);
  }
  if (!made.ok()) return made.status();
  Reenactment& data = *made;

  // Bookkeeping.
  ReenactmentInfo& info = data.info;
  info.reenactment_id = input.reenactment_id;
  info.take_id = input.take_id;
  info.job_id = input.job_id;
  info.method = input.method;
  info.texture_mode = method->spec().texture;
  info.options.clear();
  for (const auto& [key, value] : input.options) info.options[key] = value;
  info.created_unix_ns = NowUnixNs();
  info.generator = kGenerator;
  info.frame_count = static_cast<int>(data.frames.size());
  if (!(info.fps > 0)) info.fps = take->fps();
  if (info.part_names.empty() && !data.is_body()) info.part_names = BodyPartNames();
  info.sensors.clear();
  for (const TakeSensor& sensor : take->sensors()) info.sensors.push_back(sensor.calibration);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto& figures = info.figures;
  figures["seconds"] = seconds;
  figures["load_seconds"] = load_s;
  figures["frames_per_second"] = seconds > 0 ? data.frames.size() / seconds : 0.0;

  // Write.
  if (progress && !progress({"write", 0.95, 0, 1})) {
    return absl::CancelledError("cancelled before writing the reenactment");
  }
  RETURN_IF_ERROR(WriteReenactment(data, out_path));
  if (progress && !progress({"write", 1.0, 1, 1})) {
    std::error_code ec;
    std::filesystem::remove(out_path, ec);
    return absl::CancelledError("cancelled after writing the reenactment");
  }

  MethodResult result;
  result.frames = static_cast<int>(data.frames.size());
  result.keyframes = static_cast<int>(data.keyframes.size());
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(out_path, ec);
  result.file_bytes = ec ? 0 : static_cast<int64_t>(bytes);
  result.figures.insert(figures.begin(), figures.end());
  if (log) {
    log(absl::StrCat("write: ", out_path, ", ", result.file_bytes, " bytes, ", result.frames,
                     " frames, ", result.keyframes, " keyframes, ", seconds, " s"));
  }
  return result;
}

absl::StatusOr<std::vector<SensorFrameNeeds>> FramesNeeded(const MethodInput& input) {
  const ReconstructionMethod* method = FindMethod(input.method);
  if (method == nullptr) return methods::UnknownMethodError(MethodSpecs(), input.method);
  OptionMap load_options, method_options;
  SplitLoadOptions(input.options, &load_options, &method_options);
  LoadOptions load;
  RETURN_IF_ERROR(methods::ParseOptions(load_options, &load));
  RETURN_IF_ERROR(method->CheckOptions(method_options));
  ASSIGN_OR_RETURN(const std::unique_ptr<TakeFrames> take,
                   TakeFrames::Load(input.take_path, load.frames));
  std::vector<SensorFrameNeeds> out(take->num_sensors());
  for (int s = 0; s < take->num_sensors(); ++s) out[s].sensor_id = take->sensors()[s].sensor_id;
  const auto add = [&](const std::vector<int>& instants, bool color) -> absl::Status {
    for (const int i : instants) {
      if (i < 0 || i >= take->num_instants()) {
        return absl::InternalError(absl::StrCat("method ", input.method, " needs instant ", i,
                                                " of ", take->num_instants()));
      }
      for (int s = 0; s < take->num_sensors(); ++s) {
        const SensorView& view = take->instant(i).views[s];
        if (!view.present) continue;
        (color ? out[s].color_frames : out[s].depth_frames).push_back(view.frame_index);
      }
    }
    return absl::OkStatus();
  };
  if (take->num_valid_instants() == 0) {
    // No skeleton: the run tracks the take first (take_tracking.h), which
    // reads every depth frame of every sensor, instants or not, and what
    // the method needs is known only after that: every image. (This is the
    // take without image bytes, so skeletons kept beside the stored take
    // are not at hand here.)
    ASSIGN_OR_RETURN(const std::unique_ptr<TakeReader> reader, TakeReader::Open(input.take_path));
    for (SensorFrameNeeds& sensor : out) {
      RETURN_IF_ERROR(reader->ForEach<v1::DepthImage>(
          SensorTopic(sensor.sensor_id, "depth"), [&sensor](const v1::DepthImage& m) {
            sensor.depth_frames.push_back(m.frame_index());
            return absl::OkStatus();
          }));
      RETURN_IF_ERROR(reader->ForEach<v1::ColorImage>(
          SensorTopic(sensor.sensor_id, "color"), [&sensor](const v1::ColorImage& m) {
            sensor.color_frames.push_back(m.frame_index());
            return absl::OkStatus();
          }));
    }
  } else {
    ASSIGN_OR_RETURN(const TakeNeeds needs,
                     method->Needs(*take, method_options, input.phase, input.segment_index,
                                   input.segment_count));
    RETURN_IF_ERROR(add(needs.depth, false));
    RETURN_IF_ERROR(add(needs.color, true));
  }
  for (SensorFrameNeeds& sensor : out) {
    for (std::vector<int64_t>* frames : {&sensor.depth_frames, &sensor.color_frames}) {
      std::sort(frames->begin(), frames->end());
      frames->erase(std::unique(frames->begin(), frames->end()), frames->end());
    }
  }
  return out;
}

}  // namespace reenact::recon
