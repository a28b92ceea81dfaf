#include "clients/cli/fit_diagnosis.h"

#include <optional>
#include <ostream>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/terminal_text.h"

namespace reenact::cli {
namespace {

std::optional<double> Figure(const v1::ReenactmentInfo& info, const std::string& key) {
  const auto it = info.figures().find(key);
  if (it == info.figures().end()) return std::nullopt;
  return it->second;
}

// The figures of sensor `id`: explained share, RMS, surface seen.
struct SensorFigures {
  double explained = 0.0;
  double rms_mm = 0.0;
  double seen = 0.0;
};

std::optional<SensorFigures> FiguresOfSensor(const v1::ReenactmentInfo& info,
                                             const std::string& id) {
  const std::string prefix = absl::StrCat("sensor.", id, ".");
  const auto explained = Figure(info, prefix + "explained_fraction");
  const auto rms = Figure(info, prefix + "rms_mm");
  const auto seen = Figure(info, prefix + "surface_seen_fraction");
  if (!explained || !rms || !seen) return std::nullopt;
  return SensorFigures{*explained, *rms, *seen};
}

}  // namespace

void PrintFitDiagnosis(const v1::ReenactmentInfo& info, std::ostream& out) {
  for (const v1::SensorCalibration& sensor : info.sensors()) {
    const auto f = FiguresOfSensor(info, sensor.sensor_id());
    if (!f) continue;
    out << absl::StrFormat(
        "fit          sensor %s: %.1f %% of its points explained (RMS %.1f mm), %.0f %% of the "
        "surface facing it seen\n",
        TerminalSafe(sensor.sensor_id()), 100.0 * f->explained, f->rms_mm, 100.0 * f->seen);
  }
  const auto frames = Figure(info, "doubtful_frames");
  if (!frames && info.doubtful_spans().empty()) return;
  if (info.doubtful_spans().empty()) {
    out << "doubtful     none: the sensors agree with every fit\n";
    return;
  }
  out << absl::StrFormat("doubtful     %d frames in %d spans\n",
                         static_cast<int>(frames.value_or(0.0)), info.doubtful_spans_size());
  int printed = 0;
  for (const v1::DoubtfulSpan& span : info.doubtful_spans()) {
    if (printed++ == kMaxPrintedSpans) {
      out << "  ... and " << info.doubtful_spans_size() - kMaxPrintedSpans << " more spans\n";
      break;
    }
    out << absl::StrFormat("  %7.2f .. %7.2f s  frames %d-%d: %s\n", span.start_s(), span.end_s(),
                           span.first_frame(), span.last_frame(), TerminalSafe(span.reason()));
  }
}

nlohmann::json FitDiagnosisJson(const v1::ReenactmentInfo& info) {
  nlohmann::json sensors = nlohmann::json::array();
  for (const v1::SensorCalibration& sensor : info.sensors()) {
    const auto f = FiguresOfSensor(info, sensor.sensor_id());
    if (!f) continue;
    sensors.push_back({{"sensor_id", sensor.sensor_id()},
                       {"explained_fraction", f->explained},
                       {"rms_mm", f->rms_mm},
                       {"surface_seen_fraction", f->seen}});
  }
  nlohmann::json spans = nlohmann::json::array();
  for (const v1::DoubtfulSpan& span : info.doubtful_spans()) {
    spans.push_back({{"first_frame", span.first_frame()},
                     {"last_frame", span.last_frame()},
                     {"start_s", span.start_s()},
                     {"end_s", span.end_s()},
                     {"reason", span.reason()}});
  }
  // Null where the method does not judge its frames.
  const auto frames = Figure(info, "doubtful_frames");
  return {{"sensors", sensors},
          {"doubtful_frames", frames ? nlohmann::json(*frames) : nlohmann::json(nullptr)},
          {"doubtful_spans", spans}};
}

}  // namespace reenact::cli
