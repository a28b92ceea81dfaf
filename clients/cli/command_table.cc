#include "clients/cli/commands.h"

namespace reenact::cli {

std::vector<Command> BuildCommandTable() {
  return {
      {{"motion", "info"}, "FILE [--asf F] [--json]",
       "frames, fps, joints and length unit of a BVH or ASF/AMC motion", RunMotionInfo},
      {{"motion", "joints"}, "FILE [--asf F] --frame N --json",
       "world joint positions (metres, Kinect v2 names) of one frame", RunMotionJoints},
  };
}

}  // namespace reenact::cli
