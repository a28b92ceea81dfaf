// The network side of reenact-worker (reenact-worker --server HOST:PORT):
// leases jobs from a server's Work service (proto/reenact/v1/
// work_service.proto), fetches each job's take into a scratch folder of its
// own, runs the job there as a child process that speaks the worker
// protocol on stdout (server/worker/worker_protocol.h; the child is
// reenact-worker itself in its one-job mode), relays its progress and log
// lines by heartbeat, and uploads the reenactment or says why the job
// failed. The scratch folder is deleted after each job; nothing is shared
// with the server but the network.
//
// A lease the server no longer holds (it expired, the job was cancelled)
// stops the child (SIGTERM, then SIGKILL after the grace period). A stop
// request (SIGTERM to the worker) stops the child the same way and gives
// the job back to the queue. A server that cannot be reached is retried
// with a growing pause (at most retry_max_s), so a worker outlives a server
// restart.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/statusor.h"
#include "common/rpc/channel.h"
#include "reenact/v1/work_service.pb.h"

namespace reenact::server {

// The part of the take a phase of a segmented job reads: given the lease
// and the take without any image bytes (ReadTake with an empty selection),
// the frames whose images to stream (reenact-worker asks the job's method,
// ReconstructionMethod::Needs).
using TakeSelector = std::function<absl::StatusOr<v1::TakeSelection>(
    const v1::WorkLease& lease, const std::string& index_path)>;

struct WorkAgentOptions {
  // The server: HOST:PORT, or unix:PATH.
  std::string server;
  rpc::ClientSecurity security;
  // A channel to use instead (a server's own workers: its in-process
  // channel); `server` then only names it in logs.
  std::shared_ptr<grpc::Channel> channel;
  // Where a leased job's take can be read without streaming it (a server's
  // own workers: the take file itself); empty, or none: ReadTake.
  std::function<std::optional<std::string>(const std::string& lease_id)> local_take;
  // Phases of segmented jobs stream only the frames this names (when the
  // take is streamed); null: the whole take.
  TakeSelector select_take;
  // The program that runs one job (reenact-worker; tests give a fake).
  std::string job_program;
  // Methods this worker runs; empty: all the server lists.
  std::vector<std::string> methods;
  // Where each job's folder is made; empty: $TMPDIR or /tmp.
  std::string scratch_dir;
  // Body-model asset folders, passed to the job (--assets).
  std::vector<std::string> asset_roots;
  // Each job's memory ceiling, MiB, passed to it (--memory-limit-mb;
  // common/base/memory_limit.h); 0: none.
  int64_t memory_limit_mb = 0;
  // For the server's logs and `jobs show`; empty: HOSTNAME/pid N.
  std::string name;
  // One job, then return (Slurm's sbatch runs one worker per job); else
  // jobs until `stop`.
  bool once = false;
  // --once: how long to wait for a job before giving up, seconds.
  double once_wait_s = 60;
  // How long one Lease call waits on the server, seconds.
  double lease_wait_s = 20;
  double cancel_grace_s = 5;
  // The same when the worker is stopped.
  double stop_grace_s = 5;
  // On a stop, give the job under way back to the queue (a node that
  // drains); false: just stop it (a server stopping its own workers leaves
  // the job RUNNING, and queues it again when it starts).
  bool give_back_on_stop = true;
  // Longest time between heartbeats, seconds (0: the lease's period).
  double heartbeat_period_s = 0;
  double poll_period_s = 0.1;
  // Longest pause between attempts to reach the server, seconds.
  double retry_max_s = 10;
};

struct WorkAgentSummary {
  int jobs = 0;
  int succeeded = 0;
  // Failed, lost (lease expired, cancelled) or given back.
  int not_succeeded = 0;
};

// Runs jobs until `stop` becomes true (or, with once, after one job, or
// when none came within once_wait_s). InvalidArgument for bad options;
// the server's refusal when it refuses this worker for good (a bad token,
// a wrong protocol, an unknown method).
absl::StatusOr<WorkAgentSummary> RunWorkAgent(const WorkAgentOptions& options,
                                              const std::atomic<bool>& stop);

}  // namespace reenact::server
