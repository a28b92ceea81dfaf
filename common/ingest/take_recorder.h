// One take being recorded by reenactd: numbers the sync group's FrameSets
// 1, 2, 3, ... within the take, appends each to the take's disk spool, and
// drives the take's uplink (common/ingest/uplink.h) until the server holds
// the whole take. Also measures what the end-to-end figures need: frames per
// sensor, bytes per set, and the latency from a set's capture (its newest
// frame's host stamp) to the Ack that made it durable.
//
// The spool folder of a take is <spool root>/<take id>; it holds the take's
// OpenTake ("open.pb") and, once stopped, its CloseTake ("close.pb"), so that
// a daemon that restarts finds unfinished takes (ListUnfinishedTakes) and
// finishes their upload (ResumeUnfinished).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/sample_stats.h"
#include "common/ingest/spool.h"
#include "common/ingest/uplink.h"
#include "reenact/v1/ingest_service.pb.h"

namespace reenact::ingest {

struct TakeRecorderOptions {
  // Folder holding one spool folder per take.
  std::string spool_root;
  // Bound of the take's spool, bytes.
  int64_t spool_max_bytes = int64_t{1} << 30;
  // When the spool is full: wait for acknowledgements (sources that can
  // pause, e.g. playback) instead of refusing the set.
  bool wait_when_full = false;
  UplinkOptions uplink;
};

// Figures of one take.
struct TakeStats {
  std::string take_id;
  int64_t frame_sets = 0;          // Spooled (numbered) sets.
  int64_t frame_sets_refused = 0;  // Refused because the spool was full.
  std::map<std::string, int64_t> frames_per_sensor;
  int64_t bytes_total = 0;  // Spool record bytes of all sets.
  uint64_t durable_sequence = 0;
  int64_t acked_sets = 0;  // Sets whose latency was measured.
  int64_t latency_p50_ns = 0;
  int64_t latency_p99_ns = 0;
  int64_t latency_max_ns = 0;
  int64_t spool_frame_sets = 0;
  int64_t spool_bytes = 0;
  UplinkStats uplink;
};

class TakeRecorder {
 public:
  // Starts recording take `take_id`: creates its spool folder and its uplink
  // (which connects once the first set is there, or at Stop). `info` is the
  // take's description (start_stamp_ns is filled from the first set),
  // `sensors` every sensor of the take.
  static absl::StatusOr<std::unique_ptr<TakeRecorder>> Start(
      const std::shared_ptr<grpc::Channel>& channel, const TakeRecorderOptions& options,
      const std::string& take_id, const std::string& daemon_id, const v1::TakeInfo& info,
      const std::vector<v1::SensorCalibration>& sensors);

  // Resumes the upload of an unfinished take found in `dir` (a folder of
  // ListUnfinishedTakes): resends what the server lacks and closes it
  // (reason "daemon restarted" when it was never stopped).
  static absl::StatusOr<std::unique_ptr<TakeRecorder>> ResumeUnfinished(
      const std::shared_ptr<grpc::Channel>& channel, const TakeRecorderOptions& options,
      const std::string& dir);

  ~TakeRecorder();

  // Holds the take's OpenTake back (sets are spooled meanwhile) until
  // ReleaseOpen or Stop; call before the first Add. For calibrations that are
  // still being measured when the take starts (the board anchoring).
  void HoldOpen();
  // Replaces the calibrations of the held OpenTake by those of `sensors`
  // with the same sensor_id, and lets it go to the server. No-op when the
  // open was not held or is already sent.
  void ReleaseOpen(const std::vector<v1::SensorCalibration>& sensors);

  // Appends one set (its sequence is replaced by the take's next one; frames
  // of sensors not in the take are removed). A set whose sequence the server
  // already holds (it resumed the take at a later durable sequence) is
  // numbered and skipped. ResourceExhausted when the spool
  // is full (the set is refused and counted; with wait_when_full only after
  // Stop or Abort); FailedPrecondition after Stop or Abort.
  absl::Status Add(v1::FrameSet set);
  // A sensor of the take ended.
  void SensorLost(const std::string& sensor_id, int64_t stamp_ns, const std::string& reason);
  // No more sets: close the take once everything is sent. Idempotent.
  void Stop(const std::string& reason);
  // Add no longer waits for space (it refuses instead); for a daemon that
  // is about to stop the take.
  void StopWaiting();
  // Gives up uploading, leaving the spool on disk.
  void Abort();
  // Waits up to `timeout_s` (negative: forever) for the server to close the
  // take (then the spool folder is removed) or the uplink to fail.
  bool WaitDone(double timeout_s);
  bool done() const;
  // OK once the server closed the take; the uplink's error otherwise.
  absl::Status result() const;
  std::optional<v1::TakeClosed> closed() const;

  const std::string& take_id() const { return take_id_; }
  uint64_t last_sequence() const;
  TakeStats Stats() const;

 private:
  TakeRecorder(const TakeRecorderOptions& options, std::string take_id);
  void OnAck(uint64_t durable_sequence, int64_t arrival_ns);
  void SendOpen(int64_t start_stamp_ns);
  void SendOpenLocked(int64_t start_stamp_ns);

  TakeRecorderOptions options_;
  std::string take_id_;
  std::unique_ptr<Spool> spool_;
  std::unique_ptr<TakeUplink> uplink_;
  std::optional<v1::OpenTake> open_;  // Before SendOpen: the template.
  std::mutex open_mutex_;
  bool open_sent_ = false;
  bool open_held_ = false;
  std::optional<int64_t> held_start_stamp_ns_;  // The first set's, while held.
  std::set<std::string> sensor_ids_;

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool stopped_ = false;
  bool no_wait_ = false;
  bool aborted_ = false;
  bool removed_ = false;
  uint64_t last_sequence_ = 0;
  int64_t frame_sets_ = 0;
  int64_t refused_ = 0;
  int64_t bytes_total_ = 0;
  std::map<std::string, int64_t> frames_per_sensor_;
  // Newest frame host stamp of each spooled, unacknowledged set.
  std::deque<std::pair<uint64_t, int64_t>> newest_stamp_ns_;
  SampleReservoir latency_ns_;
};

// Folders under `spool_root` holding a take whose upload did not finish.
std::vector<std::string> ListUnfinishedTakes(const std::string& spool_root);

// A take id: "<UTC yyyymmddThhmmss>-<name, sanitized, up to 24>-<4 hex>".
std::string MakeTakeId(const std::string& name);

}  // namespace reenact::ingest
