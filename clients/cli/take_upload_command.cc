// `reenact takes upload TAKE.mcap`: sends a take file to a reenact-server
// through its Ingest service, with the capture daemon's durable path
// (common/ingest): the file's frame sets (common/ingest/take_file_sets.h) go
// through a bounded disk spool to a resumable uplink, which reconnects with
// backoff when the server or the network goes away and resends from what
// the server acknowledged as durable. The take id is made from the file's
// fingerprint, so running the same command again after an interruption
// resumes the take where the server holds it, and running it after success
// changes nothing.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <ostream>
#include <thread>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/remote_flags.h"
#include "common/base/flags.h"
#include "common/base/time.h"
#include "common/ingest/take_file_sets.h"
#include "common/ingest/take_recorder.h"
#include "common/ingest/uplink.h"

namespace reenact::cli {
namespace {

// Where the spool goes without --spool: the user's state folder (frames of
// people never land in the shared /tmp).
std::string DefaultUploadSpool() {
  if (const char* state = std::getenv("XDG_STATE_HOME"); state != nullptr && *state == '/') {
    return (std::filesystem::path(state) / "reenact" / "upload-spool").string();
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home == '/') {
    return (std::filesystem::path(home) / ".local" / "state" / "reenact" / "upload-spool").string();
  }
  return "reenact-upload-spool";
}

// "<file stem, [A-Za-z0-9_-], at most 40>-<16 hex of the fingerprint>".
std::string DefaultTakeId(const std::string& path, uint64_t fingerprint) {
  std::string stem;
  for (const char c : std::filesystem::path(path).stem().string()) {
    if (stem.size() >= 40) break;
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    stem.push_back(ok ? c : '_');
  }
  return absl::StrFormat("%s%s%016x", stem, stem.empty() ? "" : "-", fingerprint);
}

bool ValidTakeId(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    if (!ok) return false;
  }
  return true;
}

// An exclusive lock on "<spool root>/<take id>.lock" for the life of the
// upload: one upload of a take at a time from this spool. The empty lock
// file is left in place.
class UploadLock {
 public:
  static absl::StatusOr<UploadLock> Take(const std::string& spool_root,
                                         const std::string& take_id) {
    std::error_code ec;
    std::filesystem::create_directories(spool_root, ec);
    if (ec) {
      return absl::UnavailableError(
          absl::StrCat("cannot create the upload spool ", spool_root, ": ", ec.message()));
    }
    // The spool holds people's frames: its user's alone, even if it existed.
    std::filesystem::permissions(spool_root, std::filesystem::perms::owner_all, ec);
    const std::string path = (std::filesystem::path(spool_root) / (take_id + ".lock")).string();
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0) return absl::UnavailableError(absl::StrCat("cannot open ", path));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd);
      return absl::FailedPreconditionError(
          absl::StrCat("another upload of take ", take_id, " is running (", path, ")"));
    }
    return UploadLock(fd);
  }
  UploadLock(UploadLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  UploadLock& operator=(UploadLock&&) = delete;
  // The file stays: unlinking it would let an upload that opened it just
  // before hold a lock on a file no longer in the folder, beside one that
  // creates it anew.
  ~UploadLock() {
    if (fd_ >= 0) ::close(fd_);
  }

 private:
  explicit UploadLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

}  // namespace

