// The subcommands of `reenact`, one RunX() per command, grouped by topic in
// their own files. BuildCommandTable() registers them all in one place.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "clients/cli/command.h"
#include "common/base/image.h"

namespace reenact::cli {

std::vector<Command> BuildCommandTable();

// motion_commands.cc
int RunMotionInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunMotionJoints(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// board_command.cc
int RunBoard(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// synth_command.cc
int RunSynth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// take_commands.cc
int RunTakeInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakeSheet(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakeFrame(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// import_command.cc
int RunImport(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// skeleton_commands.cc
int RunTakeSkeletons(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// auth_command.cc
int RunAuthAdd(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunAuthList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunAuthRemove(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// remote_commands.cc
int RunTakesList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesDownload(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesUpload(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesDelete(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureSensors(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStatus(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStart(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStop(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// job_commands.cc
int RunJobsSubmit(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunJobsList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunJobsMethods(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunJobsShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunJobsWatch(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunJobsCancel(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// reenactment_commands.cc
int RunReenactmentsList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunReenactmentsShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunReenactmentsDelete(const std::vector<std::string>& args, std::ostream& out,
                          std::ostream& err);
int RunReenactmentsFollow(const std::vector<std::string>& args, std::ostream& out,
                          std::ostream& err);
int RunExport(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// view_commands.cc
int RunRender(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunEval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// track_command.cc
int RunTrack(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// A single-channel 16-bit PNG in millimetres (at most 4096 px a side).
absl::StatusOr<DepthImageMm> ReadPngDepth(const std::string& path);

// tracker_commands.cc
int RunTrackerTrain(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTrackerEval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// tracker_real_commands.cc
int RunTrackerEvalReal(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTrackerSynth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// grade_command.cc
int RunGrade(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace reenact::cli
