// `reenact takes ...` (the server's Takes service) and `reenact capture ...`
// (a capture daemon's CaptureControl service).
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "clients/sdk/takes_client.h"
#include "common/base/flags.h"
#include "common/base/terminal_text.h"
#include "common/base/time.h"

namespace reenact::cli {
namespace {

nlohmann::json TakeJson(const v1::Take& take) {
  nlohmann::json sensors = nlohmann::json::array();
  for (const auto& s : take.sensors()) {
    nlohmann::json j = {
        {"sensor_id", s.sensor_id()}, {"model", s.model()}, {"frame_count", s.frame_count()}};
    if (s.lost_stamp_ns() != 0) {
      j["lost_stamp_ns"] = s.lost_stamp_ns();
      j["lost_reason"] = s.lost_reason();
    }
    sensors.push_back(j);
  }
  return {{"take_id", take.take_id()},
          {"name", take.name()},
          {"state", client::TakeStateName(take.state())},
          {"created_unix_ns", take.created_unix_ns()},
          {"updated_unix_ns", take.updated_unix_ns()},
          {"duration_s", NsToSeconds(take.duration_ns())},
          {"frame_set_count", take.frame_set_count()},
          {"durable_sequence", take.durable_sequence()},
          {"size_bytes", take.size_bytes()},
          {"fps", take.fps()},
          {"generator", take.generator()},
          {"synthetic", take.synthetic()},
          {"daemon_id", take.daemon_id()},
          {"sensors", sensors}};
}

}  // namespace

int RunTakesList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(
      args, {"server", "timeout", "tls-ca", "token-file", "state", "page-size"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("takes list takes no arguments"), err);
  }
  auto page_size = flags->GetInt("page-size", 0);
  if (!page_size.ok()) return ReportError(page_size.status(), err);
  auto connection = ConnectionFromFlags(*flags, "server", kDefaultServer);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto state = client::ParseTakeState(flags->GetOr("state", "all"));
  if (!state.ok()) return ReportError(state.status(), err);
  auto takes = client::TakesClient(*connection).List(*state, *page_size);
  if (!takes.ok()) return ReportRemoteError(takes.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& take : *takes) j.push_back(TakeJson(take));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << absl::StrFormat("%-36s %-12s %-11s %7s %10s %9s %10s  %s\n", "TAKE", "NAME", "STATE",
                         "SENSORS", "FRAMESETS", "SECONDS", "SIZE", "CREATED (UTC)");
  for (const auto& take : *takes) {
    out << absl::StrFormat("%-36s %-12s %-11s %7d %10d %9.2f %10s  %s\n", take.take_id(),
                           TerminalSafe(take.name()), client::TakeStateName(take.state()),
                           take.sensors_size(), take.frame_set_count(),
                           NsToSeconds(take.duration_ns()), HumanBytes(take.size_bytes()),
                           UtcTime(take.created_unix_ns()));
  }
  if (takes->empty()) out << "(no takes)\n";
  return kExitOk;
}

int RunTakesShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("takes show needs exactly one TAKE_ID"), err);
  }
  auto connection = ConnectionFromFlags(*flags, "server", kDefaultServer);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto take = client::TakesClient(*connection).Get(flags->positional()[0]);
  if (!take.ok()) return ReportRemoteError(take.status(), err);
  if (flags->Has("json")) {
    out << TakeJson(*take).dump(2) << "\n";
    return kExitOk;
  }
  out << "take        " << take->take_id() << "\n"
      << "name        " << TerminalSafe(take->name()) << "\n"
      << "state       " << client::TakeStateName(take->state()) << "\n"
      << "created     " << UtcTime(take->created_unix_ns()) << "\n"
      << "duration    " << absl::StrFormat("%.3f s", NsToSeconds(take->duration_ns())) << "\n"
      << "frame sets  " << take->frame_set_count() << " (durable through sequence "
      << take->durable_sequence() << ")\n"
      << "size        " << HumanBytes(take->size_bytes()) << "\n"
      << "fps         " << take->fps() << "\n"
      << "generator   " << TerminalSafe(take->generator())
      << (take->synthetic() ? " (synthetic)" : "") << "\n"
      << "daemon      " << take->daemon_id() << "\n";
  for (const auto& s : take->sensors()) {
    out << "sensor      " << s.sensor_id() << "  " << s.model() << "  " << s.frame_count()
        << " frames";
    if (s.lost_stamp_ns() != 0) out << "  (lost: " << s.lost_reason() << ")";
    out << "\n";
  }
  return kExitOk;
}

