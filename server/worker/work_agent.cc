#include "server/worker/work_agent.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <thread>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "proto/grpc_status.h"
#include "reenact/v1/work_service.grpc.pb.h"
#include "server/worker/worker_process.h"
#include "server/worker/worker_protocol.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kUploadChunkBytes = int64_t{1} << 20;
// Deadline of a heartbeat or a Fail call, seconds.
constexpr double kCallDeadlineS = 15;

std::chrono::system_clock::time_point DeadlineIn(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::duration_cast<std::chrono::system_clock::duration>(
             std::chrono::duration<double>(seconds));
}

// Errors that another try will not mend: the worker stops.
bool Permanent(const grpc::Status& status) {
  switch (status.error_code()) {
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::PERMISSION_DENIED:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::UNIMPLEMENTED:
      return true;
    default:
      return false;
  }
}

// Sleeps `seconds` in short steps; false when `stop` came meanwhile.
bool SleepUnlessStopped(double seconds, const std::atomic<bool>& stop) {
  const int64_t until = SteadyNowNs() + SecondsToNs(seconds);
  while (!stop.load()) {
    const int64_t left = until - SteadyNowNs();
    if (left <= 0) return true;
    std::this_thread::sleep_for(std::chrono::nanoseconds(std::min<int64_t>(left, 50'000'000)));
  }
  return false;
}

// Cancels a call when `stop` becomes true, so that a long Lease wait ends
// at once on SIGTERM.
class CancelOnStop {
 public:
  CancelOnStop(grpc::ClientContext& context, const std::atomic<bool>& stop) {
    thread_ = std::thread([this, &context, &stop] {
      std::unique_lock<std::mutex> lock(mu_);
      while (!done_) {
        if (stop.load()) {
          context.TryCancel();
          return;
        }
        wake_.wait_for(lock, std::chrono::milliseconds(50));
      }
    });
  }
  ~CancelOnStop() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      done_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  CancelOnStop(const CancelOnStop&) = delete;
  CancelOnStop& operator=(const CancelOnStop&) = delete;

 private:
  std::mutex mu_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;
};

std::string DefaultName() {
  char host[256] = {};
  if (::gethostname(host, sizeof(host) - 1) != 0) host[0] = '\0';
  return absl::StrCat(host[0] != '\0' ? host : "worker", "/pid ", ::getpid());
}

// Sends a lease's heartbeats from a thread of its own: the job's progress
// and log lines as reported, every period, until stopped. Notes when the
// server no longer holds the lease.
class Heartbeats {
 public:
  Heartbeats(v1::Work::Stub* stub, std::string lease_id, double period_s)
      : stub_(stub), lease_id_(std::move(lease_id)), period_s_(period_s) {
    thread_ = std::thread([this] { Loop(); });
  }
  ~Heartbeats() { Stop(/*flush=*/false); }
  Heartbeats(const Heartbeats&) = delete;
  Heartbeats& operator=(const Heartbeats&) = delete;

  // A new stage is sent at once (at most five beats a second), the rest
  // with the next periodic beat.
  void Report(const v1::JobProgress& progress, std::vector<std::string> logs) {
    std::lock_guard<std::mutex> lock(mu_);
    if (progress.stage() != progress_.stage()) {
      stage_changed_ = true;
      wake_.notify_all();
    }
    progress_ = progress;
    for (std::string& line : logs) logs_.push_back(std::move(line));
  }
  bool lost() const { return lost_.load(); }
  std::string lost_reason() const {
    std::lock_guard<std::mutex> lock(mu_);
    return lost_reason_;
  }
  // Ends the thread; with `flush` a last heartbeat carries what is left.
  // Returns the log lines not sent.
  std::vector<std::string> Stop(bool flush) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (stopping_) return {};
      stopping_ = true;
      wake_.notify_all();
    }
    if (thread_.joinable()) thread_.join();
    if (flush && !lost()) Send();
    std::lock_guard<std::mutex> lock(mu_);
    return std::exchange(logs_, {});
  }

 private:
  void Loop() {
    while (true) {
      {
        std::unique_lock<std::mutex> lock(mu_);
        wake_.wait_for(lock, std::chrono::duration<double>(period_s_),
                       [this] { return stopping_ || stage_changed_; });
        if (stopping_) return;
        stage_changed_ = false;
      }
      Send();
      // At most five beats a second (ten with a short period).
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.2, period_s_ / 2)));
    }
  }

  void Send() {
    v1::HeartbeatRequest request;
    request.set_lease_id(lease_id_);
    {
      std::lock_guard<std::mutex> lock(mu_);
      *request.mutable_progress() = progress_;
      for (std::string& line : logs_) request.add_log_lines(std::move(line));
      logs_.clear();
    }
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(kCallDeadlineS));
    v1::HeartbeatResponse response;
    const grpc::Status status = stub_->Heartbeat(&context, request, &response);
    if (status.ok()) return;
    if (status.error_code() == grpc::StatusCode::ABORTED ||
        status.error_code() == grpc::StatusCode::NOT_FOUND) {
      std::lock_guard<std::mutex> lock(mu_);
      lost_reason_ = status.error_message();
      lost_ = true;
      return;
    }
    // Unreachable for now: the lines go with the next beat.
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<std::string> unsent(request.log_lines().begin(), request.log_lines().end());
    for (std::string& line : logs_) unsent.push_back(std::move(line));
    logs_ = std::move(unsent);
  }

  v1::Work::Stub* const stub_;
  const std::string lease_id_;
  const double period_s_;
  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool stopping_ = false;
  bool stage_changed_ = false;
  v1::JobProgress progress_;
  std::vector<std::string> logs_;
  std::atomic<bool> lost_{false};
  std::string lost_reason_;
  std::thread thread_;
};

