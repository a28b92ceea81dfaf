// `reenact board`: writes the printable ArUco board that anchors takes and
// the AR viewer in one world frame (common/board, thesis 3.4.2, Eq. 3.12).
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "clients/cli/commands.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/board/board_image.h"
#include "common/board/board_spec.h"

namespace reenact::cli {
namespace {

void PrintSummary(const std::string& path, const board::BoardSpec& spec,
                  const board::BoardPrint& print, bool json, std::ostream& out) {
  if (json) {
    const nlohmann::json j = {{"out", path},
                              {"spec", board::FormatBoardSpec(spec)},
                              {"dpi", print.dpi},
                              {"width_px", print.image.width},
                              {"height_px", print.image.height},
                              {"width_mm", print.width_m * 1e3},
                              {"height_mm", print.height_m * 1e3},
                              {"marker_side_mm", spec.marker_side_m * 1e3},
                              {"grid_width_mm", spec.width_m() * 1e3},
                              {"grid_depth_mm", spec.depth_m() * 1e3}};
    out << j.dump(2) << "\n";
    return;
  }
  out << absl::StrFormat(
      "wrote %s: %s, %d x %d px at %d dpi = %.1f x %.1f mm\n"
      "print at 100%% (no fit-to-page) and check that a marker's black square measures %g mm;\n"
      "lay it face up on the floor: origin at the grid centre, +X to the right, +Z down the "
      "page, +Y up\n",
      path, board::FormatBoardSpec(spec), print.image.width, print.image.height, print.dpi,
      print.width_m * 1e3, print.height_m * 1e3, spec.marker_side_m * 1e3);
}

}  // namespace

int RunBoard(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"out", "spec", "dpi", "margin-mm"}, {"no-caption", "json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  board::PrintOptions options;
  auto path = flags->Required("out");
  auto dpi = flags->GetInt("dpi", options.dpi);
  auto margin_mm = flags->GetDouble("margin-mm", options.margin_m * 1e3);
  for (const absl::Status& s : {path.status(), dpi.status(), margin_mm.status()}) {
    if (!s.ok()) return ReportError(s, err);
  }
  auto spec = board::ParseBoardSpec(flags->GetOr("spec", board::kDefaultBoardSpecText));
  if (!spec.ok()) return ReportError(spec.status(), err);
  options.dpi = *dpi;
  options.margin_m = *margin_mm * 1e-3;
  options.caption = !flags->Has("no-caption");
  auto print = board::RenderBoardForPrint(*spec, options);
  if (!print.ok()) return ReportError(print.status(), err);
  auto png = board::EncodePrintPng(*print);
  if (!png.ok()) return ReportError(png.status(), err);
  if (absl::Status written = WriteFileAtomically(*path, *png); !written.ok()) {
    return ReportError(written, err);
  }
  PrintSummary(*path, *spec, *print, flags->Has("json"), out);
  return kExitOk;
}

}  // namespace reenact::cli
