// `reenact reenactments ...` (the server's Reenactments service) and
// `reenact export` (a reenactment, fetched or from a local file, as glTF).
#include <ctime>
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "clients/sdk/reenactments_client.h"
#include "common/base/flags.h"
#include "common/base/time.h"
#include "common/io/gltf_export.h"
#include "common/io/reenactment_file.h"

namespace reenact::cli {
namespace {

double DurationS(const v1::ReenactmentInfo& info) {
  return info.fps() > 0 && info.frame_count() > 0 ? (info.frame_count() - 1) / info.fps() : 0.0;
}

nlohmann::json SummaryJson(const v1::ReenactmentSummary& s) {
  const v1::ReenactmentInfo& info = s.info();
  nlohmann::json options = nlohmann::json::object();
  for (const auto& [key, value] : info.options()) options[key] = value;
  nlohmann::json figures = nlohmann::json::object();
  for (const auto& [key, value] : info.figures()) figures[key] = value;
  return {
      {"reenactment_id", info.reenactment_id()},
      {"take_id", info.take_id()},
      {"job_id", info.job_id()},
      {"method", info.method()},
      {"options", options},
      {"created_unix_ns", info.created_unix_ns()},
      {"generator", info.generator()},
      {"frame_count", info.frame_count()},
      {"fps", info.fps()},
      {"duration_s", DurationS(info)},
      {"part_names", std::vector<std::string>(info.part_names().begin(), info.part_names().end())},
      {"sensor_count", info.sensors_size()},
      {"figures", figures},
      {"part_count", s.part_count()},
      {"keyframe_count", s.keyframe_count()},
      {"file_bytes", s.file_bytes()}};
}

// The id from `--reenactment ID` or the one positional argument.
absl::StatusOr<std::string> ReenactmentId(const Flags& flags, const std::string& command) {
  const std::vector<std::string>& positional = flags.positional();
  if (flags.Has("reenactment") && positional.empty()) return *flags.Get("reenactment");
  if (!flags.Has("reenactment") && positional.size() == 1) return positional[0];
  return absl::InvalidArgumentError(
      absl::StrCat(command, " needs exactly one reenactment id (ID or --reenactment ID)"));
}

void PrintSummary(const v1::ReenactmentSummary& s, std::ostream& out) {
  const v1::ReenactmentInfo& info = s.info();
  out << "reenactment " << info.reenactment_id() << "\n"
      << "take        " << info.take_id() << "\n"
      << "job         " << info.job_id() << "\n"
      << "method      " << info.method() << "\n"
      << "created     " << UtcTime(info.created_unix_ns()) << "\n"
      << "frames      " << info.frame_count()
      << absl::StrFormat(" at %.2f fps (%.3f s)", info.fps(), DurationS(info)) << "\n"
      << "parts       " << s.part_count() << "\n"
      << "keyframes   " << s.keyframe_count() << " from " << info.sensors_size() << " sensor(s)\n"
      << "size        " << HumanBytes(s.file_bytes()) << "\n"
      << "generator   " << info.generator() << "\n";
  for (const auto& [key, value] : info.options()) {
    out << "option      " << key << " = " << value << "\n";
  }
  for (const auto& [key, value] : info.figures()) {
    out << "figure      " << key << " = " << value << "\n";
  }
}

}  // namespace

int RunReenactmentsList(const std::vector<std::string>& args, std::ostream& out,
                        std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "take"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("reenactments list takes no arguments"), err);
  }
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto listed = client::ReenactmentsClient(*connection).List(flags->GetOr("take", ""));
  if (!listed.ok()) return ReportRemoteError(listed.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& s : *listed) j.push_back(SummaryJson(s));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << absl::StrFormat("%-28s %-36s %-16s %7s %9s %9s %10s  %s\n", "REENACTMENT", "TAKE",
                         "METHOD", "FRAMES", "SECONDS", "KEYFRAMES", "SIZE", "CREATED (UTC)");
  for (const auto& s : *listed) {
    out << absl::StrFormat("%-28s %-36s %-16s %7d %9.2f %9d %10s  %s\n", s.info().reenactment_id(),
                           s.info().take_id(), s.info().method(), s.info().frame_count(),
                           DurationS(s.info()), s.keyframe_count(), HumanBytes(s.file_bytes()),
                           UtcTime(s.info().created_unix_ns()));
  }
  if (listed->empty()) out << "(no reenactments)\n";
  return kExitOk;
}

