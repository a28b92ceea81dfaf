#include "clients/cli/commands.h"

namespace reenact::cli {

std::vector<Command> BuildCommandTable() {
  return {
      {{"motion", "info"}, "FILE [--asf F] [--json]",
       "frames, fps, joints and length unit of a BVH or ASF/AMC motion", RunMotionInfo},
      {{"motion", "joints"}, "FILE [--asf F] --frame N --json",
       "world joint positions (metres, Kinect v2 names) of one frame", RunMotionJoints},
      {{"synth"},
       "--motion FILE.bvh|FILE.amc|builtin:NAME [--asf FILE] --body procedural|makehuman:DIR "
       "[--shape mean|random[:SEED]] --sensors 1|2 --seconds S --out take.mcap [--json]",
       "synthesise a take: a body doing a motion seen by virtual Kinect v2 sensors", RunSynth},
      {{"take", "info"}, "FILE [--json]", "sensors, channels, frames and duration of a take",
       RunTakeInfo},
      {{"take", "sheet"}, "FILE --out sheet.png [--frames N]",
       "contact sheet: colour with skeleton, depth and mask of a few frames per sensor",
       RunTakeSheet},
  };
}

}  // namespace reenact::cli