// Writes the lease's take (`input` empty; with `selection`, the part of it
// the selection names) or one of its inputs to `path`, checking offsets
// and the size: `bytes`, or the size the chunks state (bytes < 0).
absl::Status FetchFile(v1::Work::Stub* stub, const v1::WorkLease& lease, const std::string& input,
                       const v1::TakeSelection* selection, int64_t bytes, const std::string& path) {
  const std::string what =
      input.empty() ? (selection != nullptr ? "take selection" : "take") : "input " + input;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return absl::InternalError(absl::StrCat("cannot write ", path));
  grpc::ClientContext context;
  v1::ReadTakeRequest request;
  request.set_lease_id(lease.lease_id());
  request.set_input(input);
  if (selection != nullptr) *request.mutable_selection() = *selection;
  std::unique_ptr<grpc::ClientReader<v1::TakeChunk>> reader = stub->ReadTake(&context, request);
  v1::TakeChunk chunk;
  int64_t received = 0;
  while (reader->Read(&chunk)) {
    if (bytes < 0 && received == 0 && chunk.file_bytes() > 0) bytes = chunk.file_bytes();
    if (chunk.offset() != received || bytes < 0 ||
        received + static_cast<int64_t>(chunk.data().size()) > bytes) {
      context.TryCancel();
      (void)reader->Finish();
      return absl::DataLossError(
          absl::StrCat("the ", what, " stream is out of order at byte ", received));
    }
    out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
    received += static_cast<int64_t>(chunk.data().size());
  }
  RETURN_IF_ERROR(FromGrpcStatus(reader->Finish()));
  out.close();
  if (!out) return absl::InternalError(absl::StrCat("writing ", path, " failed (disk full?)"));
  if (received != bytes) {
    return absl::DataLossError(
        absl::StrCat("the ", what, " ended after ", received, " of ", bytes, " bytes"));
  }
  return absl::OkStatus();
}

// The lease's take, then each of its inputs, into `dir`; their paths
// (the take first). A phase of a segmented job with `select_take` reads the
// take without image bytes first and then only the images `select_take`
// names; an error of `select_take` is the job's (`*job_error`).
absl::StatusOr<std::vector<std::string>> FetchInputs(v1::Work::Stub* stub,
                                                     const v1::WorkLease& lease,
                                                     const std::string& dir,
                                                     const std::optional<std::string>& local_take,
                                                     const TakeSelector& select_take,
                                                     bool* job_error) {
  std::vector<std::string> paths;
  if (local_take.has_value()) {
    paths.push_back(*local_take);
  } else if (select_take && !lease.part().empty()) {
    const std::string index = (fs::path(dir) / "take-index.mcap").string();
    const v1::TakeSelection nothing;
    RETURN_IF_ERROR(FetchFile(stub, lease, "", &nothing, -1, index));
    absl::StatusOr<v1::TakeSelection> selection = select_take(lease, index);
    if (!selection.ok()) {
      *job_error = true;
      return selection.status();
    }
    if (selection->depth_size() + selection->color_size() == 0) {
      paths.push_back(index);
    } else {
      paths.push_back((fs::path(dir) / "take.mcap").string());
      RETURN_IF_ERROR(FetchFile(stub, lease, "", &*selection, -1, paths.back()));
      std::error_code ignored;
      fs::remove(index, ignored);
    }
  } else {
    paths.push_back((fs::path(dir) / "take.mcap").string());
    RETURN_IF_ERROR(FetchFile(stub, lease, "", nullptr, lease.take_bytes(), paths.back()));
  }
  for (const v1::WorkInput& input : lease.inputs()) {
    // Names are the server's ("prepare", "segment-2"); kept to a safe set.
    std::string file = input.name();
    for (char& c : file) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
    }
    paths.push_back((fs::path(dir) / (file + ".part")).string());
    RETURN_IF_ERROR(FetchFile(stub, lease, input.name(), nullptr, input.bytes(), paths.back()));
  }
  return paths;
}

