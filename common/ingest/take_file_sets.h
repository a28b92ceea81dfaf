// The frame sets of a take file (common/io/take.h), rebuilt the way a capture
// daemon would have sent them over the Ingest service, so that a take
// recorded elsewhere (imported, synthesised, downloaded from another server)
// can be sent to a server with the same durable ingest (`reenact takes
// upload`).
//
// Grouping, as the server's reconstruction reads a take
// (server/recon/take_frames.h):
//  * a take the server ingested holds /ingest/frame_set records: each record
//    is one set, made of the frames it lists (by sensor and frame_index),
//    with its stamp, skew and missing sensors;
//  * any other take: the frames of all sensors with the same frame_index
//    form one set, stamped with the mean of their host stamps; sets are
//    ordered by stamp.
// A frame is its sensor's depth image with the colour image, actor mask and
// skeletons of the same sensor and frame_index. Messages without a depth
// image of their frame are left out (a FrameSet's frames always carry
// depth) and counted. Ground truth is not part of any set: the server keeps
// what a daemon sends.
//
// Reading takes two passes over the file: the first parses only the index of
// every message (sensor, stream, frame_index) to plan the sets, the second
// assembles each set as its last message arrives and hands it over in order.
// A take written in time order (every Reenact writer) keeps a few sets in
// memory; one whose messages are far out of order would need more than
// `max_buffered_bytes` and is refused (ResourceExhausted) rather than loaded
// whole.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/io/take.h"
#include "reenact/v1/frame.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"

namespace reenact::ingest {

// The daemon id that `reenact takes upload` opens its takes with: a take it
// sent may be resumed by any later upload of the same file (with the same
// credential, which the server checks as for any take).
inline constexpr char kTakeUploadDaemonId[] = "reenact-takes-upload";

struct TakeFileSetsOptions {
  // Bound on the frames held while waiting for the rest of their set, bytes.
  int64_t max_buffered_bytes = int64_t{512} << 20;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What the first pass found.
struct TakeFilePlan {
  int64_t frame_sets = 0;             // Sets that will be handed over.
  int64_t frames = 0;                 // Sensor frames in them.
  bool from_ingest_records = false;   // Grouped by /ingest/frame_set records.
  int64_t messages_left_out = 0;      // Sensor messages without a depth frame.
  int64_t ground_truth_messages = 0;  // Not sent (see the header comment).
  std::map<std::string, int64_t> frames_per_sensor;
  // FNV-1a (64 bit) over the file's size, its TakeInfo and every set's
  // stamp and frames: two files with the same fingerprint send the same
  // take (the default take id of `reenact takes upload` is made from it).
  uint64_t fingerprint = 0;
};

class TakeFileSets {
 public:
  // Opens `path` and plans its sets (the first pass). InvalidArgument or
  // DataLoss (from TakeReader) for a file that is not a readable take;
  // FailedPrecondition when it has no sensor or no depth frame.
  static absl::StatusOr<std::unique_ptr<TakeFileSets>> Open(
      const std::string& path, const TakeFileSetsOptions& options = {});

  const v1::TakeInfo& info() const { return reader_->info(); }
  // Every sensor's calibration, in sensor id order.
  std::vector<v1::SensorCalibration> sensors() const;
  const TakeFilePlan& plan() const { return plan_; }
  // Sensors whose stream ended early (/ingest/sensor_lost), by stamp.
  const std::vector<v1::SensorLostRecord>& sensors_lost() const { return lost_; }

  // The second pass: calls `on_set` with each set in order (sequence 1, 2,
  // ...). An error from `on_set` stops the pass and is returned.
  absl::Status ForEach(const std::function<absl::Status(v1::FrameSet set)>& on_set) const;

 private:
  struct FrameKey {
    int sensor = 0;
    int64_t frame_index = 0;
    bool operator<(const FrameKey& o) const {
      return sensor != o.sensor ? sensor < o.sensor : frame_index < o.frame_index;
    }
  };
  // Messages a planned frame waits for.
  struct FrameParts {
    int64_t host_stamp_ns = 0;
    bool color = false;
    bool mask = false;
    int skeletons = 0;
    int set = -1;  // Index into sets_; -1 while not in a set.
  };
  struct PlannedSet {
    int64_t stamp_ns = 0;
    int64_t skew_ns = 0;
    std::vector<FrameKey> frames;
    std::vector<std::string> missing_sensor_ids;
  };
  enum class Stream { kDepth, kColor, kMask, kSkeleton };
  struct Route {
    int sensor = 0;
    Stream stream = Stream::kDepth;
  };

  TakeFileSets(std::unique_ptr<TakeReader> reader, const TakeFileSetsOptions& options)
      : reader_(std::move(reader)), options_(options) {}
  absl::Status Plan();
  void PlanFromRecords(const std::vector<v1::FrameSetRecord>& records);
  void PlanByFrameIndex();
  absl::StatusOr<Route> RouteOf(const McapChannel& channel) const;

  std::unique_ptr<TakeReader> reader_;
  TakeFileSetsOptions options_;
  std::vector<std::string> sensor_ids_;  // Sorted; index = FrameKey::sensor.
  std::map<std::string, Route> routes_;  // Topic -> route.
  std::map<FrameKey, FrameParts> frames_;
  std::vector<PlannedSet> sets_;
  std::vector<v1::SensorLostRecord> lost_;
  TakeFilePlan plan_;
};

}  // namespace reenact::ingest