int RunTakesDownload(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "out"}, {"quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_path = flags->Required("out");
  if (!out_path.ok()) return ReportError(out_path.status(), err);
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("takes download needs exactly one TAKE_ID"), err);
  }
  auto connection = ConnectionFromFlags(*flags, "server", kDefaultServer);
  if (!connection.ok()) return ReportError(connection.status(), err);
  ProgressBar bar(err, !flags->Has("quiet"));
  auto bytes = client::TakesClient(*connection)
                   .Download(flags->positional()[0], *out_path,
                             [&bar](const Progress& p) { return bar.Update(p); });
  bar.Finish();
  if (!bytes.ok()) return ReportRemoteError(bytes.status(), err);
  out << "wrote " << *out_path << " (" << HumanBytes(*bytes) << ")\n";
  return kExitOk;
}

int RunTakesDelete(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("takes delete needs exactly one TAKE_ID"), err);
  }
  auto connection = ConnectionFromFlags(*flags, "server", kDefaultServer);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto deleted = client::TakesClient(*connection).Delete(flags->positional()[0]);
  if (!deleted.ok()) return ReportRemoteError(deleted.status(), err);
  out << "deleted " << flags->positional()[0] << " with " << deleted->reenactments_deleted()
      << " reenactment(s) and " << deleted->jobs_deleted() << " job(s) made from it ("
      << HumanBytes(deleted->freed_bytes()) << " freed)\n";
  return kExitOk;
}

nlohmann::json SensorJson(const v1::SensorInfo& s) {
  return {{"sensor_id", s.sensor_id()},
          {"backend", s.backend()},
          {"model", s.model()},
          {"serial", s.serial()},
          {"uri", s.uri()},
          {"state", v1::SensorState_Name(s.state())},
          {"depth_size_px", {s.depth_width_px(), s.depth_height_px()}},
          {"color_size_px", {s.color_width_px(), s.color_height_px()}},
          {"nominal_fps", s.nominal_fps()},
          {"frames_delivered", s.frames_delivered()},
          {"detail", s.detail()}};
}

int RunCaptureSensors(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"daemon", "timeout", "tls-ca", "token-file"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto connection = ConnectionFromFlags(*flags, "daemon", kDefaultDaemon);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto sensors = client::CaptureClient(*connection).ListSensors();
  if (!sensors.ok()) return ReportRemoteError(sensors.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& s : *sensors) j.push_back(SensorJson(s));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  for (const auto& s : *sensors) {
    out << absl::StrFormat("%-8s %-10s %-22s %-10s %4dx%-4d %5.1f fps  %s\n", s.sensor_id(),
                           s.backend(), s.model(),
                           absl::AsciiStrToLower(v1::SensorState_Name(s.state()).substr(13)),
                           s.depth_width_px(), s.depth_height_px(), s.nominal_fps(), s.uri());
  }
  if (sensors->empty()) out << "(no sensors)\n";
  return kExitOk;
}

