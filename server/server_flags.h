// The command line of reenact-server, parsed into ServerOptions.
//   reenact-server --data DIR --listen HOST:PORT [--max-message-mb N]
//                  [--port-file FILE] [--depth-check decode|header]
//                  [--jobs N] [--worker PATH]
//                  [--max-name-bytes N] [--max-notes-bytes N] [--max-frame-pixels N]
//                  [--max-calls-per-client N] [--max-streams-per-client N]
//                  [--job-retention-days D]
//                  [--tls-cert PEM --tls-key PEM [--tls-client-ca PEM]]
//                  [--auth TOKENS.json] [--insecure] [--keep-derived]
//                  [--assets DIR[,DIR...]] [--metrics HOST:PORT]
//                  [--http HOST:PORT [--http-port-file FILE] [--web DIR]
//                   [--http-max-connections N]]
//                  [--log-format text|json] [--log-level debug|info|warn|error]
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/log/log.h"
#include "server/server.h"

namespace reenact::server {

inline constexpr char kServerUsage[] =
    "usage: reenact-server --data DIR --listen HOST:PORT [flags]\n"
    "\n"
    "Where it stores and listens:\n"
    "  --data DIR                 takes, jobs and reenactments (created if absent)\n"
    "  --listen HOST:PORT         the gRPC address clients, daemons and workers dial\n"
    "  --port-file FILE           write the gRPC port there once listening (--listen HOST:0)\n"
    "  --assets DIR[,DIR...]      folders whose subfolders jobs name as model=makehuman:NAME\n"
    "  --keep-derived             deleting a take keeps its reenactments and job folders\n"
    "\n"
    "Jobs and workers:\n"
    "  --jobs N                   workers at a time (default one per hardware thread)\n"
    "  --worker PATH              the worker program (default reenact-worker beside this one)\n"
    "  --workers local|local:N|none|slurm\n"
    "                             who runs jobs: workers this server starts (N at a time,\n"
    "                             like --jobs); none: only workers that connect\n"
    "                             (reenact-worker --server); slurm: Slurm batch jobs that\n"
    "                             each run one such worker (default local)\n"
    "  --slurm-config FILE        --workers slurm: partition, account, time, worker, server,\n"
    "                             ... as key = value lines (deploy/slurm/README.md)\n"
    "  --lease-ttl S              a connected worker's job is queued again S seconds after\n"
    "                             its last heartbeat (default 30)\n"
    "  --job-memory-mb N          memory one job may take: a job estimated over it is\n"
    "                             refused, and the server's own workers run each job under\n"
    "                             it (default: three quarters of the machine's memory\n"
    "                             shared by the --jobs, at least 1024; 0: no budget)\n"
    "  --job-retention-days D     finished jobs' logs and rows are deleted after D days\n"
    "                             (default 30, 0: never)\n"
    "  --max-queued-jobs N        jobs waiting at once (default 1000)\n"
    "  --max-queued-jobs-per-token N\n"
    "                             jobs of one token waiting at once (default 100)\n"
    "\n"
    "Security:\n"
    "  --tls-cert PEM --tls-key PEM\n"
    "                             serve gRPC (and --http) over TLS\n"
    "  --tls-client-ca PEM        clients need a certificate it signed\n"
    "  --auth TOKENS.json         every call needs a token (see 'reenact auth add')\n"
    "  --insecure                 allow a non-loopback address without TLS and tokens\n"
    "\n"
    "Limits on what clients send:\n"
    "  --max-message-mb N         largest gRPC message (default 64)\n"
    "  --depth-check decode|header\n"
    "                             how ingested depth is checked (default decode)\n"
    "  --max-name-bytes N         a take's name (default 256)\n"
    "  --max-notes-bytes N        a take's notes (default 16384)\n"
    "  --max-frame-pixels N       width x height of one ingested image (default 16777216)\n"
    "  --max-calls-per-client N   (default 256)\n"
    "  --max-streams-per-client N (default 64)\n"
    "\n"
    "The tablet app and monitoring:\n"
    "  --http HOST:PORT           the tablet app and its JSON API, over TLS with --tls-cert;\n"
    "                             the same tokens as gRPC; loopback unless TLS and --auth,\n"
    "                             or --insecure (default off)\n"
    "  --http-port-file FILE      write the HTTP port there once listening\n"
    "  --web DIR                  the built app (default: beside the program)\n"
    "  --http-max-connections N   (default 256)\n"
    "  --http-max-connections-per-client N\n"
    "                             from one IP address (default 32)\n"
    "  --metrics HOST:PORT        Prometheus text on GET /metrics; loopback unless\n"
    "                             --insecure (default off)\n"
    "  --log-format text|json     one line per event on stderr (default text)\n"
    "  --log-level debug|info|warn|error\n"
    "                             (default info)";

// The HTTP front's flags (server/http/http_front.h takes them from here).
struct HttpFlags {
  // --http HOST:PORT; empty: no HTTP front.
  std::string address;
  // --http-port-file: where to write the bound "HOST:PORT\n".
  std::string port_file;
  // --web DIR: the built web app; empty: found beside the program.
  std::string web_root;
  // --http-max-connections.
  int max_connections = 256;
  // --http-max-connections-per-client.
  int max_connections_per_client = 32;
};

struct ServerCommandLine {
  ServerOptions options;
  HttpFlags http{};
  // --log-format and --log-level (common/log/log.h).
  log::Options log{};
  // Where to write the bound "HOST:PORT\n" (empty: nowhere).
  std::string port_file;
  // --workers slurm --slurm-config FILE: the launcher's config
  // (server/jobs/slurm_launcher.h); empty otherwise.
  std::string slurm_config;
  // --help was given.
  bool help = false;
};

// Parses `args` (without the program name). InvalidArgument naming the flag
// for unknown flags, missing --data or --listen, or bad values.
absl::StatusOr<ServerCommandLine> ParseServerCommandLine(const std::vector<std::string>& args);

// Writes "`address`\n" to `path` through a temporary file and a rename.
absl::Status WritePortFile(const std::string& path, const std::string& address);

}  // namespace reenact::server
