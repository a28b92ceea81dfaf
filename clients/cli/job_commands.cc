// `reenact jobs ...`: the server's Jobs service. Submit a reconstruction of a
// stored take, follow it with a progress bar, list, watch, cancel. Submit's
// `--model X` is `--option model=X` of the method body (the body model:
// procedural | makehuman:NAME, an asset folder of the server).
//
// Exit codes of the commands that wait for a job (submit --wait, watch): 0
// when it SUCCEEDED, 1 when it FAILED or was CANCELLED (the reason on
// stderr) or the server went away, 2 for usage errors.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_replace.h"
#include "clients/cli/commands.h"
#include "clients/cli/fit_diagnosis.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "clients/sdk/jobs_client.h"
#include "clients/sdk/reenactments_client.h"
#include "common/base/flags.h"
#include "common/base/terminal_text.h"
#include "common/base/time.h"

namespace reenact::cli {
namespace {

// "1h02m", "3m05s", "42s"; "?" when negative (unknown).
std::string Duration(double seconds) {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return "?";
  const int64_t s = static_cast<int64_t>(std::llround(seconds));
  if (s >= 3600) return absl::StrFormat("%dh%02dm", s / 3600, (s % 3600) / 60);
  if (s >= 60) return absl::StrFormat("%dm%02ds", s / 60, s % 60);
  return absl::StrFormat("%ds", s);
}

// ", read N MB" for an attempt that streamed from the server.
std::string ReadBytes(const v1::JobAttempt& a) {
  if (a.read_bytes() <= 0) return "";
  return absl::StrFormat(", read %.1f MB", 1e-6 * static_cast<double>(a.read_bytes()));
}

nlohmann::json AttemptsJson(const google::protobuf::RepeatedPtrField<v1::JobAttempt>& attempts) {
  nlohmann::json history = nlohmann::json::array();
  for (const v1::JobAttempt& a : attempts) {
    history.push_back({{"number", a.number()},
                       {"worker", a.worker()},
                       {"started_unix_ns", a.started_unix_ns()},
                       {"ended_unix_ns", a.ended_unix_ns()},
                       {"outcome", a.outcome()},
                       {"read_bytes", a.read_bytes()}});
  }
  return history;
}

nlohmann::json JobJson(const v1::Job& job) {
  nlohmann::json options = nlohmann::json::object();
  for (const auto& [key, value] : job.options()) options[key] = value;
  const v1::JobProgress& p = job.progress();
  const nlohmann::json history = AttemptsJson(job.attempt_history());
  nlohmann::json parts = nlohmann::json::array();
  for (const v1::JobPart& part : job.parts()) {
    const nlohmann::json attempts = AttemptsJson(part.attempt_history());
    parts.push_back({{"name", part.name()},
                     {"state", part.state() == v1::JOB_STATE_UNSPECIFIED
                                   ? std::string("waiting")
                                   : std::string(client::JobStateName(part.state()))},
                     {"attempts", part.attempts()},
                     {"attempt_history", attempts},
                     {"file_bytes", part.file_bytes()}});
  }
  return {{"job_id", job.job_id()},
          {"take_id", job.take_id()},
          {"method", job.method()},
          {"options", options},
          {"state", client::JobStateName(job.state())},
          {"progress",
           {{"stage", p.stage()},
            {"fraction", p.fraction()},
            {"frames_done", p.frames_done()},
            {"frames_total", p.frames_total()},
            {"eta_s", p.eta_s()}}},
          {"submitted_unix_ns", job.submitted_unix_ns()},
          {"started_unix_ns", job.started_unix_ns()},
          {"finished_unix_ns", job.finished_unix_ns()},
          {"reenactment_id", job.reenactment_id()},
          {"error", job.error()},
          {"attempts", job.attempts()},
          {"attempt_history", history},
          {"segments", job.segments()},
          {"live", job.live()},
          {"parts", parts}};
}

// The job's id from --job or the one positional argument.
absl::StatusOr<std::string> JobIdArgument(const Flags& flags, const std::string& command) {
  const std::string from_flag = flags.GetOr("job", "");
  if (!from_flag.empty() && flags.positional().empty()) return from_flag;
  if (from_flag.empty() && flags.positional().size() == 1) return flags.positional()[0];
  return absl::InvalidArgumentError(absl::StrCat(command, " needs exactly one job: --job ID"));
}

// The job's progress on stderr (ProgressLine: redrawn on a terminal, plain
// lines otherwise): stage, bar, percentage, frames, ETA (the server's
// estimate). Log lines, when shown, go above it.
class JobProgressLine {
 public:
  JobProgressLine(std::ostream& err, bool enabled)
      : line_(err, enabled, ProgressLine::IsTerminal(err)), err_(err), enabled_(enabled) {}