// Streams the reenactment at `path` under the lease.
absl::StatusOr<v1::Job> Upload(v1::Work::Stub* stub, const std::string& lease_id,
                               const std::string& path, const WorkerReport& report) {
  std::ifstream in(path, std::ios::binary);
  std::error_code error;
  const auto size = static_cast<int64_t>(fs::file_size(path, error));
  if (!in || error) return absl::InternalError(absl::StrCat("cannot read the result ", path));
  grpc::ClientContext context;
  v1::UploadResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::UploadChunk>> writer = stub->Upload(&context, &response);
  v1::UploadChunk chunk;
  chunk.set_lease_id(lease_id);
  v1::WorkResult* result = chunk.mutable_result();
  result->set_frames(report.result_frames);
  result->set_keyframes(report.result_keyframes);
  result->set_file_bytes(size);
  for (const auto& [name, value] : report.result_figures)
    (*result->mutable_figures())[name] = value;
  std::string buffer(static_cast<size_t>(std::min(kUploadChunkBytes, size)), '\0');
  int64_t sent = 0;
  bool first = true;
  while (sent < size || first) {
    const int64_t n = std::min<int64_t>(kUploadChunkBytes, size - sent);
    in.read(buffer.data(), static_cast<std::streamsize>(n));
    if (in.gcount() != n) {
      context.TryCancel();
      (void)writer->Finish();
      return absl::InternalError(absl::StrCat("reading the result failed at byte ", sent));
    }
    chunk.set_data(buffer.data(), static_cast<size_t>(n));
    if (!writer->Write(chunk)) break;  // Finish says why.
    chunk.clear_lease_id();
    chunk.clear_result();
    sent += n;
    first = false;
  }
  writer->WritesDone();
  RETURN_IF_ERROR(FromGrpcStatus(writer->Finish()));
  return response.job();
}

class Agent {
 public:
  Agent(const WorkAgentOptions& options, const std::atomic<bool>& stop)
      : options_(options), stop_(stop) {
    name_ = options.name.empty() ? DefaultName() : options.name;
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(8 << 20);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
    stub_ = v1::Work::NewStub(options.channel != nullptr
                                  ? options.channel
                                  : rpc::MakeClientChannel(options.server, args, options.security));
  }

  absl::StatusOr<WorkAgentSummary> Run() {
    const int64_t give_up_ns = SteadyNowNs() + SecondsToNs(options_.once_wait_s);
    double pause_s = 0.25;
    while (!stop_.load()) {
      if (options_.once && SteadyNowNs() >= give_up_ns) break;
      v1::LeaseRequest request;
      request.set_protocol(v1::WORK_PROTOCOL_V1);
      request.set_worker_name(name_);
      for (const std::string& method : options_.methods) request.add_methods(method);
      double wait_s = options_.lease_wait_s;
      if (options_.once) wait_s = std::min(wait_s, NsToSeconds(give_up_ns - SteadyNowNs()));
      request.set_wait_s(std::max(0.0, wait_s));
      grpc::ClientContext context;
      context.set_deadline(DeadlineIn(request.wait_s() + kCallDeadlineS));
      v1::LeaseResponse response;
      grpc::Status status;
      {
        const CancelOnStop cancel(context, stop_);
        status = stub_->Lease(&context, request, &response);
      }
      if (stop_.load()) break;
      if (!status.ok()) {
        if (Permanent(status)) return FromGrpcStatus(status);
        log::Warn(
            "server_unreachable",
            {{"server", options_.server}, {"error", status.error_message()}, {"retry_s", pause_s}},
            absl::StrCat("the server at ", options_.server, " does not answer (",
                         status.error_message(), "); trying again in ", pause_s, " s"));
        if (!SleepUnlessStopped(pause_s, stop_)) break;
        pause_s = std::min(pause_s * 2, options_.retry_max_s);
        continue;
      }
      pause_s = 0.25;
      if (!response.has_lease()) continue;
      ++summary_.jobs;
      if (RunJob(response.lease())) {
        ++summary_.succeeded;
      } else {
        ++summary_.not_succeeded;
      }
      if (options_.once) break;
    }
    return summary_;
  }

