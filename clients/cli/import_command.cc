// `reenact import`: a recording made by another tool (Azure Kinect .mkv, TUM
// RGB-D folder, OpenNI2 .oni, a folder of depth PNGs) as a take
// (common/io/recordings).
#include <functional>
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
#include "common/io/recordings/recording.h"
#include "common/io/recordings/recording_import.h"

namespace reenact::cli {
namespace {

// Prints "imported N of M frames" to `err` every 30 frames.
std::function<void(int64_t)> ProgressPrinter(std::ostream& err, int64_t total) {
  return [&err, total](int64_t frames) {
    if (frames % 30 != 0) return;
    err << "\rimported " << frames << (total > 0 ? absl::StrCat(" of ", total) : "") << " frames"
        << std::flush;
  };
}

}  // namespace

int RunImport(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args,
                            {"out", "format", "max-frames", "intrinsics", "sensor-id",
                             "jpeg-quality", "name", "depth-units-per-m", "fps"},
                            {"quiet", "json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_path = flags->Required("out");
  if (!out_path.ok()) return ReportError(out_path.status(), err);
  auto max_frames = flags->GetInt("max-frames", 0);
  if (!max_frames.ok()) return ReportError(max_frames.status(), err);
  auto quality = flags->GetInt("jpeg-quality", 90);
  if (!quality.ok()) return ReportError(quality.status(), err);
  if (flags->positional().size() != 1 || *max_frames < 0 || *quality < 1 || *quality > 100) {
    return ReportError(absl::InvalidArgumentError(
                           "import needs one FILE|DIR, --out take.mcap, --max-frames >= 0 and "
                           "--jpeg-quality 1..100"),
                       err);
  }
  const std::string& source = flags->positional()[0];
  absl::StatusOr<recordings::RecordingFormat> format =
      flags->Has("format") ? recordings::ParseFormat(*flags->Get("format"))
                           : recordings::DetectFormat(source);
  if (!format.ok()) {
    // An unknown --format name is a usage error; a path that is missing or
    // of no known kind is bad input.
    if (flags->Has("format")) return ReportError(format.status(), err);
    err << "reenact: " << format.status().message() << "\n";
    return kExitFailure;
  }
  recordings::RecordingOptions options;
  options.intrinsics_path = flags->GetOr("intrinsics", "");
  auto units = flags->GetDouble("depth-units-per-m", 0.0);
  if (!units.ok()) return ReportError(units.status(), err);
  auto fps = flags->GetDouble("fps", 0.0);
  if (!fps.ok()) return ReportError(fps.status(), err);
  options.depth_units_per_m = *units;
  options.fps = *fps;
  const bool folder = *format == recordings::RecordingFormat::kTum ||
                      *format == recordings::RecordingFormat::kDepthFolder;
  if ((flags->Has("intrinsics") || flags->Has("depth-units-per-m")) && !folder) {
    return ReportError(absl::InvalidArgumentError(
                           "--intrinsics and --depth-units-per-m apply to TUM and depth-png "
                           "folders (the other formats carry their own calibration)"),
                       err);
  }
  if (flags->Has("fps") && *format != recordings::RecordingFormat::kDepthFolder) {
    return ReportError(
        absl::InvalidArgumentError("--fps applies to depth-png folders (the others are stamped)"),
        err);
  }
  if (*units != 0 && !(*units >= 1 && *units <= 1e6)) {
    return ReportError(absl::InvalidArgumentError("--depth-units-per-m must be in [1, 10^6]"), err);
  }
  if (!(*fps >= 0 && *fps <= 1000)) {
    return ReportError(absl::InvalidArgumentError("--fps must be in (0, 1000]"), err);
  }
  auto reader = recordings::OpenRecording(source, *format, options);
  if (!reader.ok()) {
    err << "reenact: " << reader.status().message() << "\n";
    return kExitFailure;
  }
  recordings::ImportOptions import;
  import.sensor_id = flags->GetOr("sensor-id", "");
  import.max_frames = *max_frames;
  import.jpeg_quality = *quality;
  import.take_name = flags->GetOr("name", "");
  const bool quiet = flags->Has("quiet") || flags->Has("json");
  const int64_t total = (*reader)->info().frame_count;
  if (!quiet) import.progress = ProgressPrinter(err, total);
  absl::StatusOr<recordings::ImportReport> report =
      recordings::ImportRecording(**reader, *out_path, import);
  if (!quiet) err << "\n";
  if (!report.ok()) {
    err << "reenact: import of " << source << " failed: " << report.status().message() << "\n";
    return kExitFailure;
  }
  const recordings::RecordingInfo& info = (*reader)->info();
  nlohmann::json j = {
      {"source", source},
      {"format", recordings::FormatName(*format)},
      {"out", *out_path},
      {"sensor", report->sensor_id},
      {"frames", report->frames},
      {"frames_with_color", report->frames_with_color},
      {"duration_s", (report->last_stamp_ns - report->first_stamp_ns) * 1e-9},
      {"fps", info.nominal_fps},
      {"depth", {info.depth_lens.pinhole.width, info.depth_lens.pinhole.height}},
      {"color",
       {info.has_color ? info.color_lens.pinhole.width : 0,
        info.has_color ? info.color_lens.pinhole.height : 0}},
      {"lens_fit_px", {{"depth", report->depth_lens_fit_px}, {"color", report->color_lens_fit_px}}},
      {"calibration", info.calibration_note}};
  if (flags->Has("json")) {
    out << j.dump(2) << "\n";
  } else {
    out << "wrote " << *out_path << ": " << report->frames << " frames ("
        << report->frames_with_color << " with colour) of sensor " << report->sensor_id << " from "
        << recordings::FormatName(*format) << " " << source << "\n  " << info.calibration_note
        << "\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
