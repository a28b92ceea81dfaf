#include "capture_daemon/reenactd_cli.h"

#include <cmath>
#include <ostream>
#include <set>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/source_backends.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/board/board_spec.h"
#include "common/log/log.h"
#include "common/rpc/channel.h"

namespace reenact::capture {

namespace {

const std::set<std::string> kValueFlags = {
    "server",     "control",       "control-port-file", "spool",          "spool-max-mb",
    "take-name",  "daemon-id",     "sync-tolerance-ms", "segmentation",   "registration",
    "tracker",    "tracker-model", "tracker-forest",    "tracker-refine", "config",
    "stats-json", "max-seconds",   "drain-timeout-s",   "anchor",         "anchor-timeout-s",
    "tls-ca",     "token-file",    "tls-cert",          "tls-key",        "tls-client-ca",
    "auth",       "metrics",       "log-format",        "log-level"};
const std::set<std::string> kBoolFlags = {"fast", "loop", "once", "verbose", "help", "insecure"};

// "--anchor board[:SPEC]" (or "none") into `anchor`.
absl::Status ParseAnchor(const Flags& flags, AnchorOptions* anchor) {
  const std::string value = flags.GetOr("anchor", "none");
  if (value == "none") {
    anchor->board_spec.clear();
  } else if (value == "board") {
    anchor->board_spec = board::kDefaultBoardSpecText;
  } else if (value.rfind("board:", 0) == 0) {
    anchor->board_spec = value.substr(6);
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("--anchor: expected 'board', 'board:SPEC' or 'none', got '", value, "'"));
  }
  ASSIGN_OR_RETURN(anchor->timeout_s, flags.GetDouble("anchor-timeout-s", anchor->timeout_s));
  return absl::OkStatus();
}

// Pulls every --source out of `args` (Flags keeps only the last of a
// repeated flag).
absl::StatusOr<std::vector<std::string>> ExtractSources(std::vector<std::string>* args) {
  std::vector<std::string> sources;
  std::vector<std::string> rest;
  for (size_t i = 0; i < args->size(); ++i) {
    const std::string& arg = (*args)[i];
    if (arg == "--source") {
      if (i + 1 >= args->size()) return absl::InvalidArgumentError("--source needs a value");
      sources.push_back((*args)[++i]);
    } else if (arg.rfind("--source=", 0) == 0) {
      sources.push_back(arg.substr(9));
    } else {
      rest.push_back(arg);
    }
  }
  *args = std::move(rest);
  return sources;
}

// Turns the config file into flag arguments (and sources).
absl::Status ConfigToArgs(const std::string& path, std::vector<std::string>* args,
                          std::vector<std::string>* sources) {
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path));
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) {
    return absl::InvalidArgumentError(absl::StrCat("--config ", path, ": not a JSON object"));
  }
  for (const auto& [key, value] : j.items()) {
    const std::string where = absl::StrCat("--config ", path, ": key \"", key, "\"");
    if (key == "source") {
      if (value.is_string()) {
        sources->push_back(value.get<std::string>());
      } else if (value.is_array()) {
        for (const auto& item : value) {
          if (!item.is_string()) return absl::InvalidArgumentError(where + ": sources are strings");
          sources->push_back(item.get<std::string>());
        }
      } else {
        return absl::InvalidArgumentError(where + ": a string or a list of strings");
      }
    } else if (kBoolFlags.count(key) && key != "help") {
      if (!value.is_boolean()) return absl::InvalidArgumentError(where + ": true or false");
      if (value.get<bool>()) args->push_back("--" + key);
    } else if (kValueFlags.count(key) && key != "config") {
      if (value.is_string()) {
        args->push_back(absl::StrCat("--", key, "=", value.get<std::string>()));
      } else if (value.is_number()) {
        args->push_back(absl::StrCat("--", key, "=", value.dump()));
      } else {
        return absl::InvalidArgumentError(where + ": a string or a number");
      }
    } else {
      return absl::InvalidArgumentError(where + ": unknown key");
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<ProcessingOptions::Mode> ParseMode(const Flags& flags, const std::string& name) {
  const std::string value = flags.GetOr(name, "auto");
  if (value == "auto") return ProcessingOptions::Mode::kAuto;
  if (value == "on") return ProcessingOptions::Mode::kOn;
  if (value == "off") return ProcessingOptions::Mode::kOff;
  return absl::InvalidArgumentError(
      absl::StrCat("--", name, ": auto, on or off, not \"", value, "\""));
}

// "usage: ..." and the --source lines: one per backend of the table, those
// this build cannot open marked.
std::string SourcesUsage() {
  std::string out =
      "usage: reenactd --server HOST:PORT --source SPEC [--source SPEC ...] [flags]\n"
      "  --source SPEC           a sensor or recording to capture (repeat, or separate\n"
      "                          with commas):\n";
  for (const SourceBackend& backend : SourceBackends()) {
    absl::StrAppend(&out, absl::StrFormat("      %-24s%s%s\n", backend.syntax, backend.description,
                                          backend.built() ? "" : " [not in this build]"));
  }
  return out;
}

}  // namespace

std::string ReenactdUsage() {
  return SourcesUsage() +
         "  --server HOST:PORT      Ingest service of reenact-server (default 127.0.0.1:50051)\n"
         "  --fast                  playback, recordings: as fast as the pipeline takes frames\n"
         "  --loop                  playback, recordings: start over at the end\n"
         "  --once                  record one take until the sources end, exit when durable\n"
         "  --max-seconds S         end the --once take after S seconds\n"
         "  --control HOST:PORT     CaptureControl service (default 127.0.0.1:50052; :0 any port)\n"
         "  --control-port-file F   write the bound control address to F\n"
         "  --tls-ca PEM            trust the server's certificate signed by this CA (else\n"
         "                          $REENACT_TLS_CA; none: plaintext to the server)\n"
         "  --token-file FILE       token sent to the server (else $REENACT_TOKEN)\n"
         "  --tls-cert PEM --tls-key PEM  TLS for the control service\n"
         "  --tls-client-ca PEM     control clients need a certificate this CA signed\n"
         "  --auth TOKENS.json      control calls need a token (see 'reenact auth add')\n"
         "  --insecure              allow a non-loopback --control without TLS and tokens\n"
         "  --spool DIR             spool folder (default $STATE_DIRECTORY/spool,\n"
         "                          /var/lib/reenactd/spool for root, else\n"
         "                          ~/.local/state/reenactd/spool)\n"
         "  --spool-max-mb N        bound of a take's spool (default 1024)\n"
         "  --take-name NAME        name of the --once take (default \"take\")\n"
         "  --daemon-id ID          stable id of this daemon (default from host and spool)\n"
         "  --sync-tolerance-ms X   sync tolerance (default half a frame period)\n"
         "  --segmentation M        auto|on|off (default auto)\n"
         "  --registration M        auto|on|off (default auto)\n"
         "  --tracker M             body tracking on depth: auto (sensors that give no\n"
         "                          skeleton) | on (every sensor, replacing its own) | off\n"
         "  --tracker-model FILE    the tracker's network (default the shipped\n"
         "                          models/tracker/pose_net.onnx)\n"
         "  --tracker-forest FILE   track with a body-part forest instead of the network\n"
         "                          (models/tracker/body_parts.rtf)\n"
         "  --tracker-refine on|off also fit the body model to each person's points\n"
         "                          (default off)\n"
         "  --drain-timeout-s S     wait at shutdown for the take to be durable (default 10)\n"
         "  --anchor board[:SPEC]   at each take's start, find the printed board (default\n"
         "                          aruco:DICT_4X4_50:3x2:110:22) in every sensor's colour\n"
         "                          and make its frame the take's world (default none)\n"
         "  --anchor-timeout-s S    longest wait for the anchoring (default 15)\n"
         "  --config FILE           JSON with the same keys; flags win\n"
         "  --stats-json FILE       figures written at exit\n"
         "  --verbose               a progress event per second\n"
         "  --metrics HOST:PORT     Prometheus text on GET /metrics (loopback unless\n"
         "                          --insecure; :0 any port; default off)\n"
         "  --log-format text|json  one line per event on stderr (default text)\n"
         "  --log-level L           debug|info|warn|error (default info)\n";
}

absl::StatusOr<DaemonOptions> ParseReenactdFlags(const std::vector<std::string>& args_in,
                                                 bool* help) {
  std::vector<std::string> args = args_in;
  ASSIGN_OR_RETURN(std::vector<std::string> sources, ExtractSources(&args));
  ASSIGN_OR_RETURN(const Flags cli, Flags::Parse(args, kValueFlags, kBoolFlags));
  if (help != nullptr) *help = cli.Has("help");
  if (!cli.positional().empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("unexpected argument \"", cli.positional()[0], "\""));
  }
  std::vector<std::string> merged;
  std::vector<std::string> config_sources;
  if (auto config = cli.Get("config"))
    RETURN_IF_ERROR(ConfigToArgs(*config, &merged, &config_sources));
  merged.insert(merged.end(), args.begin(), args.end());
  ASSIGN_OR_RETURN(const Flags flags, Flags::Parse(merged, kValueFlags, kBoolFlags));
  if (sources.empty()) sources = config_sources;

  DaemonOptions options;
  if (help != nullptr && *help) return options;
  options.server_address = flags.GetOr("server", options.server_address);
  ASSIGN_OR_RETURN(options.sources, ParseSourceSpecs(sources));
  options.fast = flags.Has("fast");
  options.loop = flags.Has("loop");
  options.once = flags.Has("once");
  options.verbose = flags.Has("verbose");
  ASSIGN_OR_RETURN(options.max_seconds, flags.GetDouble("max-seconds", 0.0));
  options.control_address = flags.GetOr("control", options.control_address);
  options.control_port_file = flags.GetOr("control-port-file", "");
  options.control_tls = {flags.GetOr("tls-cert", ""), flags.GetOr("tls-key", ""),
                         flags.GetOr("tls-client-ca", "")};
  RETURN_IF_ERROR(options.control_tls.Validate());
  options.control_auth_file = flags.GetOr("auth", "");
  options.insecure = flags.Has("insecure");
  options.metrics_address = flags.GetOr("metrics", "");
  ASSIGN_OR_RETURN(options.log_options, log::ParseOptions(flags.GetOr("log-format", "text"),
                                                          flags.GetOr("log-level", "info")));
  ASSIGN_OR_RETURN(options.uplink.security, rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""),
                                                                    flags.GetOr("token-file", "")));
  options.spool_dir = flags.GetOr("spool", DefaultSpoolDir());
  ASSIGN_OR_RETURN(const int spool_mb, flags.GetInt("spool-max-mb", 1024));
  options.spool_max_mb = spool_mb;
  options.take_name = flags.GetOr("take-name", options.take_name);
  options.daemon_id = flags.GetOr("daemon-id", "");
  ASSIGN_OR_RETURN(const double tolerance_ms, flags.GetDouble("sync-tolerance-ms", 0.0));
  if (!std::isfinite(tolerance_ms) || tolerance_ms < 0) {
    return absl::InvalidArgumentError("--sync-tolerance-ms must be a number >= 0");
  }
  options.sync.tolerance_ns = static_cast<int64_t>(tolerance_ms * 1e6);
  ASSIGN_OR_RETURN(options.processing.segmentation, ParseMode(flags, "segmentation"));
  ASSIGN_OR_RETURN(options.processing.registration, ParseMode(flags, "registration"));
  ASSIGN_OR_RETURN(options.processing.tracking, ParseMode(flags, "tracker"));
  options.processing.tracker.model_path = flags.GetOr("tracker-model", "");
  if (const std::optional<std::string> forest = flags.Get("tracker-forest")) {
    options.processing.tracker.method = tracking::TrackerMethod::kForest;
    options.processing.tracker.forest_path = *forest;
  }
  if (const std::string refine = flags.GetOr("tracker-refine", "off"); refine == "on") {
    options.processing.tracker.refine = true;
  } else if (refine == "off") {
    options.processing.tracker.refine = false;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("--tracker-refine: on or off, not \"", refine, "\""));
  }
  ASSIGN_OR_RETURN(options.drain_timeout_s, flags.GetDouble("drain-timeout-s", 10.0));
  options.stats_json = flags.GetOr("stats-json", "");
  RETURN_IF_ERROR(ParseAnchor(flags, &options.anchor));
  if (!std::isfinite(options.max_seconds) || !std::isfinite(options.drain_timeout_s)) {
    return absl::InvalidArgumentError("--max-seconds and --drain-timeout-s must be finite");
  }
  for (const std::string& id : {options.daemon_id}) {
    for (char c : id) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') {
        return absl::InvalidArgumentError("--daemon-id: only [A-Za-z0-9_-]");
      }
    }
  }
  RETURN_IF_ERROR(options.Validate());
  return options;
}

int RunReenactd(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  bool help = false;
  absl::StatusOr<DaemonOptions> options = ParseReenactdFlags(args, &help);
  if (help) {
    out << ReenactdUsage();
    return kExitOk;
  }
  if (!options.ok()) {
    err << "reenactd: " << options.status().message() << "\n" << ReenactdUsage();
    return kExitUsage;
  }
  // The daemon's events and those of the libraries it runs (uplink,
  // refusals of control calls) in one format on stderr.
  log::Configure(options->log_options);
  options->log = &err;
  const log::Logger logger(&err, options->log_options);
  absl::StatusOr<std::unique_ptr<Daemon>> daemon = Daemon::Create(*options);
  if (!daemon.ok()) {
    logger.Error("daemon_failed", {{"status", absl::StatusCodeToString(daemon.status().code())}},
                 daemon.status().message());
    return absl::IsInvalidArgument(daemon.status()) ? kExitUsage : kExitFailure;
  }
  const absl::Status result = (*daemon)->Run();
  if (!result.ok()) {
    logger.Error("daemon_failed", {{"status", absl::StatusCodeToString(result.code())}},
                 result.message());
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace reenact::capture