  void Update(const v1::JobEvent& event, bool show_logs) {
    if (!enabled_) return;
    if (show_logs) {
      for (const std::string& line : event.log_lines()) {
        line_.EndLine();
        err_ << "  " << TerminalSafe(line) << "\n";
      }
    }
    const v1::Job& job = event.job();
    const v1::JobProgress& p = job.progress();
    if (job.state() == v1::JOB_STATE_QUEUED) {
      line_.Show("queued", 0.0, absl::StrCat("job ", job.job_id(), " queued"));
      return;
    }
    const double fraction = std::clamp(p.fraction(), 0.0, 1.0);
    const std::string stage = p.stage().empty() ? "starting" : p.stage();
    std::string text =
        absl::StrFormat("%-12s %s %5.1f%%", stage, BarText(fraction), fraction * 100.0);
    if (p.frames_total() > 0) {
      absl::StrAppend(&text, absl::StrFormat("  %d/%d frames", p.frames_done(), p.frames_total()));
    } else if (p.frames_done() > 0) {  // A live job following its take.
      absl::StrAppend(&text, absl::StrFormat("  %d frames", p.frames_done()));
    }
    if (job.state() == v1::JOB_STATE_RUNNING) absl::StrAppend(&text, "  ETA ", Duration(p.eta_s()));
    line_.Show(stage, fraction, text);
  }
  void EndLine() { line_.EndLine(); }

 private:
  ProgressLine line_;
  std::ostream& err_;
  bool enabled_;
};

// Ends a waited-for job: exit 0 when it succeeded; the reason on stderr
// otherwise.
int JobExit(const v1::Job& job, std::ostream& err) {
  if (job.state() == v1::JOB_STATE_SUCCEEDED) return kExitOk;
  err << "reenact: job " << job.job_id() << " " << client::JobStateName(job.state())
      << (job.error().empty() ? "" : ": ") << TerminalSafe(job.error()) << "\n";
  return kExitFailure;
}

std::string Summary(const v1::Job& job) {
  const double seconds = job.finished_unix_ns() > job.started_unix_ns() && job.started_unix_ns() > 0
                             ? NsToSeconds(job.finished_unix_ns() - job.started_unix_ns())
                             : 0.0;
  if (job.state() == v1::JOB_STATE_SUCCEEDED) {
    return absl::StrFormat("job %s succeeded in %.1f s: reenactment %s", job.job_id(), seconds,
                           job.reenactment_id());
  }
  return absl::StrCat("job ", job.job_id(), " ", client::JobStateName(job.state()));
}

// Follows the job to its end with the progress line (or, with `json_lines`,
// one JSON object per event on `out`).
absl::StatusOr<v1::Job> Follow(const client::JobsClient& jobs, const std::string& job_id, bool bar,
                               bool show_logs, bool json_lines, std::ostream& out,
                               std::ostream& err) {
  JobProgressLine line(err, bar);
  absl::StatusOr<v1::Job> job = jobs.Watch(job_id, [&](const v1::JobEvent& event) {
    if (json_lines) {
      nlohmann::json logs = nlohmann::json::array();
      for (const std::string& l : event.log_lines()) logs.push_back(l);
      out << nlohmann::json{{"job", JobJson(event.job())}, {"log_lines", logs}}.dump() << "\n"
          << std::flush;
    }
    line.Update(event, show_logs);
    return true;
  });
  line.EndLine();
  return job;
}

// Pulls every "--option KEY=VALUE" (or "--option=KEY=VALUE") out of `args`.
absl::StatusOr<std::map<std::string, std::string>> TakeOptions(std::vector<std::string>* args) {
  std::map<std::string, std::string> options;
  std::vector<std::string> rest;
  for (size_t i = 0; i < args->size(); ++i) {
    const std::string& arg = (*args)[i];
    std::string pair;
    if (arg == "--option") {
      if (i + 1 >= args->size()) return absl::InvalidArgumentError("--option needs KEY=VALUE");
      pair = (*args)[++i];
    } else if (arg.rfind("--option=", 0) == 0) {
      pair = arg.substr(9);
    } else {
      rest.push_back(arg);
      continue;
    }
    const size_t eq = pair.find('=');
    if (eq == std::string::npos || eq == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("--option takes KEY=VALUE, got \"", pair, "\""));
    }
    options[pair.substr(0, eq)] = pair.substr(eq + 1);
  }
  *args = std::move(rest);
  return options;
}

// `--model X`: shorthand for `--option model=X`, the body model of a method
// that has one (procedural | makehuman:NAME; the server refuses it for a
// method without the option). InvalidArgument beside a different
// `--option model=`.
absl::Status ApplyModelFlag(const Flags& flags, std::map<std::string, std::string>* options) {
  if (!flags.Has("model")) return absl::OkStatus();
  const std::string model = flags.GetOr("model", "");
  if (model.empty()) {
    return absl::InvalidArgumentError("--model takes procedural or makehuman:NAME");
  }
  const auto [it, inserted] = options->emplace("model", model);
  if (!inserted && it->second != model) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--model ", model, " disagrees with --option model=", it->second, "; give one of them"));
  }
  return absl::OkStatus();
}

}  // namespace

