// Which moments of a body-model reenactment to doubt: each instant's fit
// against each sensor's view (SensorFit), summed into the reenactment's
// figures, and the instants whose fit the sensors contradict gathered into
// DoubtfulSpans, so that a coach sees where the reenactment is unreliable
// (`reenact jobs show`, `reenact reenactments show`).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "common/model/reenactment.h"

namespace reenact::recon {

struct DoubtOptions {
  // A sensor judges an instant only with at least this many of its points.
  int min_points = 200;
  // An instant is doubtful when the fit explains less than this share of a
  // sensor's points, or when less than min_surface_seen of the fitted
  // surface facing a sensor is where that sensor saw the actor.
  double min_explained = 0.9;
  double min_surface_seen = 0.8;
};

// Why `frame` is doubtful ("" when it is not): no valid fit, or the sensor
// that contradicts the fit most. `sensor_ids[k]` names sensor k.
std::string DoubtAbout(const ReenactmentFrame& frame, const std::vector<std::string>& sensor_ids,
                       const DoubtOptions& options = {});

// The doubtful instants of `frames` (one per instant, in order) as spans of
// consecutive instants, each with the reason of its worst instant; times
// from the first frame's stamp.
std::vector<DoubtfulSpan> FindDoubtfulSpans(const std::vector<ReenactmentFrame>& frames,
                                            const std::vector<std::string>& sensor_ids,
                                            const DoubtOptions& options = {});

// Per sensor, the means over the instants it saw: "sensor.ID.explained_fraction",
// "sensor.ID.rms_mm", "sensor.ID.surface_seen_fraction"; and the doubtful
// instants and spans ("doubtful_frames", "doubtful_spans").
void AddDiagnosisFigures(const std::vector<ReenactmentFrame>& frames,
                         const std::vector<std::string>& sensor_ids,
                         const std::vector<DoubtfulSpan>& spans,
                         std::map<std::string, double>* figures);

}  // namespace reenact::recon