 private:
  // One leased job, start to end; true when its reenactment was stored.
  bool RunJob(const v1::WorkLease& lease) {
    const v1::Job& job = lease.job();
    const log::Field job_fields[] = {{"job_id", job.job_id()},
                                     {"take_id", job.take_id()},
                                     {"method", job.method()},
                                     {"attempt", job.attempts()}};
    log::Info("job_leased", job_fields,
              absl::StrCat("leased job ", job.job_id(), " (", job.method(), " on take ",
                           job.take_id(), ", ", lease.take_bytes(), " bytes)"));
    const absl::StatusOr<std::string> dir = MakeJobDir(job.job_id());
    if (!dir.ok()) {
      SendFail(lease,
               absl::StrCat("the worker cannot make its scratch folder: ", dir.status().message()),
               {}, /*give_back=*/true);
      return false;
    }
    const bool stored = RunJobIn(lease, *dir);
    std::error_code error;
    fs::remove_all(*dir, error);
    return stored;
  }

  bool RunJobIn(const v1::WorkLease& lease, const std::string& dir) {
    double period_s = lease.heartbeat_period_s() > 0 ? lease.heartbeat_period_s() : 5.0;
    if (options_.heartbeat_period_s > 0) period_s = std::min(period_s, options_.heartbeat_period_s);
    Heartbeats beats(stub_.get(), lease.lease_id(), period_s);
    const std::string out_path =
        (fs::path(dir) /
         (lease.part().empty() || lease.part() == "stitch" ? "reenactment.rnr" : "result.part"))
            .string();
    const std::optional<std::string> local =
        options_.local_take ? options_.local_take(lease.lease_id()) : std::nullopt;
    bool job_error = false;
    absl::StatusOr<std::vector<std::string>> inputs =
        FetchInputs(stub_.get(), lease, dir, local, options_.select_take, &job_error);
    if (!inputs.ok()) {
      beats.Stop(false);
      if (absl::IsAborted(inputs.status())) {
        return Lost(lease, std::string(inputs.status().message()));
      }
      if (job_error) {
        SendFail(
            lease,
            absl::StrCat("the job's phase cannot name its frames: ", inputs.status().message()), {},
            /*give_back=*/false);
        return false;
      }
      SendFail(lease,
               absl::StrCat("the worker could not fetch its inputs: ", inputs.status().message()),
               {}, /*give_back=*/true);
      return false;
    }
    WorkerInvocation invocation;
    invocation.worker_path = options_.job_program;
    invocation.take_path = inputs->front();
    invocation.out_path = out_path;
    invocation.reenactment_id = lease.reenactment_id();
    invocation.asset_roots = options_.asset_roots;
    invocation.memory_limit_mb = options_.memory_limit_mb;
    invocation.part = lease.part();
    invocation.input_paths.assign(inputs->begin() + 1, inputs->end());
    // The lease's options are the worker's already (no live-only ones).
    absl::StatusOr<std::unique_ptr<WorkerProcess>> started = WorkerProcess::Start(
        WorkerArgs(lease.job(), nullptr, invocation), dir,
        absl::StrCat("--- job ", lease.job().job_id(), ", lease ", lease.lease_id(), " ---"),
        lease.job().progress(), 10.0);
    if (!started.ok()) {
      beats.Stop(false);
      SendFail(lease, absl::StrCat("cannot start the worker: ", started.status().message()), {},
               /*give_back=*/false);
      return false;
    }
    WorkerProcess& worker = **started;
    std::optional<ExitInfo> exit;
    bool stopped = false;
    while (true) {
      exit = worker.Poll();  // Exit first, then read: all it wrote is in.
      std::vector<std::string> logs;
      worker.ReadOutput(&logs);
      beats.Report(worker.progress(), std::move(logs));
      if (exit.has_value()) break;
      if (beats.lost() || stop_.load()) {
        stopped = stopped || stop_.load();
        worker.Cancel(stopped ? options_.stop_grace_s : options_.cancel_grace_s);
      }
      std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_period_s));
    }
    if (beats.lost()) {
      beats.Stop(false);
      return Lost(lease, beats.lost_reason());
    }
    const bool ok = exit->exited && exit->exit_code == 0;
    if (ok) {
      beats.Stop(/*flush=*/true);
      const absl::StatusOr<v1::Job> stored =
          Upload(stub_.get(), lease.lease_id(), out_path, worker.report());
      if (!stored.ok()) {
        log::Error("upload_failed",
                   {{"job_id", lease.job().job_id()}, {"error", stored.status().message()}},
                   absl::StrCat("job ", lease.job().job_id(),
                                ": the upload was refused: ", stored.status().message()));
        return false;
      }
      log::Info("job_stored",
                {{"job_id", lease.job().job_id()}, {"reenactment_id", stored->reenactment_id()}},
                absl::StrCat("job ", lease.job().job_id(), " succeeded: reenactment ",
                             stored->reenactment_id()));
      return true;
    }
    std::vector<std::string> logs = beats.Stop(false);
    if (stopped && !options_.give_back_on_stop) {
      log::Info("job_left", {{"job_id", lease.job().job_id()}},
                absl::StrCat("job ", lease.job().job_id(), " stopped with the worker; it stays ",
                             "running on the server, which queues it again when it starts"));
    } else if (stopped) {
      SendFail(lease, "the worker was told to stop", std::move(logs), /*give_back=*/true);
    } else {
      SendFail(lease, worker.FailureText(*exit), std::move(logs), /*give_back=*/false);
    }
    return false;
  }

  bool Lost(const v1::WorkLease& lease, const std::string& why) {
    log::Warn("lease_lost", {{"job_id", lease.job().job_id()}, {"why", why}},
              absl::StrCat("job ", lease.job().job_id(), " dropped: ", why));
    return false;
  }

  void SendFail(const v1::WorkLease& lease, const std::string& error, std::vector<std::string> logs,
                bool give_back) {
    v1::FailRequest request;
    request.set_lease_id(lease.lease_id());
    request.set_error(error);
    request.set_give_back(give_back);
    for (std::string& line : logs) request.add_log_lines(std::move(line));
    grpc::ClientContext context;
    context.set_deadline(DeadlineIn(kCallDeadlineS));
    v1::FailResponse response;
    const grpc::Status status = stub_->Fail(&context, request, &response);
    log::Warn(give_back ? "job_given_back" : "job_failed",
              {{"job_id", lease.job().job_id()},
               {"error", error},
               {"told_server", status.ok() ? "yes" : status.error_message()}},
              absl::StrCat("job ", lease.job().job_id(),
                           give_back ? " given back: " : " failed: ", error));
  }

  absl::StatusOr<std::string> MakeJobDir(const std::string& job_id) {
    std::string root = options_.scratch_dir;
    if (root.empty()) {
      const char* tmp = std::getenv("TMPDIR");
      root = tmp != nullptr && tmp[0] != '\0' ? tmp : "/tmp";
    }
    static std::mt19937_64 random{std::random_device{}()};
    const fs::path dir =
        fs::path(root) / absl::StrFormat("reenact-job-%s-%08x", job_id, random() & 0xffffffffu);
    std::error_code error;
    fs::create_directories(dir, error);
    if (error) return absl::InternalError(absl::StrCat(dir.string(), ": ", error.message()));
    ::chmod(dir.c_str(), 0700);
    return dir.string();
  }

  const WorkAgentOptions& options_;
  const std::atomic<bool>& stop_;
  std::string name_;
  std::unique_ptr<v1::Work::Stub> stub_;
  WorkAgentSummary summary_;
};

}  // namespace

absl::StatusOr<WorkAgentSummary> RunWorkAgent(const WorkAgentOptions& options,
                                              const std::atomic<bool>& stop) {
  if (options.server.empty()) return absl::InvalidArgumentError("--server is empty");
  if (options.job_program.empty()) return absl::InvalidArgumentError("no job program");
  if (!(options.once_wait_s >= 0) || !(options.lease_wait_s >= 0) ||
      !(options.cancel_grace_s >= 0) || !(options.poll_period_s > 0) ||
      !(options.retry_max_s > 0)) {
    return absl::InvalidArgumentError("wait, grace and poll times must be positive");
  }
  Agent agent(options, stop);
  return agent.Run();
}

}  // namespace reenact::server
