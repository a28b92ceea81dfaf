// Motions keyframed by Reenact itself, so that a synthetic take needs no
// download: a slow lateral arm raise, a squat and a front kick. They are
// Motions on the canonical (Kinect v2) skeleton in a T-pose rest, facing +Z,
// feet on y = 0, and go through the same retargeting as recorded BVH/ASF
// motion.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "common/body/motion.h"

namespace reenact::synth {

// "arm-raise", "squat", "front-kick".
std::vector<std::string> BuiltinMotionNames();

// One cycle of the named motion (looped to `seconds`, at `fps`). NotFound for
// an unknown name, listing the known ones.
absl::StatusOr<body::Motion> MakeBuiltinMotion(std::string_view name, double seconds = 10.0,
                                               double fps = 30.0);

}  // namespace reenact::synth
