// A reenactment's own judgement of its frames, as `reenact jobs show` and
// `reenact reenactments show` print it: per sensor, how well the body fits
// explain what it saw (figures "sensor.ID.*"), and the doubtful spans
// (ReenactmentInfo.doubtful_spans; server/recon/body/body_diagnosis.h).
#pragma once

#include <iosfwd>

#include <nlohmann/json.hpp>

#include "reenact/v1/reenactment.pb.h"

namespace reenact::cli {

// At most this many spans are printed; the rest are counted.
inline constexpr int kMaxPrintedSpans = 12;

// Lines "fit ..." per sensor and "doubtful ..." per span; nothing for a
// reenactment without them.
void PrintFitDiagnosis(const v1::ReenactmentInfo& info, std::ostream& out);

// {"sensors": [...], "doubtful_frames": N (null when not judged),
// "doubtful_spans": [...]}.
nlohmann::json FitDiagnosisJson(const v1::ReenactmentInfo& info);

}  // namespace reenact::cli
