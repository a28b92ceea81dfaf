#include "capture_daemon/sync_group.h"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"

namespace reenact::capture {

absl::Status SyncOptions::Validate() const {
  if (tolerance_ns < 0) return absl::InvalidArgumentError("SyncOptions.tolerance_ns < 0");
  if (max_wait_ns < -1) return absl::InvalidArgumentError("SyncOptions.max_wait_ns < -1");
  if (offset_window_frames < 1) {
    return absl::InvalidArgumentError("SyncOptions.offset_window_frames < 1");
  }
  if (!(default_fps > 0.0)) return absl::InvalidArgumentError("SyncOptions.default_fps <= 0");
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<SyncGroup>> SyncGroup::Create(const SyncOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  return std::unique_ptr<SyncGroup>(new SyncGroup(options));
}

absl::Status SyncGroup::AddSensor(const std::string& sensor_id, double nominal_fps) {
  if (sensor_id.empty()) return absl::InvalidArgumentError("sync group: empty sensor id");
  auto it = sensors_.find(sensor_id);
  if (it != sensors_.end() && it->second.stats.live) {
    return absl::InvalidArgumentError(
        absl::StrCat("sync group: sensor ", sensor_id, " is already streaming"));
  }
  SensorState& sensor = sensors_[sensor_id];
  sensor.stats.sensor_id = sensor_id;
  sensor.stats.live = true;
  sensor.nominal_fps = nominal_fps > 0.0 ? nominal_fps : 0.0;
  sensor.differences_ns.clear();
  sensor.has_offset = false;
  return absl::OkStatus();
}

int64_t SyncGroup::tolerance_ns() const {
  if (options_.tolerance_ns > 0) return options_.tolerance_ns;
  double slowest_fps = 0.0;
  for (const auto& [id, sensor] : sensors_) {
    const double fps = sensor.nominal_fps > 0.0 ? sensor.nominal_fps : options_.default_fps;
    slowest_fps = slowest_fps == 0.0 ? fps : std::min(slowest_fps, fps);
  }
  if (slowest_fps == 0.0) slowest_fps = options_.default_fps;
  return static_cast<int64_t>(0.5e9 / slowest_fps);
}

int64_t SyncGroup::max_wait_ns() const {
  return options_.max_wait_ns >= 0 ? options_.max_wait_ns : 2 * tolerance_ns();
}

int64_t SyncGroup::UpdateOffset(SensorState& sensor, const v1::Frame& frame) {
  // Running lower envelope of host - device over the window.
  sensor.differences_ns.push_back(frame.host_stamp_ns() - frame.device_stamp_ns());
  while (static_cast<int>(sensor.differences_ns.size()) > options_.offset_window_frames) {
    sensor.differences_ns.pop_front();
  }
  sensor.stats.clock_offset_ns =
      *std::min_element(sensor.differences_ns.begin(), sensor.differences_ns.end());
  sensor.has_offset = true;
  return sensor.stats.clock_offset_ns;
}

std::vector<v1::FrameSet> SyncGroup::Add(v1::Frame frame) {
  auto it = sensors_.find(frame.sensor_id());
  if (it == sensors_.end()) return {};
  SensorState& sensor = it->second;
  ++sensor.stats.frames_in;
  if (!sensor.stats.live) {
    ++sensor.stats.frames_dropped;
    return {};
  }
  const int64_t corrected_ns = frame.device_stamp_ns() + UpdateOffset(sensor, frame);
  const int64_t tolerance = tolerance_ns();
  newest_corrected_ns_ = std::max(newest_corrected_ns_, corrected_ns);

  // The open set whose anchor is nearest, within the tolerance.
  OpenSet* nearest = nullptr;
  int64_t nearest_distance = std::numeric_limits<int64_t>::max();
  for (auto set = open_.lower_bound(corrected_ns - tolerance);
       set != open_.end() && set->first <= corrected_ns + tolerance; ++set) {
    const int64_t distance = std::llabs(set->first - corrected_ns);
    if (distance < nearest_distance) {
      nearest_distance = distance;
      nearest = &set->second;
    }
  }
  if (nearest != nullptr) {
    if (nearest->corrected_ns.count(frame.sensor_id()) > 0) {
      ++sensor.stats.frames_duplicate;
    } else {
      nearest->corrected_ns[frame.sensor_id()] = corrected_ns;
      nearest->frames.push_back(std::move(frame));
    }
  } else if (last_emitted_anchor_ns_ != INT64_MIN &&
             corrected_ns <= last_emitted_anchor_ns_ + tolerance) {
    // Its instant was already sent: a second frame for a sent set is a
    // duplicate, anything else arrived too late.
    bool duplicate = false;
    for (const SentSet& sent : recently_sent_) {
      if (std::llabs(sent.anchor_ns - corrected_ns) <= tolerance &&
          sent.sensor_ids.count(frame.sensor_id()) > 0) {
        duplicate = true;
      }
    }
    ++(duplicate ? sensor.stats.frames_duplicate : sensor.stats.frames_dropped);
  } else {
    OpenSet& set = open_[corrected_ns];
    set.anchor_ns = corrected_ns;
    set.corrected_ns[frame.sensor_id()] = corrected_ns;
    set.frames.push_back(std::move(frame));
  }
  return EmitReady();
}

bool SyncGroup::Complete(const OpenSet& set) const {
  for (const auto& [id, sensor] : sensors_) {
    if (sensor.stats.live && set.corrected_ns.count(id) == 0) return false;
  }
  return true;
}

std::vector<v1::FrameSet> SyncGroup::EmitReady() {
  std::vector<v1::FrameSet> out;
  const int64_t window_ns = tolerance_ns() + max_wait_ns();
  while (!open_.empty()) {
    auto front = open_.begin();
    if (!Complete(front->second) && newest_corrected_ns_ <= front->first + window_ns) break;
    out.push_back(Emit(std::move(front->second)));
    open_.erase(front);
  }
  return out;
}

v1::FrameSet SyncGroup::Emit(OpenSet set) {
  v1::FrameSet out;
  out.set_sequence(next_sequence_++);
  int64_t earliest = std::numeric_limits<int64_t>::max();
  int64_t latest = std::numeric_limits<int64_t>::min();
  // Mean relative to the anchor, so that the sum cannot overflow.
  int64_t sum_from_anchor = 0;
  for (const auto& [id, stamp] : set.corrected_ns) {
    earliest = std::min(earliest, stamp);
    latest = std::max(latest, stamp);
    sum_from_anchor += stamp - set.anchor_ns;
  }
  const int64_t n = static_cast<int64_t>(set.corrected_ns.size());
  out.set_stamp_ns(set.anchor_ns + sum_from_anchor / std::max<int64_t>(n, 1));
  out.set_skew_ns(n > 0 ? latest - earliest : 0);
  std::sort(set.frames.begin(), set.frames.end(),
            [](const v1::Frame& a, const v1::Frame& b) { return a.sensor_id() < b.sensor_id(); });
  for (v1::Frame& frame : set.frames) {
    ++sensors_[frame.sensor_id()].stats.frames_grouped;
    *out.add_frames() = std::move(frame);
  }
  for (const auto& [id, sensor] : sensors_) {
    if (set.corrected_ns.count(id) == 0) out.add_missing_sensor_ids(id);
  }
  if (out.missing_sensor_ids_size() > 0) ++incomplete_sets_;
  skews_ns_.Add(out.skew_ns());
  SentSet sent;
  sent.anchor_ns = set.anchor_ns;
  for (const auto& [id, stamp] : set.corrected_ns) sent.sensor_ids.insert(id);
  recently_sent_.push_back(std::move(sent));
  if (recently_sent_.size() > kRecentlySent) recently_sent_.pop_front();
  last_emitted_anchor_ns_ = std::max(last_emitted_anchor_ns_, set.anchor_ns);
  return out;
}

std::vector<v1::FrameSet> SyncGroup::SensorLost(const std::string& sensor_id) {
  auto it = sensors_.find(sensor_id);
  if (it == sensors_.end()) return {};
  it->second.stats.live = false;
  return EmitReady();
}

std::vector<v1::FrameSet> SyncGroup::Expire(int64_t host_now_ns, int64_t stall_ns) {
  std::vector<v1::FrameSet> out;
  const int64_t window_ns = tolerance_ns() + max_wait_ns();
  while (!open_.empty() && open_.begin()->first + window_ns + stall_ns < host_now_ns) {
    out.push_back(Emit(std::move(open_.begin()->second)));
    open_.erase(open_.begin());
  }
  return out;
}

std::vector<v1::FrameSet> SyncGroup::Flush() {
  std::vector<v1::FrameSet> out;
  while (!open_.empty()) {
    out.push_back(Emit(std::move(open_.begin()->second)));
    open_.erase(open_.begin());
  }
  return out;
}

SyncSummary SyncGroup::Summary() const {
  SyncSummary summary;
  summary.frame_sets = static_cast<int64_t>(next_sequence_ - 1);
  summary.incomplete_sets = incomplete_sets_;
  summary.skew_p50_ns = skews_ns_.Quantile(0.5);
  summary.skew_p99_ns = skews_ns_.Quantile(0.99);
  summary.skew_max_ns = skews_ns_.max();
  for (const auto& [id, sensor] : sensors_) summary.sensors.push_back(sensor.stats);
  return summary;
}

std::vector<v1::SensorSyncStats> SyncGroup::SensorStats() const {
  std::vector<v1::SensorSyncStats> out;
  for (const auto& [id, sensor] : sensors_) {
    v1::SensorSyncStats s;
    s.set_sensor_id(id);
    s.set_frames_in(sensor.stats.frames_in);
    s.set_frames_dropped(sensor.stats.frames_dropped);
    s.set_frames_duplicate(sensor.stats.frames_duplicate);
    s.set_clock_offset_ns(sensor.stats.clock_offset_ns);
    out.push_back(s);
  }
  return out;
}

}  // namespace reenact::capture