int RunJobsSubmit(const std::vector<std::string>& raw_args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> args = raw_args;
  auto options = TakeOptions(&args);
  if (!options.ok()) return ReportError(options.status(), err);
  auto flags = Flags::Parse(
      args, {"server", "timeout", "tls-ca", "token-file", "take", "method", "model", "segments"},
      {"wait", "json", "logs", "quiet", "live"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError(
                           absl::StrCat("unexpected argument \"", flags->positional()[0], "\"")),
                       err);
  }
  if (options->contains("live")) {
    return ReportError(absl::InvalidArgumentError(
                           "live is not an option: follow a take while it is recorded with --live"),
                       err);
  }
  auto take = flags->Required("take");
  if (!take.ok()) return ReportError(take.status(), err);
  auto method = flags->Required("method");
  if (!method.ok()) return ReportError(method.status(), err);
  if (absl::Status model = ApplyModelFlag(*flags, &*options); !model.ok()) {
    return ReportError(model, err);
  }
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const client::JobsClient jobs(*connection);
  const absl::StatusOr<int> segments = flags->GetInt("segments", 0);
  if (!segments.ok() || *segments < 0) {
    return ReportError(absl::InvalidArgumentError("--segments takes a count of workers >= 0"), err);
  }
  auto job = jobs.Submit(*take, *method, *options, *segments, flags->Has("live"));
  if (!job.ok()) return ReportRemoteError(job.status(), err);
  const bool json = flags->Has("json");
  if (!flags->Has("wait")) {
    if (json) {
      out << JobJson(*job).dump(2) << "\n";
    } else {
      out << job->job_id() << "\n";
    }
    return kExitOk;
  }
  if (!json && !flags->Has("quiet")) err << "job " << job->job_id() << " submitted\n";
  auto end = Follow(jobs, job->job_id(), !flags->Has("quiet"), flags->Has("logs"),
                    /*json_lines=*/false, out, err);
  if (!end.ok()) return ReportRemoteError(end.status(), err);
  if (json) {
    nlohmann::json result = {{"job", JobJson(*end)}, {"reenactment", nullptr}};
    if (end->state() == v1::JOB_STATE_SUCCEEDED) result["reenactment"] = end->reenactment_id();
    out << result.dump(2) << "\n";
  } else if (end->state() == v1::JOB_STATE_SUCCEEDED) {
    out << Summary(*end) << "\n";
  }
  return JobExit(*end, err);
}

int RunJobsList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(
      args, {"server", "timeout", "tls-ca", "token-file", "state", "take", "page-size"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("jobs list takes no arguments"), err);
  }
  auto page_size = flags->GetInt("page-size", 0);
  if (!page_size.ok()) return ReportError(page_size.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto state = client::ParseJobState(flags->GetOr("state", "all"));
  if (!state.ok()) return ReportError(state.status(), err);
  auto jobs = client::JobsClient(*connection).List(*state, flags->GetOr("take", ""), *page_size);
  if (!jobs.ok()) return ReportRemoteError(jobs.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& job : *jobs) j.push_back(JobJson(job));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << absl::StrFormat("%-24s %-24s %-16s %-10s %8s  %-20s  %s\n", "JOB", "TAKE", "METHOD",
                         "STATE", "PROGRESS", "SUBMITTED (UTC)", "RESULT");
  for (const auto& job : *jobs) {
    const std::string result =
        job.state() == v1::JOB_STATE_SUCCEEDED ? job.reenactment_id() : TerminalSafe(job.error());
    out << absl::StrFormat("%-24s %-24s %-16s %-10s %7.1f%%  %-20s  %s\n", job.job_id(),
                           job.take_id(), job.method(), client::JobStateName(job.state()),
                           job.progress().fraction() * 100.0, UtcTime(job.submitted_unix_ns()),
                           result);
  }
  if (jobs->empty()) out << "(no jobs)\n";
  return kExitOk;
}

