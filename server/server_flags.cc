#include "server/server_flags.h"

#include <filesystem>
#include <system_error>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/image.h"
#include "common/base/status_macros.h"
#include "common/log/log.h"
#include "common/rpc/channel.h"

namespace reenact::server {

absl::StatusOr<ServerCommandLine> ParseServerCommandLine(const std::vector<std::string>& args) {
  ASSIGN_OR_RETURN(const Flags flags, Flags::Parse(args,
                                                   {"data",
                                                    "listen",
                                                    "max-message-mb",
                                                    "port-file",
                                                    "depth-check",
                                                    "jobs",
                                                    "worker",
                                                    "workers",
                                                    "lease-ttl",
                                                    "slurm-config",
                                                    "max-name-bytes",
                                                    "max-notes-bytes",
                                                    "max-frame-pixels",
                                                    "max-calls-per-client",
                                                    "max-streams-per-client",
                                                    "job-retention-days",
                                                    "max-queued-jobs",
                                                    "max-queued-jobs-per-token",
                                                    "job-memory-mb",
                                                    "tls-cert",
                                                    "tls-key",
                                                    "tls-client-ca",
                                                    "auth",
                                                    "assets",
                                                    "metrics",
                                                    "http",
                                                    "http-port-file",
                                                    "web",
                                                    "http-max-connections",
                                                    "http-max-connections-per-client",
                                                    "log-format",
                                                    "log-level"},
                                                   {"help", "insecure", "keep-derived"}));
  ServerCommandLine out;
  if (flags.Has("help")) {
    out.help = true;
    return out;
  }
  if (!flags.positional().empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("unexpected argument \"", flags.positional().front(), "\""));
  }
  ASSIGN_OR_RETURN(out.options.data_dir, flags.Required("data"));
  ASSIGN_OR_RETURN(out.options.listen_address, flags.Required("listen"));
  if (out.options.data_dir.empty() || out.options.listen_address.empty()) {
    return absl::InvalidArgumentError("--data and --listen must not be empty");
  }
  ASSIGN_OR_RETURN(out.options.max_message_mb, flags.GetInt("max-message-mb", 64));
  out.port_file = flags.GetOr("port-file", "");
  const std::string depth_check = flags.GetOr("depth-check", "decode");
  if (depth_check != "decode" && depth_check != "header") {
    return absl::InvalidArgumentError(
        absl::StrCat("--depth-check must be decode or header, got \"", depth_check, "\""));
  }
  out.options.store.limits.depth_check =
      depth_check == "decode" ? DepthCheck::kDecode : DepthCheck::kHeader;
  FrameSetLimits& limits = out.options.store.limits;
  ASSIGN_OR_RETURN(limits.max_name_bytes, flags.GetInt("max-name-bytes", limits.max_name_bytes));
  ASSIGN_OR_RETURN(limits.max_notes_bytes, flags.GetInt("max-notes-bytes", limits.max_notes_bytes));
  if (limits.max_name_bytes < 1 || limits.max_notes_bytes < 0) {
    return absl::InvalidArgumentError("--max-name-bytes must be >= 1 and --max-notes-bytes >= 0");
  }
  int max_frame_pixels = 0;
  ASSIGN_OR_RETURN(max_frame_pixels,
                   flags.GetInt("max-frame-pixels", static_cast<int>(limits.max_image_pixels)));
  limits.max_image_pixels = max_frame_pixels;
  if (absl::Status status = limits.Validate(); !status.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("--max-frame-pixels must be 1..", kMaxDecodedImagePixels));
  }
  ASSIGN_OR_RETURN(out.options.client_limits.max_calls,
                   flags.GetInt("max-calls-per-client", out.options.client_limits.max_calls));
  ASSIGN_OR_RETURN(out.options.client_limits.max_streams,
                   flags.GetInt("max-streams-per-client", out.options.client_limits.max_streams));
  out.options.tls.cert_file = flags.GetOr("tls-cert", "");
  out.options.tls.key_file = flags.GetOr("tls-key", "");
  out.options.tls.client_ca_file = flags.GetOr("tls-client-ca", "");
  RETURN_IF_ERROR(out.options.tls.Validate());
  out.options.auth_file = flags.GetOr("auth", "");
  out.options.metrics_address = flags.GetOr("metrics", "");
  out.http.address = flags.GetOr("http", "");
  out.http.port_file = flags.GetOr("http-port-file", "");
  out.http.web_root = flags.GetOr("web", "");
  ASSIGN_OR_RETURN(out.http.max_connections,
                   flags.GetInt("http-max-connections", out.http.max_connections));
  if (out.http.max_connections < 1) {
    return absl::InvalidArgumentError("--http-max-connections must be >= 1");
  }
  ASSIGN_OR_RETURN(
      out.http.max_connections_per_client,
      flags.GetInt("http-max-connections-per-client", out.http.max_connections_per_client));
  if (out.http.max_connections_per_client < 1) {
    return absl::InvalidArgumentError("--http-max-connections-per-client must be >= 1");
  }
  if (out.http.address.empty() && (!out.http.port_file.empty() || flags.Has("web"))) {
    return absl::InvalidArgumentError("--http-port-file and --web need --http HOST:PORT");
  }
  ASSIGN_OR_RETURN(out.log, log::ParseOptions(flags.GetOr("log-format", "text"),
                                              flags.GetOr("log-level", "info")));
  out.options.insecure = flags.Has("insecure");
  out.options.keep_derived = flags.Has("keep-derived");
  ASSIGN_OR_RETURN(out.options.jobs.concurrency, flags.GetInt("jobs", 0));
  if (out.options.jobs.concurrency < 0) {
    return absl::InvalidArgumentError("--jobs must be >= 1 (or 0: one per hardware thread)");
  }
  out.options.jobs.worker_path = flags.GetOr("worker", "");
  const std::string workers = flags.GetOr("workers", "local");
  out.slurm_config = flags.GetOr("slurm-config", "");
  if ((workers == "slurm") != !out.slurm_config.empty()) {
    return absl::InvalidArgumentError("--workers slurm and --slurm-config FILE go together");
  }
  if (workers == "none" || workers == "slurm") {
    out.options.jobs.local_workers = false;
  } else if (workers != "local") {
    const std::vector<std::string> parts = absl::StrSplit(workers, absl::MaxSplits(':', 1));
    int count = 0;
    if (parts.size() != 2 || parts[0] != "local" || !absl::SimpleAtoi(parts[1], &count) ||
        count < 1 || count > 1024) {
      return absl::InvalidArgumentError(
          absl::StrCat("--workers takes local, local:N (1..1024 workers), none or slurm, not \"",
                       workers, "\""));
    }
    if (flags.Has("jobs") && out.options.jobs.concurrency != count) {
      return absl::InvalidArgumentError("--jobs and --workers local:N name different counts");
    }
    out.options.jobs.concurrency = count;
  }
  ASSIGN_OR_RETURN(out.options.jobs.lease_ttl_s,
                   flags.GetDouble("lease-ttl", out.options.jobs.lease_ttl_s));
  ASSIGN_OR_RETURN(out.options.jobs.job_retention_days,
                   flags.GetDouble("job-retention-days", out.options.jobs.job_retention_days));
  ASSIGN_OR_RETURN(out.options.jobs.max_queued_jobs,
                   flags.GetInt("max-queued-jobs", out.options.jobs.max_queued_jobs));
  if (out.options.jobs.max_queued_jobs < 1) {
    return absl::InvalidArgumentError("--max-queued-jobs must be >= 1");
  }
  ASSIGN_OR_RETURN(
      out.options.jobs.max_queued_jobs_per_token,
      flags.GetInt("max-queued-jobs-per-token", out.options.jobs.max_queued_jobs_per_token));
  if (out.options.jobs.max_queued_jobs_per_token < 1) {
    return absl::InvalidArgumentError("--max-queued-jobs-per-token must be >= 1");
  }
  if (flags.Has("job-memory-mb")) {
    ASSIGN_OR_RETURN(const int job_memory_mb, flags.GetInt("job-memory-mb", 0));
    if (job_memory_mb < 0) {
      return absl::InvalidArgumentError(
          "--job-memory-mb must be >= 0 (MiB a job may take; 0: no budget)");
    }
    out.options.jobs.job_memory_mb = job_memory_mb;
  }
  if (const std::string assets = flags.GetOr("assets", ""); !assets.empty()) {
    out.options.jobs.asset_roots = absl::StrSplit(assets, ',', absl::SkipEmpty());
    for (const std::string& root : out.options.jobs.asset_roots) {
      std::error_code error;
      if (!std::filesystem::is_directory(root, error)) {
        return absl::InvalidArgumentError(absl::StrCat("--assets ", root, " is not a folder"));
      }
    }
  }
  RETURN_IF_ERROR(out.options.Validate());
  // The web front serves the same data as the gRPC port: the same rule
  // about leaving loopback.
  RETURN_IF_ERROR(rpc::CheckExposure(absl::StrCat("--http ", out.http.address), out.http.address,
                                     out.options.tls.enabled(), !out.options.auth_file.empty(),
                                     out.options.insecure, "watch every reenactment"));
  return out;
}

absl::Status WritePortFile(const std::string& path, const std::string& address) {
  return WriteFileAtomically(path, address + "\n");
}

}  // namespace reenact::server
