#include "server/recon/methods.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_file.h"
#include "server/recon/body/body_method.h"
#include "server/recon/cylinders.h"
#include "server/recon/method_util.h"
#include "server/recon/take_frames.h"
#if REENACT_HAVE_RIGID_CARVED
#include "server/recon/carving/rigid_carved.h"
#endif

namespace reenact::recon {
namespace {

constexpr char kRigidCylinders[] = "rigid-cylinders";
constexpr char kRigidCarved[] = "rigid-carved";
constexpr char kBody[] = "body";
constexpr char kGenerator[] = "reenact-recon 0.1.0";

// Options RunMethod itself reads (loading), taken out before the method
// sees the rest.
struct LoadOptions {
  TakeFramesOptions frames;
};

absl::Status ReadLoadOptions(std::map<std::string, std::string>* options, LoadOptions* out) {
  std::map<std::string, std::string> mine;
  for (const char* key : {"threads", "max_frames"}) {
    auto it = options->find(key);
    if (it == options->end()) continue;
    mine.insert(*it);
    options->erase(it);
  }
  OptionReader reader(mine);
  RETURN_IF_ERROR(reader.Int("threads", &out->frames.num_threads, 0, 256));
  RETURN_IF_ERROR(reader.Int("max_frames", &out->frames.max_instants, 0));
  return reader.Finish();
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

}  // namespace

std::vector<std::string> MethodNames() { return {kRigidCylinders, kRigidCarved, kBody}; }

absl::StatusOr<MethodResult> RunMethod(const MethodInput& input, const std::string& out_path,
                                       const ProgressCallback& progress, const LogCallback& log) {
  const auto start = std::chrono::steady_clock::now();
  const bool cylinders = input.method == kRigidCylinders;
  const bool body = input.method == kBody;
  if (!cylinders && !body && input.method != kRigidCarved) {
    return absl::InvalidArgumentError(absl::StrCat(
        "unknown method \"", input.method, "\" (known: ", absl::StrJoin(MethodNames(), ", "), ")"));
  }
#if !REENACT_HAVE_RIGID_CARVED
  if (!cylinders && !body) {
    return absl::UnimplementedError("method rigid-carved is not built into this program");
  }
#endif
  if (out_path.empty()) return absl::InvalidArgumentError("no output path");
  std::map<std::string, std::string> method_options = input.options;
  LoadOptions load;
  RETURN_IF_ERROR(ReadLoadOptions(&method_options, &load));
  if (cylinders) {
    // Reject bad options before the (slow) load.
    CylinderOptions options;
    OptionReader reader(method_options);
    RETURN_IF_ERROR(options.Read(reader));
    RETURN_IF_ERROR(reader.Finish());
  }
  if (body) RETURN_IF_ERROR(CheckBodyOptions(method_options));

  // Load.
  ASSIGN_OR_RETURN(std::unique_ptr<TakeFrames> take,
                   TakeFrames::Load(input.take_path, load.frames, SubRange(progress, 0.0, 0.15)));
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
  const ProgressCallback method_progress = SubRange(progress, 0.15, 0.95);
  absl::StatusOr<ReenactmentData> made;
  if (cylinders) {
    made = RunRigidCylinders(*take, method_options, method_progress, log);
  } else if (body) {
    made = RunBody(*take, method_options, input.asset_roots, method_progress, log);
  } else {
#if REENACT_HAVE_RIGID_CARVED
    made = RunRigidCarved(*take, method_options, method_progress, log);
#endif
  }
  if (!made.ok()) return made.status();
  ReenactmentData& data = *made;

  // Bookkeeping.
  v1::ReenactmentInfo& info = data.info;
  info.set_reenactment_id(input.reenactment_id);
  info.set_take_id(input.take_id);
  info.set_job_id(input.job_id);
  info.set_method(input.method);
  info.mutable_options()->clear();
  for (const auto& [key, value] : input.options) (*info.mutable_options())[key] = value;
  info.set_created_unix_ns(NowUnixNs());
  info.set_generator(kGenerator);
  info.set_frame_count(static_cast<int32_t>(data.frames.size()));
  if (!(info.fps() > 0)) info.set_fps(take->fps());
  if (info.part_names_size() == 0 && !data.is_body()) {
    for (const std::string& name : BodyPartNames()) info.add_part_names(name);
  }
  info.clear_sensors();
  for (const TakeSensor& sensor : take->sensors()) *info.add_sensors() = sensor.calibration;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto& figures = *info.mutable_figures();
  figures["seconds"] = seconds;
  figures["load_seconds"] = load_s;
  figures["frames_per_second"] = seconds > 0 ? data.frames.size() / seconds : 0.0;

  // Write.
  if (progress && !progress({"write", 0.95, 0, 1})) {
    return absl::CancelledError("cancelled before writing the reenactment");
  }
  RETURN_IF_ERROR(WriteReenactmentFile(data, out_path));
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

}  // namespace reenact::recon