int RunReenactmentsShow(const std::vector<std::string>& args, std::ostream& out,
                        std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "reenactment"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto id = ReenactmentId(*flags, "reenactments show");
  if (!id.ok()) return ReportError(id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto summary = client::ReenactmentsClient(*connection).Get(*id);
  if (!summary.ok()) return ReportRemoteError(summary.status(), err);
  if (flags->Has("json")) {
    out << SummaryJson(*summary).dump(2) << "\n";
    return kExitOk;
  }
  PrintSummary(*summary, out);
  return kExitOk;
}

int RunReenactmentsDelete(const std::vector<std::string>& args, std::ostream& out,
                          std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "reenactment"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto id = ReenactmentId(*flags, "reenactments delete");
  if (!id.ok()) return ReportError(id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const absl::Status deleted = client::ReenactmentsClient(*connection).Delete(*id);
  if (!deleted.ok()) return ReportRemoteError(deleted, err);
  out << "deleted " << *id << "\n";
  return kExitOk;
}

int RunExport(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "reenactment", "in", "format", "out"},
                            {"no-textures", "quiet", "json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_path = flags->Required("out");
  if (!out_path.ok()) return ReportError(out_path.status(), err);
  const std::string format = flags->GetOr("format", "glb");
  if (format != "glb") {
    return ReportError(absl::InvalidArgumentError(absl::StrCat(
                           "--format ", format, " is not supported (glb: glTF 2.0 binary)")),
                       err);
  }
  if (!flags->positional().empty() || flags->Has("in") == flags->Has("reenactment") ||
      (flags->Has("in") && flags->Has("server"))) {
    return ReportError(absl::InvalidArgumentError(
                           "export needs either --server HOST:PORT --reenactment ID or --in "
                           "FILE.reen"),
                       err);
  }
  absl::StatusOr<ReenactmentData> data;
  if (flags->Has("in")) {
    data = ReadReenactmentFile(*flags->Get("in"), /*skip_keyframes=*/true);
    if (!data.ok()) return ReportRemoteError(data.status(), err);
  } else {
    auto connection = ConnectionFromFlags(*flags);
    if (!connection.ok()) return ReportError(connection.status(), err);
    // The baked textures are in the part meshes; keyframes are not needed.
    ProgressBar bar(err, !flags->Has("quiet") && !flags->Has("json"));
    data = client::ReenactmentsClient(*connection)
               .Fetch(*flags->Get("reenactment"), /*skip_keyframes=*/true, bar.AsCallback());
    bar.Finish();
    if (!data.ok()) return ReportRemoteError(data.status(), err);
  }
  GltfExportOptions options;
  options.textures = !flags->Has("no-textures");
  GltfExportSummary summary;
  const absl::Status written = WriteReenactmentGlb(*data, *out_path, options, &summary);
  if (!written.ok()) return ReportRemoteError(written, err);
  if (flags->Has("json")) {
    out << nlohmann::json{{"out", *out_path},
                          {"reenactment_id", data->info.reenactment_id()},
                          {"nodes", summary.nodes},
                          {"meshes", summary.meshes},
                          {"textures", summary.textures},
                          {"animation_channels", summary.animation_channels},
                          {"keys", summary.keys},
                          {"duration_s", summary.duration_s},
                          {"stamps_fell_back", summary.stamps_fell_back},
                          {"bytes", summary.bytes}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << "wrote " << *out_path << " (" << HumanBytes(summary.bytes)
      << "): " << summary.BriefReport() << "\n";
  return kExitOk;
}

}  // namespace reenact::cli
