// The subcommands of `reenact`, one RunX() per command, grouped by topic in
// their own files. BuildCommandTable() registers them all in one place.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "clients/cli/command.h"

namespace reenact::cli {

std::vector<Command> BuildCommandTable();

// motion_commands.cc
int RunMotionInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunMotionJoints(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// synth_command.cc
int RunSynth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// take_commands.cc
int RunTakeInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakeSheet(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// remote_commands.cc
int RunTakesList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesDownload(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunTakesDelete(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureSensors(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStatus(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStart(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int RunCaptureStop(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace reenact::cli