int RunTakesUpload(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args,
                            {"server", "timeout", "tls-ca", "token-file", "take-id", "name",
                             "spool", "spool-max-mb", "stall-timeout"},
                            {"json", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("takes upload needs exactly one TAKE.mcap"), err);
  }
  const std::string path = flags->positional()[0];
  auto stall_s = flags->GetDouble("stall-timeout", 120.0);
  if (!stall_s.ok()) return ReportError(stall_s.status(), err);
  if (!(*stall_s > 0)) {
    return ReportError(absl::InvalidArgumentError("--stall-timeout must be > 0 seconds"), err);
  }
  auto spool_mb = flags->GetInt("spool-max-mb", 256);
  if (!spool_mb.ok()) return ReportError(spool_mb.status(), err);
  if (*spool_mb < 16 || *spool_mb > (1 << 20)) {
    return ReportError(absl::InvalidArgumentError("--spool-max-mb must be within 16..1048576"),
                       err);
  }
  auto connection = ConnectionFromFlags(*flags, "server", kDefaultServer);
  if (!connection.ok()) return ReportError(connection.status(), err);
  const bool json = flags->Has("json");

  auto sets = ingest::TakeFileSets::Open(path);
  if (!sets.ok()) {
    err << "reenact: " << sets.status().message() << "\n";
    return kExitFailure;
  }
  const ingest::TakeFilePlan& plan = (*sets)->plan();
  const std::string take_id = flags->GetOr("take-id", DefaultTakeId(path, plan.fingerprint));
  if (!ValidTakeId(take_id)) {
    return ReportError(
        absl::InvalidArgumentError("--take-id must be 1..64 characters of [A-Za-z0-9_-]"), err);
  }

  ingest::TakeRecorderOptions options;
  options.spool_root = flags->GetOr("spool", DefaultUploadSpool());
  options.spool_max_bytes = static_cast<int64_t>(*spool_mb) << 20;
  options.wait_when_full = true;  // A file can wait for the server.
  options.uplink.max_message_bytes = connection->max_message_bytes;
  options.uplink.security = connection->security;
  options.uplink.open_timeout_s = connection->timeout_s;
  auto lock = UploadLock::Take(options.spool_root, take_id);
  if (!lock.ok()) return ReportError(lock.status(), err);
  // What an earlier, interrupted upload of this take left in the spool: the
  // file holds all of it, and the server says from where to go on.
  std::error_code ec;
  std::filesystem::remove_all(std::filesystem::path(options.spool_root) / take_id, ec);

  v1::TakeInfo info = (*sets)->info();
  if (flags->Has("name")) info.set_name(flags->GetOr("name", ""));
  if (info.created_unix_ns() == 0) info.set_created_unix_ns(WallNowNs());
  auto recorder = ingest::TakeRecorder::Start(
      ingest::MakeIngestChannel(connection->address, options.uplink), options, take_id,
      ingest::kTakeUploadDaemonId, info, (*sets)->sensors());
  if (!recorder.ok()) return ReportError(recorder.status(), err);
  ingest::TakeRecorder& take = **recorder;

  const int64_t start_ns = SteadyNowNs();
  std::atomic<bool> reading_done = false;
  absl::Status read_status;
  std::thread reader([&] {
    read_status = (*sets)->ForEach([&take](v1::FrameSet set) { return take.Add(std::move(set)); });
    if (read_status.ok()) take.Stop(absl::StrCat("uploaded from ", path));
    reading_done = true;
  });

  ProgressBar bar(err, !json && !flags->Has("quiet"));
  uint64_t last_durable = 0;
  int64_t last_progress_ns = SteadyNowNs();
  std::string stalled;
  while (!take.WaitDone(0.2)) {
    const ingest::TakeStats stats = take.Stats();
    if (stats.durable_sequence != last_durable) {
      last_durable = stats.durable_sequence;
      last_progress_ns = SteadyNowNs();
    }
    const int64_t planned = std::max<int64_t>(plan.frame_sets, 1);
    bar.Update({"upload", std::min(1.0, static_cast<double>(last_durable) / planned),
                static_cast<int64_t>(last_durable), plan.frame_sets});
    if (reading_done && !read_status.ok()) break;
    if (static_cast<double>(SteadyNowNs() - last_progress_ns) / kNanosPerSecond > *stall_s) {
      stalled = absl::StrFormat("nothing became durable on the server for %.0f s", *stall_s);
      if (!stats.uplink.last_error.empty())
        absl::StrAppend(&stalled, " (", stats.uplink.last_error, ")");
      break;
    }
  }
  bar.Finish();
  const bool read_failed = reading_done && !read_status.ok();
  const bool uploaded = take.done() && take.result().ok();
  if (!uploaded) take.Abort();  // Stops the reader, also while it waits for spool space.
  reader.join();
  const ingest::TakeStats stats = take.Stats();
  const double seconds = static_cast<double>(SteadyNowNs() - start_ns) / kNanosPerSecond;
  if (!uploaded) {
    std::string why;
    if (read_failed) {
      why = std::string(read_status.message());
    } else if (!stalled.empty()) {
      why = "UNAVAILABLE: " + stalled;
    } else {
      const absl::Status status = take.result();
      why = absl::StrCat(absl::StatusCodeToString(status.code()), ": ", status.message());
    }
    const bool retry = read_failed       ? false
                       : stalled.empty() ? !ingest::IsNonRetryable(take.result().code())
                                         : true;
    err << "reenact: " << why;
    if (retry) err << "; run the same command again to resume take " << take_id;
    err << "\n";
    // The spool holds nothing the file does not; leave no frames behind.
    const std::string spool_dir = (std::filesystem::path(options.spool_root) / take_id).string();
    recorder->reset();
    std::filesystem::remove_all(spool_dir, ec);
    return kExitFailure;
  }
  const std::optional<v1::TakeClosed> closed = take.closed();
  const int64_t size_bytes = closed ? closed->size_bytes() : 0;
  if (json) {
    nlohmann::json j = {{"take_id", take_id},
                        {"file", path},
                        {"frame_sets", closed ? closed->frame_set_count() : 0},
                        {"frames", closed ? closed->frame_count() : 0},
                        {"size_bytes", size_bytes},
                        {"frame_sets_sent", stats.uplink.frame_sets_sent},
                        {"resumed", stats.uplink.first_open_resumed},
                        {"server_held_at_start", stats.uplink.first_open_durable_sequence},
                        {"reconnects", stats.uplink.reconnects},
                        {"seconds", seconds},
                        {"grouped_by", plan.from_ingest_records ? "ingest records" : "frame index"},
                        {"messages_left_out", plan.messages_left_out},
                        {"ground_truth_messages_not_sent", plan.ground_truth_messages}};
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << "uploaded " << path << " as take " << take_id << ": "
      << (closed ? closed->frame_set_count() : 0) << " frame sets, "
      << (closed ? closed->frame_count() : 0) << " frames, " << HumanBytes(size_bytes) << " stored";
  if (stats.uplink.first_open_resumed) {
    out << " (the server held " << stats.uplink.first_open_durable_sequence << " of them already)";
  }
  out << absl::StrFormat(" in %.1f s", seconds);
  if (stats.uplink.reconnects > 0) out << ", " << stats.uplink.reconnects << " reconnects";
  out << "\n";
  if (plan.messages_left_out > 0) {
    out << "left out " << plan.messages_left_out
        << " sensor messages without a depth frame (a frame set's frames carry depth)\n";
  }
  if (plan.ground_truth_messages > 0) {
    out << "not sent: " << plan.ground_truth_messages
        << " ground-truth messages (the server stores what a capture daemon sends)\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
