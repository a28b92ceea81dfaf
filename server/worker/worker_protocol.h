// The scheduler's side of the worker protocol (server/jobs/job_scheduler.h
// describes it): the command line a job's worker gets, the JSON lines it
// writes on stdout (progress.jsonl), and the line of its stderr log
// (worker.log) that a failed job quotes. No processes here: the reader only
// reads a file that a worker appends to.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "common/methods/method_spec.h"
#include "reenact/v1/jobs_service.pb.h"

namespace reenact::server {

// Longest log line passed on to watchers (and longest {"error"} kept).
inline constexpr size_t kMaxWorkerLogLineChars = 2000;
// Longest log line quoted in a failed job's error.
inline constexpr size_t kMaxQuotedLogChars = 300;
// A worker line longer than this without a newline is taken as it is
// rather than held back for its end.
inline constexpr size_t kMaxPendingBytes = 1 << 20;
// Of worker.log, the last this many bytes are searched for its last line.
inline constexpr int64_t kLogTailBytes = 4096;

// The options a job's worker gets: the job's, less those `spec` marks live-
// only (MethodSpec; a null spec leaves out none).
std::map<std::string, std::string> WorkerOptions(
    const methods::MethodSpec* spec,
    const google::protobuf::Map<std::string, std::string>& options);

// Where one attempt of a job's worker reads and writes.
struct WorkerInvocation {
  std::string worker_path;
  // The take file the worker reads (TakeStore::TakeFileForReading).
  std::string take_path;
  // The reenactment it writes (ReenactmentStore::PathFor(reenactment_id)).
  std::string out_path;
  std::string reenactment_id;
  // The server's --assets folders; none: no --assets argument.
  std::vector<std::string> asset_roots;
  // A part of a segmented job (v1::JobPart.name; empty: the whole job), and
  // the files of its inputs (WorkLease.inputs), in order.
  std::string part;
  std::vector<std::string> input_paths;
  // The job's memory ceiling, MiB (--memory-limit-mb; reenact-server
  // --job-memory-mb); 0: no argument.
  int64_t memory_limit_mb = 0;
};

// The worker's argv for `job` (the job's method, take and id; its options
// through WorkerOptions(spec, ...) as --options-json):
//   WORKER --take T --method M --options-json '{"k":"v"}' --out O
//          --reenactment-id R --take-id ID --job-id J [--assets A,B]
//          [--part prepare | --part segment-K --segments N --prepared P |
//           --part stitch --segments N --prepared P --segment-files S1,...]
//          [--memory-limit-mb M]
// (a part: its inputs are the prepared file first, then the segments').
std::vector<std::string> WorkerArgs(const v1::Job& job, const methods::MethodSpec* spec,
                                    const WorkerInvocation& invocation);

// What a worker's stdout lines said so far.
struct WorkerReport {
  // Stage, fraction (clamped to 0..1) and frames as the worker gave them;
  // the other fields are left as they were (the ETA is the scheduler's,
  // server/worker/eta.h).
  v1::JobProgress progress;
  // Its {"error"} message, at most kMaxWorkerLogLineChars.
  std::string error;
  // Its last log line: a {"log"} line, or a line that is no JSON object.
  std::string last_log;
  // Its {"result"}: frames, keyframes and figures (at most 64).
  int64_t result_frames = 0;
  int64_t result_keyframes = 0;
  std::map<std::string, double> result_figures;
};

// Applies one line of worker output (without its newline) to `report`;
// the lines watchers see go to `logs`. A line that is no JSON object is a
// log line as it is. True when the line was progress (it has a "stage"
// string or a "fraction" number).
bool ApplyWorkerLine(const std::string& line, WorkerReport& report, std::vector<std::string>* logs);

// Applies the complete lines at the front of `pending` (output as read,
// "\n" or "\r\n" ends a line; empty lines are skipped) and erases them. An
// incomplete last line stays for the next read unless kMaxPendingBytes of
// it wait already. True when any line was progress.
bool ApplyWorkerLines(std::string& pending, WorkerReport& report, std::vector<std::string>* logs);

// Reads a worker's stdout file (progress.jsonl) as the worker appends to it.
class WorkerOutputReader {
 public:
  // `progress`: the job's progress before this attempt, which the worker's
  // lines then change.
  WorkerOutputReader(std::string path, v1::JobProgress progress);

  // Reads what was appended since the last call and applies its complete
  // lines; true when the progress changed. False, reading nothing, while
  // the file cannot be opened.
  bool Read(std::vector<std::string>* logs);

  const WorkerReport& report() const { return report_; }
  WorkerReport& report() { return report_; }

 private:
  std::string path_;
  int64_t offset_ = 0;   // Bytes of the file read so far.
  std::string pending_;  // An incomplete last line.
  WorkerReport report_;
};

// The last line of `tail` (trailing newlines, carriage returns and
// spaces dropped), else `last_log`, else "(none)"; at most
// kMaxQuotedLogChars (then "..." follows).
std::string LastLogLine(std::string tail, const std::string& last_log);

// The last line the worker wrote on stderr in this attempt, else its last
// log line: LastLogLine of the bytes of `log_path` after `attempt_offset`
// (at most the last kLogTailBytes of them).
std::string LastWorkerLog(const std::string& log_path, int64_t attempt_offset,
                          const std::string& last_log);

}  // namespace reenact::server
