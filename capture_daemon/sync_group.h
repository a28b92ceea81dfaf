// The sync group of reenactd: turns the frames of several free-running sensors
// into FrameSets, one per instant of the take.
//
// Clocks. Each sensor stamps its frames on its own device clock; the backend
// adds the host arrival stamp. The group estimates, per sensor, the offset that
// maps the device clock onto the host clock (host = device + offset) as the
// running lower envelope of host - device over the last `offset_window_frames`
// frames: transport delay only ever adds to the arrival stamp, so the minimum
// is robust to arrival jitter and follows slow drift (the offset therefore
// includes the sensor's smallest transport delay). Frames are grouped on their
// offset-corrected stamps, device_stamp_ns + offset, not on arrival.
//
// Grouping. A frame joins the open set whose anchor (the corrected stamp of
// the set's first frame) is nearest, when within `tolerance_ns`; otherwise it
// opens a new set, unless its instant lies at or before a set already sent
// (then it is dropped as late). A second frame of a sensor for the same set
// is a duplicate and discarded (also when that set was already sent). Sets
// leave in time order when every live sensor has delivered, or when the
// newest corrected stamp is past the set's window by `max_wait_ns` (bounded
// waiting: a lost frame holds a set back by at most that long). A sensor that
// ended (SensorLost) no longer holds sets back.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/sample_stats.h"
#include "reenact/v1/capture_control_service.pb.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::capture {

struct SyncOptions {
  // Largest distance between a frame's corrected stamp and a set's anchor,
  // nanoseconds. 0: half the longest nominal frame period of the sensors.
  int64_t tolerance_ns = 0;
  // Extra time a set waits for missing frames past its window, measured on
  // the newest corrected stamp, nanoseconds. -1: one frame period.
  int64_t max_wait_ns = -1;
  // Frames in the lower-envelope window of the clock offset estimate.
  int offset_window_frames = 90;
  // Frame rate assumed for sensors whose nominal rate is unknown (0).
  double default_fps = 30.0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Per-sensor counters of the group.
struct SyncSensorStats {
  std::string sensor_id;
  int64_t frames_in = 0;
  int64_t frames_dropped = 0;    // Too late for their set, or malformed.
  int64_t frames_duplicate = 0;  // Second frame of the sensor for one set.
  int64_t frames_grouped = 0;    // Placed in a set (in one set each).
  int64_t clock_offset_ns = 0;   // host = device + offset.
  bool live = true;              // False after SensorLost.
};

// Figures over every set the group has emitted.
struct SyncSummary {
  int64_t frame_sets = 0;
  int64_t incomplete_sets = 0;  // Sets with a missing sensor.
  int64_t skew_p50_ns = 0;
  int64_t skew_p99_ns = 0;
  int64_t skew_max_ns = 0;
  std::vector<SyncSensorStats> sensors;
};

// Not thread-safe: the daemon serialises calls.
class SyncGroup {
 public:
  // InvalidArgument for bad options.
  static absl::StatusOr<std::unique_ptr<SyncGroup>> Create(const SyncOptions& options);

  // Declares a sensor of the group and its nominal frame rate (0: unknown).
  // InvalidArgument when the id is empty or already present and live; a
  // sensor that was lost may be added again (it comes back, e.g. replugged).
  absl::Status AddSensor(const std::string& sensor_id, double nominal_fps);

  // Adds one frame; returns the sets this completes, in time order. Sets
  // carry sequence numbers 1, 2, 3, ... in emission order. A frame of a
  // lost sensor is counted as dropped; one of an unknown sensor is ignored.
  std::vector<v1::FrameSet> Add(v1::Frame frame);

  // The sensor's stream ended: it no longer holds sets back. Returns the sets
  // this completes. Unknown ids are ignored.
  std::vector<v1::FrameSet> SensorLost(const std::string& sensor_id);

  // Emits every open set whose window ended before `host_now_ns` minus
  // `stall_ns` (for sensors that stall without ending).
  std::vector<v1::FrameSet> Expire(int64_t host_now_ns, int64_t stall_ns);

  // Emits every open set, complete or not.
  std::vector<v1::FrameSet> Flush();

  // Tolerance in use, nanoseconds.
  int64_t tolerance_ns() const;
  // Sequence number the next emitted set will carry.
  uint64_t next_sequence() const { return next_sequence_; }
  SyncSummary Summary() const;
  // Per-sensor figures in the CaptureControl Status message's form.
  std::vector<v1::SensorSyncStats> SensorStats() const;

 private:
  struct SensorState {
    SyncSensorStats stats;
    double nominal_fps = 0.0;
    // Recent host - device differences, oldest first.
    std::deque<int64_t> differences_ns;
    bool has_offset = false;
  };
  // What is remembered of a sent set, to tell duplicates from late frames.
  struct SentSet {
    int64_t anchor_ns = 0;
    std::set<std::string> sensor_ids;
  };
  static constexpr size_t kRecentlySent = 8;
  struct OpenSet {
    int64_t anchor_ns = 0;
    // Corrected stamp of each frame, by sensor id.
    std::map<std::string, int64_t> corrected_ns;
    std::vector<v1::Frame> frames;
  };

  explicit SyncGroup(const SyncOptions& options) : options_(options) {}
  int64_t UpdateOffset(SensorState& sensor, const v1::Frame& frame);
  int64_t max_wait_ns() const;
  bool Complete(const OpenSet& set) const;
  v1::FrameSet Emit(OpenSet set);
  std::vector<v1::FrameSet> EmitReady();

  SyncOptions options_;
  std::map<std::string, SensorState> sensors_;
  std::map<int64_t, OpenSet> open_;  // By anchor.
  int64_t newest_corrected_ns_ = INT64_MIN;
  int64_t last_emitted_anchor_ns_ = INT64_MIN;
  std::deque<SentSet> recently_sent_;
  uint64_t next_sequence_ = 1;
  int64_t incomplete_sets_ = 0;
  SampleReservoir skews_ns_;
};

}  // namespace reenact::capture