int RunCaptureStatus(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"daemon", "timeout", "tls-ca", "token-file"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto connection = ConnectionFromFlags(*flags, "daemon", kDefaultDaemon);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto status = client::CaptureClient(*connection).Status();
  if (!status.ok()) return ReportRemoteError(status.status(), err);
  if (flags->Has("json")) {
    nlohmann::json sync = nlohmann::json::array();
    for (const auto& s : status->sync()) {
      sync.push_back({{"sensor_id", s.sensor_id()},
                      {"frames_in", s.frames_in()},
                      {"frames_dropped", s.frames_dropped()},
                      {"frames_duplicate", s.frames_duplicate()},
                      {"clock_offset_ns", s.clock_offset_ns()}});
    }
    nlohmann::json sensors = nlohmann::json::array();
    for (const auto& s : status->sensors()) sensors.push_back(SensorJson(s));
    out << nlohmann::json{{"daemon_id", status->daemon_id()},
                          {"take_id", status->take_id()},
                          {"server_connected", status->server_connected()},
                          {"server_address", status->server_address()},
                          {"last_sequence", status->last_sequence()},
                          {"durable_sequence", status->durable_sequence()},
                          {"spool_frame_sets", status->spool_frame_sets()},
                          {"spool_bytes", status->spool_bytes()},
                          {"spool_refused_frame_sets", status->spool_refused_frame_sets()},
                          {"frame_sets", status->frame_sets()},
                          {"skew_p50_ns", status->skew_p50_ns()},
                          {"skew_max_ns", status->skew_max_ns()},
                          {"reconnects", status->reconnects()},
                          {"uplink_error", status->uplink_error()},
                          {"sync", sync},
                          {"sensors", sensors}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << "daemon      " << status->daemon_id() << "\n"
      << "take        " << (status->take_id().empty() ? "(idle)" : status->take_id()) << "\n"
      << "server      " << status->server_address()
      << (status->server_connected() ? " (connected)" : " (not connected)")
      << (status->uplink_error().empty() ? std::string() : ": " + status->uplink_error()) << "\n"
      << "sequence    " << status->last_sequence() << " sent, " << status->durable_sequence()
      << " durable\n"
      << "spool       " << status->spool_frame_sets() << " frame sets, "
      << HumanBytes(status->spool_bytes())
      << (status->spool_refused_frame_sets() > 0
              ? absl::StrCat(", ", status->spool_refused_frame_sets(), " REFUSED (spool full)")
              : std::string())
      << "\n"
      << "sync        " << status->frame_sets() << " frame sets, skew p50 "
      << absl::StrFormat("%.2f", status->skew_p50_ns() / 1e6) << " ms, max "
      << absl::StrFormat("%.2f", status->skew_max_ns() / 1e6) << " ms\n";
  for (const auto& s : status->sync()) {
    out << "  " << s.sensor_id() << ": " << s.frames_in() << " in, " << s.frames_dropped()
        << " dropped, " << s.frames_duplicate() << " duplicate, clock offset "
        << absl::StrFormat("%.3f", s.clock_offset_ns() / 1e6) << " ms\n";
  }
  return kExitOk;
}

int RunCaptureStart(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(
      args, {"daemon", "timeout", "tls-ca", "token-file", "name", "notes", "max-seconds"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto connection = ConnectionFromFlags(*flags, "daemon", kDefaultDaemon);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto max_seconds = flags->GetDouble("max-seconds", 0.0);
  if (!max_seconds.ok()) return ReportError(max_seconds.status(), err);
  if (!(*max_seconds >= 0) || !std::isfinite(*max_seconds)) {
    return ReportError(absl::InvalidArgumentError("--max-seconds must be >= 0"), err);
  }
  auto take_id = client::CaptureClient(*connection)
                     .StartTake(flags->GetOr("name", ""), flags->GetOr("notes", ""), *max_seconds);
  if (!take_id.ok()) return ReportRemoteError(take_id.status(), err);
  out << *take_id << "\n";
  return kExitOk;
}

int RunCaptureStop(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"daemon", "timeout", "tls-ca", "token-file"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto connection = ConnectionFromFlags(*flags, "daemon", kDefaultDaemon);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto stopped = client::CaptureClient(*connection).StopTake();
  if (!stopped.ok()) return ReportRemoteError(stopped.status(), err);
  out << "stopped " << stopped->take_id() << " (" << stopped->frame_set_count() << " frame sets)\n";
  return kExitOk;
}

}  // namespace reenact::cli