namespace {

nlohmann::json MethodJson(const v1::MethodDescription& method) {
  nlohmann::json options = nlohmann::json::array();
  for (const v1::MethodOption& option : method.options()) {
    nlohmann::json o = {
        {"name", option.name()}, {"type", option.type()},     {"default", option.default_value()},
        {"doc", option.doc()},   {"common", option.common()}, {"live_only", option.live_only()}};
    if (option.has_bounds()) {
      o["min"] = option.min();
      o["max"] = option.max();
    }
    options.push_back(std::move(o));
  }
  std::string texture = absl::AsciiStrToLower(v1::TextureMode_Name(method.texture_mode()));
  if (absl::StartsWith(texture, "texture_mode_")) texture = texture.substr(13);
  absl::StrReplaceAll({{"_", "-"}}, &texture);
  return {
      {"name", method.name()}, {"summary", method.summary()},         {"thesis", method.thesis()},
      {"live", method.live()}, {"segmentable", method.segmentable()}, {"texture_mode", texture},
      {"options", options}};
}

// "[0, 100]" for bounded options; "" otherwise.
std::string Bounds(const v1::MethodOption& option) {
  if (!option.has_bounds()) return "";
  return absl::StrCat("[", option.min(), ", ", option.max(), "]");
}

}  // namespace

int RunJobsMethods(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("jobs methods takes no arguments"), err);
  }
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto methods = client::JobsClient(*connection).ListMethods();
  if (!methods.ok()) return ReportRemoteError(methods.status(), err);
  if (flags->Has("json")) {
    nlohmann::json j = nlohmann::json::array();
    for (const v1::MethodDescription& method : *methods) j.push_back(MethodJson(method));
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  // Advice first, in the words of what a coach wants, for the methods this
  // server has; the details (and the thesis sections) follow.
  const std::vector<std::pair<std::string, std::string>> advice = {
      {"body",
       "a person: a fitted body model that moves smoothly, for the mirror, grading and exports "
       "to animation tools (--model makehuman:NAME where the server has the assets)"},
      {"rigid-carved",
       "whatever the sensors saw, props and loose clothes included, as rigid parts carved from "
       "the depth (two or more sensors)"},
      {"rigid-cylinders", "the quickest look: rigid parts shaped as cylinders round the skeleton"},
  };
  bool advised = false;
  for (const auto& [name, words] : advice) {
    for (const v1::MethodDescription& method : *methods) {
      if (method.name() != name) continue;
      if (!advised) out << "Which to pick:\n";
      advised = true;
      out << absl::StrFormat("  %-16s %s\n", name, words);
    }
  }
  if (advised) out << "\n";
  for (const v1::MethodDescription& method : *methods) {
    const nlohmann::json j = MethodJson(method);
    out << method.name() << ": " << method.summary() << "\n"
        << "  thesis " << method.thesis() << "; textures " << j["texture_mode"].get<std::string>()
        << "; " << (method.live() ? "can follow a take live (--live)" : "offline only")
        << (method.segmentable() ? "; can split a take across workers (--segments N)" : "") << "\n";
    for (const v1::MethodOption& option : method.options()) {
      const char* scope = option.common() ? " (every method)" : option.live_only() ? " (live)" : "";
      out << absl::StrFormat("  %-24s %-6s %-10s %-16s %s%s\n", option.name(), option.type(),
                             option.default_value().empty() ? "\"\"" : option.default_value(),
                             Bounds(option), option.doc(), scope);
    }
    out << "\n";
  }
  if (methods->empty()) out << "(no methods)\n";
  return kExitOk;
}

