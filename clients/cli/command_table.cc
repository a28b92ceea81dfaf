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
      {{"takes", "list"}, "[--server HOST:PORT] [--state recording|complete|interrupted|all] [--json]",
       "takes stored on a reenact-server, newest first", RunTakesList},
      {{"takes", "show"}, "TAKE_ID [--server HOST:PORT] [--json]",
       "one stored take: state, frame sets, sensors, size", RunTakesShow},
      {{"takes", "download"}, "TAKE_ID --out FILE.mcap [--server HOST:PORT] [--quiet]",
       "download a stored take as an MCAP file", RunTakesDownload},
      {{"takes", "delete"}, "TAKE_ID [--server HOST:PORT]", "delete a stored take",
       RunTakesDelete},
      {{"capture", "sensors"}, "[--daemon HOST:PORT] [--json]",
       "sensors a reenactd capture daemon sees", RunCaptureSensors},
      {{"capture", "status"}, "[--daemon HOST:PORT] [--json]",
       "take, uplink, spool and sync figures of a capture daemon", RunCaptureStatus},
      {{"capture", "start"}, "[--daemon HOST:PORT] [--name NAME] [--notes TEXT] [--max-seconds S]",
       "start recording a take; prints its id", RunCaptureStart},
      {{"capture", "stop"}, "[--daemon HOST:PORT]", "stop the take being recorded",
       RunCaptureStop},
  };
}

}  // namespace reenact::cli
