#include "server/recon/body/body_diagnosis.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace reenact::recon {
namespace {

// How badly a frame's fit is contradicted (lower is worse; 1 when it is not
// doubtful) and why.
struct Doubt {
  double score = 1.0;
  std::string reason;
};

std::string SensorName(int sensor, const std::vector<std::string>& sensor_ids) {
  if (sensor >= 0 && static_cast<size_t>(sensor) < sensor_ids.size()) {
    return absl::StrCat("sensor ", sensor_ids[sensor]);
  }
  return absl::StrCat("sensor #", sensor);
}

Doubt DoubtOf(const ReenactmentFrame& frame, const std::vector<std::string>& sensor_ids,
              const DoubtOptions& o) {
  Doubt doubt;
  if (!frame.body.has_value()) return doubt;
  const BodyFramePose& body = *frame.body;
  if (!body.valid) {
    doubt.score = 0.0;
    doubt.reason = body.sensor_fits.empty()
                       ? "no fit: too few points or no skeleton"
                       : "no pose explains the points (the fit is kept but hidden)";
    return doubt;
  }
  for (const SensorFit& fit : body.sensor_fits) {
    if (fit.points < o.min_points) continue;
    // Each test's value over its threshold: below 1 fails.
    const double explained = fit.explained_fraction / o.min_explained;
    const double seen = fit.surface_seen_fraction / o.min_surface_seen;
    if (explained < 1.0 && explained < doubt.score) {
      doubt.score = explained;
      doubt.reason =
          absl::StrFormat("the fit explains %.0f %% of %s's points", 100.0 * fit.explained_fraction,
                          SensorName(fit.sensor, sensor_ids));
    }
    if (seen < 1.0 && seen < doubt.score) {
      doubt.score = seen;
      doubt.reason =
          absl::StrFormat("%s sees the actor on %.0f %% of the fitted surface facing it",
                          SensorName(fit.sensor, sensor_ids), 100.0 * fit.surface_seen_fraction);
    }
  }
  return doubt;
}

}  // namespace

std::string DoubtAbout(const ReenactmentFrame& frame, const std::vector<std::string>& sensor_ids,
                       const DoubtOptions& options) {
  return DoubtOf(frame, sensor_ids, options).reason;
}

std::vector<DoubtfulSpan> FindDoubtfulSpans(const std::vector<ReenactmentFrame>& frames,
                                            const std::vector<std::string>& sensor_ids,
                                            const DoubtOptions& options) {
  std::vector<DoubtfulSpan> spans;
  if (frames.empty()) return spans;
  const int64_t origin = frames.front().stamp_ns;
  const auto seconds = [&](size_t i) {
    return 1e-9 * static_cast<double>(frames[i].stamp_ns - origin);
  };
  double worst = 1.0;
  int frames_in_span = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Doubt doubt = DoubtOf(frames[i], sensor_ids, options);
    if (doubt.reason.empty()) {
      frames_in_span = 0;
      continue;
    }
    const int index = static_cast<int>(i);
    if (frames_in_span == 0) {
      spans.push_back({index, index, seconds(i), seconds(i), doubt.reason});
      worst = doubt.score;
    } else {
      spans.back().last_frame = index;
      spans.back().end_s = seconds(i);
      if (doubt.score < worst) {
        worst = doubt.score;
        spans.back().reason = doubt.reason;
      }
    }
    ++frames_in_span;
  }
  return spans;
}

void AddDiagnosisFigures(const std::vector<ReenactmentFrame>& frames,
                         const std::vector<std::string>& sensor_ids,
                         const std::vector<DoubtfulSpan>& spans,
                         std::map<std::string, double>* figures) {
  struct Sums {
    int frames = 0;
    double explained = 0.0;
    double rms = 0.0;
    double seen = 0.0;
  };
  std::vector<Sums> sums(sensor_ids.size());
  for (const ReenactmentFrame& frame : frames) {
    if (!frame.body.has_value() || !frame.body->valid) continue;
    for (const SensorFit& fit : frame.body->sensor_fits) {
      if (fit.sensor < 0 || static_cast<size_t>(fit.sensor) >= sums.size() || fit.points == 0) {
        continue;
      }
      Sums& s = sums[fit.sensor];
      ++s.frames;
      s.explained += fit.explained_fraction;
      s.rms += fit.rms_mm;
      s.seen += fit.surface_seen_fraction;
    }
  }
  for (size_t k = 0; k < sums.size(); ++k) {
    const Sums& s = sums[k];
    if (s.frames == 0) continue;
    const std::string prefix = absl::StrCat("sensor.", sensor_ids[k], ".");
    (*figures)[prefix + "explained_fraction"] = s.explained / s.frames;
    (*figures)[prefix + "rms_mm"] = s.rms / s.frames;
    (*figures)[prefix + "surface_seen_fraction"] = s.seen / s.frames;
  }
  int doubtful = 0;
  for (const DoubtfulSpan& span : spans) doubtful += span.last_frame - span.first_frame + 1;
  (*figures)["doubtful_frames"] = doubtful;
  (*figures)["doubtful_spans"] = static_cast<double>(spans.size());
}

}  // namespace reenact::recon