int RunJobsShow(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "job"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto job_id = JobIdArgument(*flags, "jobs show");
  if (!job_id.ok()) return ReportError(job_id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto job = client::JobsClient(*connection).Get(*job_id);
  if (!job.ok()) return ReportRemoteError(job.status(), err);
  // The reenactment's judgement of its frames (fit_diagnosis.h), when the
  // job made one that can be read.
  std::optional<v1::ReenactmentSummary> made;
  if (!job->reenactment_id().empty()) {
    auto summary = client::ReenactmentsClient(*connection).Get(job->reenactment_id());
    if (summary.ok()) made = *std::move(summary);
  }
  if (flags->Has("json")) {
    nlohmann::json json = JobJson(*job);
    if (made) json["fit"] = FitDiagnosisJson(made->info());
    out << json.dump(2) << "\n";
    return kExitOk;
  }
  const v1::JobProgress& p = job->progress();
  out << "job          " << job->job_id() << "\n"
      << "take         " << job->take_id() << "\n"
      << "method       " << job->method() << "\n";
  for (const auto& [key, value] : job->options()) {
    out << "option       " << key << "=" << value << "\n";
  }
  out << "state        " << client::JobStateName(job->state()) << "\n"
      << "progress     " << (p.stage().empty() ? "-" : p.stage())
      << absl::StrFormat(" %.1f%%", p.fraction() * 100.0);
  if (p.frames_total() > 0) out << " (" << p.frames_done() << "/" << p.frames_total() << " frames)";
  if (job->state() == v1::JOB_STATE_RUNNING) out << ", ETA " << Duration(p.eta_s());
  out << "\n"
      << "submitted    " << UtcTime(job->submitted_unix_ns()) << "\n"
      << "started      " << UtcTime(job->started_unix_ns()) << "\n"
      << "finished     " << UtcTime(job->finished_unix_ns()) << "\n"
      << "attempts     " << job->attempts() << "\n";
  for (const v1::JobAttempt& a : job->attempt_history()) {
    out << "  attempt " << a.number() << "  on " << a.worker() << ", "
        << UtcTime(a.started_unix_ns()) << " .. "
        << (a.ended_unix_ns() == 0 ? "running" : UtcTime(a.ended_unix_ns()))
        << (a.outcome().empty() ? "" : ": " + a.outcome()) << ReadBytes(a) << "\n";
  }
  if (job->live()) out << "live         follows its take while it is recorded\n";
  if (job->segments() > 0) out << "segments     " << job->segments() << "\n";
  for (const v1::JobPart& part : job->parts()) {
    out << "  part " << part.name() << "  "
        << (part.state() == v1::JOB_STATE_UNSPECIFIED
                ? std::string("waiting")
                : std::string(client::JobStateName(part.state())));
    if (part.file_bytes() > 0) out << ", " << part.file_bytes() << " bytes";
    out << "\n";
    for (const v1::JobAttempt& a : part.attempt_history()) {
      out << "    attempt " << a.number() << "  on " << a.worker() << ", "
          << UtcTime(a.started_unix_ns()) << " .. "
          << (a.ended_unix_ns() == 0 ? "running" : UtcTime(a.ended_unix_ns()))
          << (a.outcome().empty() ? "" : ": " + a.outcome()) << ReadBytes(a) << "\n";
    }
  }
  if (!job->reenactment_id().empty()) out << "reenactment  " << job->reenactment_id() << "\n";
  if (made) PrintFitDiagnosis(made->info(), out);
  if (!job->error().empty()) out << "error        " << job->error() << "\n";
  return kExitOk;
}

int RunJobsWatch(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "job"},
                            {"json", "logs", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto job_id = JobIdArgument(*flags, "jobs watch");
  if (!job_id.ok()) return ReportError(job_id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const bool json = flags->Has("json");
  auto end = Follow(client::JobsClient(*connection), *job_id, !json && !flags->Has("quiet"),
                    flags->Has("logs"), json, out, err);
  if (!end.ok()) return ReportRemoteError(end.status(), err);
  if (!json && end->state() == v1::JOB_STATE_SUCCEEDED) out << Summary(*end) << "\n";
  return JobExit(*end, err);
}

int RunJobsCancel(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"server", "timeout", "tls-ca", "token-file", "job"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto job_id = JobIdArgument(*flags, "jobs cancel");
  if (!job_id.ok()) return ReportError(job_id.status(), err);
  auto connection = ConnectionFromFlags(*flags);
  if (!connection.ok()) return ReportError(connection.status(), err);
  auto job = client::JobsClient(*connection).Cancel(*job_id);
  if (!job.ok()) return ReportRemoteError(job.status(), err);
  if (flags->Has("json")) {
    out << JobJson(*job).dump(2) << "\n";
  } else if (job->state() == v1::JOB_STATE_CANCELLED) {
    out << "job " << job->job_id() << " cancelled\n";
  } else {
    out << "job " << job->job_id() << " had already ended: " << client::JobStateName(job->state())
        << "\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
