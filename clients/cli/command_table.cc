#include "clients/cli/commands.h"

namespace reenact::cli {

std::vector<Command> BuildCommandTable() {
  return {
      {{"motion", "info"},
       "FILE [--asf F] [--json]",
       "frames, fps, joints and length unit of a BVH or ASF/AMC motion",
       RunMotionInfo},
      {{"motion", "joints"},
       "FILE [--asf F] --frame N --json",
       "world joint positions (metres, Kinect v2 names) of one frame",
       RunMotionJoints},
      {{"synth"},
       "--motion FILE.bvh|FILE.amc|builtin:NAME [--asf FILE] --body procedural|makehuman:DIR "
       "[--shape mean|random[:SEED]] [--wardrobe default|solid|print|stripes] --sensors 1|2 "
       "--seconds S --out take.mcap [--fps F] "
       "[--yaw-deg D] [--lead-in-s S] [--distance M] [--color-width W --color-height H] "
       "[--jpeg-quality Q] "
       "[--seed N] [--no-depth-noise] [--no-mesh] [--board [SPEC]] "
       "[--board-x-m X --board-z-m Z --board-yaw-deg D] [--sensor-skeleton none|truth] "
       "[--skeleton-limb-noise-mm N --skeleton-arm-swaps FRACTION --skeleton-leg-drop-s S "
       "--skeleton-lock-on-s S] [--calibration-error-cm C] "
       "[--quiet] [--json]",
       "synthesise a take: a body doing a motion seen by virtual Kinect v2 sensors "
       "(--yaw-deg turns the performer about the vertical; --lead-in-s holds the first pose "
       "that long before moving; --board lays the printed board on the floor as the world "
       "frame; the sensors carry no skeleton unless --sensor-skeleton truth, as real depth "
       "cameras: the capture daemon tracks them; the --skeleton-* flags make that skeleton "
       "worse on purpose, the same in every sensor: noise on the limbs, arms swapped in a "
       "fraction of the frames, the left leg lost mid-take, no body found at the start; "
       "--calibration-error-cm stores the last sensor's pose that far off along +X)",
       RunSynth},
      {{"board"},
       "--out board.png [--spec aruco:DICT:COLSxROWS:MARKER_MM:GAP_MM] [--dpi N] "
       "[--margin-mm M] [--no-caption] [--json]",
       "write the printable ArUco board that defines the world frame (default "
       "aruco:DICT_4X4_50:3x2:110:22, A3) as a PNG; prints its physical size",
       RunBoard},
      {{"take", "info"},
       "FILE [--json]",
       "sensors, channels, frames and duration of a take",
       RunTakeInfo},
      {{"take", "sheet"},
       "FILE --out sheet.png [--frames N]",
       "contact sheet: colour with skeleton, depth and mask of a few frames per sensor",
       RunTakeSheet},
      {{"take", "frame"},
       "TAKE.mcap [--sensor ID] --index N [--depth-png F] [--color F] [--json]",
       "one frame of a sensor: its depth as a 16-bit PNG in millimetres, its colour as stored "
       "(JPEG bytes), with the frame's stamps and the sensor's calibration",
       RunTakeFrame},
      {{"import"},
       "FILE|DIR --out take.mcap [--format azure-mkv|tum|oni|depth-png] [--max-frames N] "
       "[--intrinsics FILE] [--depth-units-per-m U] [--fps F] [--sensor-id ID] "
       "[--jpeg-quality Q] [--name NAME] [--quiet] [--json]",
       "a recording made by another tool as a take: an Azure Kinect .mkv (k4arecorder; its "
       "calibration.json), a TUM RGB-D folder (rgb.txt, depth.txt; default intrinsics fx=fy=525, "
       "cx=319.5, cy=239.5 unless --intrinsics \"fx fy cx cy [d0..d4]\"), an OpenNI2 .oni, or a "
       "folder of 16-bit depth PNGs with no colour (frames named in order, or in frames/; "
       "millimetres unless --depth-units-per-m; the lens from --intrinsics or the folder's "
       "meta.json; --fps, default meta.json's or 30); the format follows from the path unless "
       "--format",
       RunImport},
      {{"take", "skeletons"},
       "TAKE.mcap --truth SYNTH.mcap [--track [--model F.onnx | --forest F] [--refine]] [--json]",
       "measure a take's skeletons against a synthetic take's ground truth (TAKE itself, or the "
       "synthetic take a daemon streamed into the stored TAKE): MPJPE, PCK@10cm and per-joint "
       "errors per sensor and fused over the sensors (left/right swaps fixed, lost joints "
       "down-weighted); --track: of skeletons tracked afresh from the take's depth",
       RunTakeSkeletons},
      {{"track"},
       "--depth FILE [--size WxH] --intrinsics kinect1|kinect2|FX,FY,CX,CY [--model F.onnx | "
       "--forest F.rtf] [--refine] [--json]",
       "the people in one depth image (16-bit PNG in mm, or raw little-endian uint16 mm with "
       "--size), each with the 25 Kinect v2 joints: position in the camera frame, pixel, "
       "confidence and state",
       RunTrack},
      {{"tracker", "train"},
       "[--out models/tracker/body_parts.rtf] [--data DIR] [--images N] [--seed S] "
       "[--bodies procedural,makehuman:DIR] [--shapes N] [--trees T] [--depth D] [--pixels P] "
       "[--features F] [--min-samples-leaf M] [--arm-poses FRACTION] [--threads N] [--quiet] "
       "[--json]",
       "train the body tracker's forest on depth synthesised from DIR/mocap/cmu-train and the "
       "body models (deterministic for a seed; --arm-poses: share of images whose arms are posed "
       "at random in front of the body, default 0.3)",
       RunTrackerTrain},
      {{"tracker", "eval"},
       "[--real DIR [--sequences NAME,...] [--no-history] [--segment] [--joints-out F.jsonl] "
       "[--model F.onnx | --forest F.rtf] [--refine]] | [--forest F] [--data DIR] [--images N] "
       "[--seed S] [--bodies ...] [--min-distance M] [--max-distance M] [--stride N] "
       "[--motions-dir DIR] [--sequence [--frame-stride K]] [--no-refine] [--json]",
       "measure the tracker. --real DIR: on recorded depth sequences laid out like "
       "shared/data/rgbd-seq (one, or every sub-folder with a meta.json), each tracked as a take "
       "(previous frames included; --no-history: each frame alone) against the skeleton stored "
       "per frame: MPJPE and PCK@10cm over the 20 body joints, the share of frames with left and "
       "right swapped, per joint, per sequence and overall; --joints-out writes one JSON line "
       "per frame. Otherwise on frames synthesised from held-out motions (DIR/mocap/cmu) and "
       "shapes (--sequence: consecutive frames of one motion seen by a fixed camera)",
       RunTrackerEval},
      {{"tracker", "synth"},
       "--out DIR [--images N] [--seed S] [--held-out] [--sequence --motion F.bvh] "
       "[--min-distance M] [--max-distance M] [--arm-poses FRACTION] [--structured-light "
       "FRACTION] [--bodies ...] [--shapes N] [--data DIR] [--json]",
       "synthesise depth of posed bodies with their true joints, written as a folder laid out "
       "like shared/data/rgbd-seq (the tracker network's training data; --held-out: motions of "
       "DIR/mocap/cmu, never trained on; --sequence: one motion seen by a fixed camera, whole "
       "frames)",
       RunTrackerSynth},
      {{"grade"},
       "--teacher REENACTMENT|TAKE --learner TAKE [--sensor ID] [--teacher-id ID] "
       "[--teacher-sensor ID] [--teacher-joints stored|tracked|tracked-refined] [--server "
       "HOST:PORT [--tls-ca F] "
       "[--token-file F] [--cache DIR]] "
       "[--one-to-one] [--smoothing-s S] [--repetition-max-deg D] [--report DIR] [--pairs] "
       "[--json] | --real DIR "
       "[--sequences NAME,...] [--learners PATTERN,...] [--tracked [--model F.onnx | --forest "
       "F.rtf]] [--quiet] [--json]",
       "grade a learner's take against a teacher as the mirror does, with no window: per body "
       "part, only where the sensor saw it (the learner's TRACKED joints), over the frames paired "
       "by DTW (--one-to-one: index by index); prints the mean over the graded parts, how much "
       "of the body it covers, the parts not graded and why, and at most three corrections in "
       "words. It counts the repetitions of the teacher's action in the take (stretches within "
       "--repetition-max-deg, default 18, of it), grades each and all of them together, and "
       "times each of the teacher's holds against the learner's. "
       "--report DIR writes grade.json, heatmap.png (parts x time) and worst-moments.png. "
       "The teacher is a reenactment (a .reen file or folder, or an ID on --server) or a take; "
       "--teacher-joints tracked compares with a reenactment's joints as our tracker finds them "
       "in it drawn as depth and seen from the learner's side, instead of its stored joints "
       "(for a learner tracked from depth; tracked-refined for reenactd's --tracker-refine on). "
       "--real DIR: every pair of recordings of two people in a folder laid out like "
       "shared/data/rgbd-seq, graded from the stored SDK skeletons (and with --tracked from ours): "
       "how often a same-action pair grades lower than a different-action pair for the same "
       "learner, how our per-part grades agree with the SDK's, and how often a recording is "
       "counted as one repetition of the same action and none of another (--learners: only "
       "recordings "
       "whose names match these shell patterns grade as learners)",
       RunGrade},
      {{"auth", "add"},
       "--file TOKENS.json --role viewer|capture|coach|worker|admin --name NAME",
       "mint a random token for reenact-server --auth TOKENS.json (or reenactd --auth): appends "
       "its SHA-256 with the role and name to the file (made 0600 when new) and prints the token "
       "once (a file it is redirected to becomes 0600); clients send it with --token-file FILE "
       "(0600) or REENACT_TOKEN",
       RunAuthAdd},
      {{"auth", "list"},
       "--file TOKENS.json [--json]",
       "the names and roles in a token file (never a token: the file holds only their SHA-256)",
       RunAuthList},
      {{"auth", "remove"},
       "--file TOKENS.json --name NAME",
       "revoke a token: deletes its entry from the file; a running reenact-server reads the file "
       "again on SIGHUP",
       RunAuthRemove},
      {{"takes", "list"},
       "[--server HOST:PORT] [--state recording|complete|interrupted|all] [--page-size N] [--json]",
       "takes stored on a reenact-server, newest first (all of them, N a call)",
       RunTakesList},
      {{"takes", "show"},
       "TAKE_ID [--server HOST:PORT] [--json]",
       "one stored take: state, frame sets, sensors, size",
       RunTakesShow},
      {{"takes", "download"},
       "TAKE_ID --out FILE.mcap [--server HOST:PORT] [--quiet]",
       "download a stored take as an MCAP file",
       RunTakesDownload},
      {{"takes", "upload"},
       "TAKE.mcap [--server HOST:PORT] [--take-id ID] [--name NAME] [--spool DIR] "
       "[--spool-max-mb N] [--stall-timeout S] [--json] [--quiet]",
       "send a take file (imported, synthesised, downloaded) to a reenact-server through the "
       "capture daemon's durable ingest: a bounded disk spool, reconnects with backoff, resent "
       "from what the server holds; the take id comes from the file, so the same command "
       "resumes an interrupted upload and repeats a finished one harmlessly; ground truth is "
       "not sent",
       RunTakesUpload},
      {{"takes", "delete"},
       "TAKE_ID [--server HOST:PORT]",
       "delete a stored take with the reenactments and job folders made from it (unless the "
       "server runs with --keep-derived); refused while a job of the take is queued or running",
       RunTakesDelete},
      {{"capture", "sensors"},
       "[--daemon HOST:PORT] [--json]",
       "sensors a reenactd capture daemon sees",
       RunCaptureSensors},
      {{"capture", "status"},
       "[--daemon HOST:PORT] [--json]",
       "take, uplink, spool and sync figures of a capture daemon",
       RunCaptureStatus},
      {{"capture", "start"},
       "[--daemon HOST:PORT] [--name NAME] [--notes TEXT] [--max-seconds S]",
       "start recording a take; prints its id",
       RunCaptureStart},
      {{"capture", "stop"}, "[--daemon HOST:PORT]", "stop the take being recorded", RunCaptureStop},
      {{"jobs", "submit"},
       "--take ID --method NAME [--model procedural|makehuman:NAME] "
       "[--option KEY=VALUE ...] [--segments N | --live] [--server HOST:PORT] [--wait [--logs] "
       "[--quiet]] [--json]",
       "queue a reconstruction of a stored take by a method of `jobs methods` (rigid parts, "
       "thesis ch. 3, or the body model, ch. 4; --model is --option model=); --segments N "
       "splits the take across N workers (methods marked segmentable); --wait follows it "
       "with a progress bar; --live follows a take still recording, with a method that can "
       "(reenactments follow)",
       RunJobsSubmit},
      {{"jobs", "methods"},
       "[--server HOST:PORT] [--json]",
       "the reconstruction methods the server runs: what each does, whether it can follow a "
       "take live, and its options with types, defaults, bounds and documentation",
       RunJobsMethods},
      {{"jobs", "list"},
       "[--server HOST:PORT] [--state queued|running|succeeded|failed|cancelled|all] "
       "[--take ID] [--page-size N] [--json]",
       "jobs of a reenact-server, newest first (all of them, N a call)",
       RunJobsList},
      {{"jobs", "show"},
       "JOB_ID|--job ID [--server HOST:PORT] [--json]",
       "one job: state, progress, times, result or error",
       RunJobsShow},
      {{"jobs", "watch"},
       "JOB_ID|--job ID [--server HOST:PORT] [--logs] [--json]",
       "follow a job to its end (progress bar, or one JSON object per event)",
       RunJobsWatch},
      {{"jobs", "cancel"},
       "JOB_ID|--job ID [--server HOST:PORT] [--json]",
       "stop a queued or running job",
       RunJobsCancel},
      {{"reenactments", "list"},
       "[--server HOST:PORT] [--take ID] [--page-size N] [--json]",
       "reenactments stored on a reenact-server, newest first (all of them, N a call)",
       RunReenactmentsList},
      {{"reenactments", "show"},
       "ID|--reenactment ID [--server HOST:PORT] [--json]",
       "one reenactment: take, method, frames, parts and keyframes (body model: model, shape, "
       "mesh and atlas), figures",
       RunReenactmentsShow},
      {{"reenactments", "delete"},
       "ID|--reenactment ID [--server HOST:PORT]",
       "delete a stored reenactment",
       RunReenactmentsDelete},
      {{"reenactments", "follow"},
       "--job ID [--server HOST:PORT] [--json]",
       "follow a live job's preview (jobs submit --method body --live) while its "
       "take is recorded: one line per fitted frame (latency: published - arrived at the "
       "server, and received here - arrived), then p50/p95/max",
       RunReenactmentsFollow},
      {{"export"},
       "(--server HOST:PORT --reenactment ID | --in FILE.reen) --format glb|bvh|appearance "
       "--out FILE [--no-textures] [--units m|cm] [--quiet] [--json]",
       "export a reenactment as glTF 2.0 (.glb: textured part nodes, or a body model's skinned "
       "mesh, with their animation), a body model's fitted skeleton as BVH (--units: metres, "
       "Blender's default scale, or centimetres), or its per-frame appearance video (MP4; frame "
       "i textures the glb's frame i)",
       RunExport},
      {{"render"},
       "(--server HOST:PORT --reenactment ID | --in FILE.reen) --camera orbit:DEG|sensor:N "
       "--out DIR [--width W --height H] [--frames A:B] [--mode vdtm|baked] [--quiet]",
       "render a reenactment's frames as PNGs from any viewpoint (view-dependent textures)",
       RunRender},
      {{"eval"},
       "(--server HOST:PORT --reenactment ID | --in FILE.reen) [--take FILE.mcap] [--every K] "
       "[--angle DEG] [--mode vdtm|baked] [--images DIR] [--json]",
       "measure a reenactment against its synthetic take's ground truth (surface, PSNR and "
       "IoU of a novel view --angle degrees (default 90) from sensor 0, MPJPE)",
       RunEval},
  };
}

}  // namespace reenact::cli
