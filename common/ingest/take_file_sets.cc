#include "common/ingest/take_file_sets.h"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <optional>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::ingest {
namespace {

constexpr char kSensorPrefix[] = "/sensor/";
constexpr char kGroundTruthPrefix[] = "/ground_truth/";

const char* TypeOf(int stream) {
  switch (stream) {
    case 0:
      return "reenact.v1.DepthImage";
    case 1:
      return "reenact.v1.ColorImage";
    case 2:
      return "reenact.v1.ActorMask";
    default:
      return "reenact.v1.Skeleton";
  }
}

struct Fnv1a {
  uint64_t value = 14695981039346656037ull;
  void Add(std::string_view bytes) {
    for (const unsigned char c : bytes) value = (value ^ c) * 1099511628211ull;
    Add(static_cast<uint64_t>(bytes.size()));
  }
  void Add(uint64_t word) {
    for (int i = 0; i < 8; ++i) value = (value ^ ((word >> (8 * i)) & 0xff)) * 1099511628211ull;
  }
  void Add(int64_t word) { Add(static_cast<uint64_t>(word)); }
};

}  // namespace

absl::Status TakeFileSetsOptions::Validate() const {
  if (max_buffered_bytes < (int64_t{1} << 20)) {
    return absl::InvalidArgumentError("max_buffered_bytes must be at least 1 MiB");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<TakeFileSets>> TakeFileSets::Open(
    const std::string& path, const TakeFileSetsOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  std::unique_ptr<TakeFileSets> sets(new TakeFileSets(std::move(reader), options));
  RETURN_IF_ERROR(sets->Plan());
  return sets;
}

std::vector<v1::SensorCalibration> TakeFileSets::sensors() const {
  std::vector<v1::SensorCalibration> out;
  for (const std::string& id : sensor_ids_) out.push_back(reader_->sensors().at(id));
  return out;
}

absl::StatusOr<TakeFileSets::Route> TakeFileSets::RouteOf(const McapChannel& channel) const {
  const auto route = routes_.find(channel.topic);
  if (route == routes_.end()) return absl::NotFoundError(channel.topic);
  const auto& schemas = reader_->mcap().schemas();
  const auto schema = schemas.find(channel.schema_id);
  const char* expected = TypeOf(static_cast<int>(route->second.stream));
  if (schema == schemas.end() || schema->second.name != expected) {
    return absl::InvalidArgumentError(absl::StrCat(reader_->mcap().path(), ": channel ",
                                                   channel.topic, " does not hold ", expected));
  }
  return route->second;
}

absl::Status TakeFileSets::Plan() {
  for (const auto& [id, calibration] : reader_->sensors()) sensor_ids_.push_back(id);
  if (sensor_ids_.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(reader_->mcap().path(), ": the take has no sensor"));
  }
  for (int s = 0; s < static_cast<int>(sensor_ids_.size()); ++s) {
    routes_[SensorTopic(sensor_ids_[s], "depth")] = {s, Stream::kDepth};
    routes_[SensorTopic(sensor_ids_[s], "color")] = {s, Stream::kColor};
    routes_[SensorTopic(sensor_ids_[s], "mask")] = {s, Stream::kMask};
    routes_[SensorTopic(sensor_ids_[s], "skeleton")] = {s, Stream::kSkeleton};
  }
  // The index of every sensor message; the parts of frames without depth
  // are counted once the depth frames are known.
  std::map<FrameKey, FrameParts> others;
  std::vector<v1::FrameSetRecord> records;
  const std::string path = reader_->mcap().path();
  RETURN_IF_ERROR(reader_->mcap().ForEachMessage(
      [&](const McapChannel& channel, const McapMessage& message) -> absl::Status {
        if (channel.topic == kIngestFrameSetTopic || channel.topic == kIngestSensorLostTopic) {
          const bool is_record = channel.topic == kIngestFrameSetTopic;
          v1::FrameSetRecord record;
          v1::SensorLostRecord lost;
          google::protobuf::Message& m = is_record ? static_cast<google::protobuf::Message&>(record)
                                                   : static_cast<google::protobuf::Message&>(lost);
          if (!m.ParseFromString(message.data)) {
            return absl::DataLossError(absl::StrCat(path, ": message on ", channel.topic,
                                                    " at log time ", message.log_time_ns,
                                                    " ns does not parse"));
          }
          if (is_record) {
            records.push_back(std::move(record));
          } else {
            lost_.push_back(std::move(lost));
          }
          return absl::OkStatus();
        }
        if (absl::StartsWith(channel.topic, kGroundTruthPrefix)) {
          ++plan_.ground_truth_messages;
          return absl::OkStatus();
        }
        if (!absl::StartsWith(channel.topic, kSensorPrefix)) return absl::OkStatus();
        absl::StatusOr<Route> route = RouteOf(channel);
        if (absl::IsNotFound(route.status())) return absl::OkStatus();  // Calibration.
        if (!route.ok()) return route.status();
        // Every per-frame message carries sensor_id = 1, device_stamp_ns = 2,
        // host_stamp_ns = 3 and frame_index = 4; parsing the whole message
        // (its image included) is what a reader has to do anyway.
        int64_t frame_index = 0;
        int64_t host_stamp_ns = 0;
        auto parse = [&](auto& typed) -> absl::Status {
          if (!typed.ParseFromString(message.data)) {
            return absl::DataLossError(absl::StrCat(path, ": message on ", channel.topic,
                                                    " at log time ", message.log_time_ns,
                                                    " ns does not parse"));
          }
          frame_index = typed.frame_index();
          host_stamp_ns = typed.host_stamp_ns();
          return absl::OkStatus();
        };
        switch (route->stream) {
          case Stream::kDepth: {
            v1::DepthImage m;
            RETURN_IF_ERROR(parse(m));
            break;
          }
          case Stream::kColor: {
            v1::ColorImage m;
            RETURN_IF_ERROR(parse(m));
            break;
          }
          case Stream::kMask: {
            v1::ActorMask m;
            RETURN_IF_ERROR(parse(m));
            break;
          }
          case Stream::kSkeleton: {
            v1::Skeleton m;
            RETURN_IF_ERROR(parse(m));
            break;
          }
        }
        const FrameKey key{route->sensor, frame_index};
        if (route->stream == Stream::kDepth) {
          auto [it, added] = frames_.try_emplace(key);
          if (added) it->second.host_stamp_ns = host_stamp_ns;
          return absl::OkStatus();  // A second depth image of a frame is left out below.
        }
        FrameParts& parts = others[key];
        switch (route->stream) {
          case Stream::kColor:
            parts.color = true;
            break;
          case Stream::kMask:
            parts.mask = true;
            break;
          default:
            ++parts.skeletons;
            break;
        }
        return absl::OkStatus();
      }));
  if (frames_.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, ": the take has no depth frame, so no frame set to send"));
  }
  for (const auto& [key, parts] : others) {
    const auto frame = frames_.find(key);
    if (frame == frames_.end()) {
      plan_.messages_left_out += parts.skeletons + parts.color + parts.mask;
      continue;
    }
    frame->second.color = parts.color;
    frame->second.mask = parts.mask;
    frame->second.skeletons = parts.skeletons;
  }
  if (!records.empty()) {
    plan_.from_ingest_records = true;
    std::sort(records.begin(), records.end(),
              [](const v1::FrameSetRecord& a, const v1::FrameSetRecord& b) {
                return a.sequence() < b.sequence();
              });
    PlanFromRecords(records);
  } else {
    PlanByFrameIndex();
  }
  std::sort(lost_.begin(), lost_.end(),
            [](const v1::SensorLostRecord& a, const v1::SensorLostRecord& b) {
              return a.stamp_ns() < b.stamp_ns();
            });
  // Frames no set took (a record-less tail after a crash) are left out.
  for (auto it = frames_.begin(); it != frames_.end();) {
    if (it->second.set >= 0) {
      ++it;
      continue;
    }
    plan_.messages_left_out += 1 + it->second.color + it->second.mask + it->second.skeletons;
    it = frames_.erase(it);
  }
  plan_.frame_sets = static_cast<int64_t>(sets_.size());
  Fnv1a hash;
  hash.Add(reader_->mcap().file_size());
  hash.Add(reader_->info().SerializeAsString());
  for (const PlannedSet& set : sets_) {
    plan_.frames += static_cast<int64_t>(set.frames.size());
    hash.Add(set.stamp_ns);
    for (const FrameKey& key : set.frames) {
      ++plan_.frames_per_sensor[sensor_ids_[static_cast<size_t>(key.sensor)]];
      hash.Add(sensor_ids_[static_cast<size_t>(key.sensor)]);
      hash.Add(key.frame_index);
    }
  }
  plan_.fingerprint = hash.value;
  return absl::OkStatus();
}

void TakeFileSets::PlanByFrameIndex() {
  std::map<int64_t, PlannedSet> by_index;
  for (const auto& [key, parts] : frames_) by_index[key.frame_index].frames.push_back(key);
  for (auto& [index, set] : by_index) {
    int64_t low = std::numeric_limits<int64_t>::max();
    int64_t high = std::numeric_limits<int64_t>::min();
    long double sum = 0;
    std::vector<bool> present(sensor_ids_.size(), false);
    for (const FrameKey& key : set.frames) {
      const int64_t stamp = frames_.at(key).host_stamp_ns;
      low = std::min(low, stamp);
      high = std::max(high, stamp);
      sum += static_cast<long double>(stamp);
      present[static_cast<size_t>(key.sensor)] = true;
    }
    set.stamp_ns = static_cast<int64_t>(sum / static_cast<long double>(set.frames.size()));
    set.skew_ns = high - low;
    for (size_t s = 0; s < present.size(); ++s) {
      if (!present[s]) set.missing_sensor_ids.push_back(sensor_ids_[s]);
    }
    sets_.push_back(std::move(set));
  }
  std::stable_sort(sets_.begin(), sets_.end(), [](const PlannedSet& a, const PlannedSet& b) {
    return a.stamp_ns < b.stamp_ns;
  });
  for (size_t i = 0; i < sets_.size(); ++i) {
    for (const FrameKey& key : sets_[i].frames) frames_.at(key).set = static_cast<int>(i);
  }
}

void TakeFileSets::PlanFromRecords(const std::vector<v1::FrameSetRecord>& records) {
  // Per sensor, its depth frames by stamp, for records without frame indices.
  std::vector<std::vector<std::pair<int64_t, FrameKey>>> by_stamp(sensor_ids_.size());
  for (const auto& [key, parts] : frames_) {
    by_stamp[static_cast<size_t>(key.sensor)].push_back({parts.host_stamp_ns, key});
  }
  for (auto& list : by_stamp) std::sort(list.begin(), list.end());
  auto sensor_index = [this](const std::string& id) {
    const auto it = std::lower_bound(sensor_ids_.begin(), sensor_ids_.end(), id);
    return it != sensor_ids_.end() && *it == id ? static_cast<int>(it - sensor_ids_.begin()) : -1;
  };
  // The unused frame of `sensor` nearest to `stamp`.
  auto nearest = [&](int sensor, int64_t stamp) -> std::optional<FrameKey> {
    const auto& list = by_stamp[static_cast<size_t>(sensor)];
    const auto it = std::lower_bound(
        list.begin(), list.end(), stamp,
        [](const std::pair<int64_t, FrameKey>& a, int64_t b) { return a.first < b; });
    std::optional<FrameKey> best;
    int64_t best_gap = std::numeric_limits<int64_t>::max();
    for (auto lo = it; lo != list.begin();) {
      --lo;
      if (frames_.at(lo->second).set >= 0) continue;
      best = lo->second;
      best_gap = stamp - lo->first;
      break;
    }
    for (auto hi = it; hi != list.end(); ++hi) {
      if (frames_.at(hi->second).set >= 0) continue;
      if (hi->first - stamp < best_gap) best = hi->second;
      break;
    }
    return best;
  };
  for (const v1::FrameSetRecord& record : records) {
    PlannedSet set;
    set.stamp_ns = record.stamp_ns();
    set.skew_ns = record.skew_ns();
    set.missing_sensor_ids.assign(record.missing_sensor_ids().begin(),
                                  record.missing_sensor_ids().end());
    const int index = static_cast<int>(sets_.size());
    for (int k = 0; k < record.sensor_ids_size(); ++k) {
      const int sensor = sensor_index(record.sensor_ids(k));
      if (sensor < 0) continue;
      if (record.frame_indices_size() == record.sensor_ids_size()) {
        const FrameKey key{sensor, record.frame_indices(k)};
        const auto frame = frames_.find(key);
        if (frame == frames_.end() || frame->second.set >= 0) continue;
        frame->second.set = index;
        set.frames.push_back(key);
        continue;
      }
      const std::optional<FrameKey> key = nearest(sensor, record.stamp_ns());
      if (!key) continue;
      frames_.at(*key).set = index;
      set.frames.push_back(*key);
    }
    if (!set.frames.empty()) sets_.push_back(std::move(set));
  }
}

absl::Status TakeFileSets::ForEach(
    const std::function<absl::Status(v1::FrameSet set)>& on_set) const {
  struct PendingFrame {
    v1::Frame frame;
    bool depth = false;
    bool color = false;
    bool mask = false;
    int skeletons = 0;
    int64_t bytes = 0;  // Of the messages taken.
  };
  struct PendingSet {
    std::map<FrameKey, PendingFrame> frames;
    int64_t remaining = 0;  // Messages still to come.
  };
  std::map<int, PendingSet> pending;
  size_t next = 0;
  uint64_t sequence = 0;
  int64_t buffered_bytes = 0;
  auto remaining_of = [this](const PlannedSet& set) {
    int64_t n = 0;
    for (const FrameKey& key : set.frames) {
      const FrameParts& parts = frames_.at(key);
      n += 1 + parts.color + parts.mask + parts.skeletons;
    }
    return n;
  };
  auto emit_ready = [&]() -> absl::Status {
    while (next < sets_.size()) {
      const auto it = pending.find(static_cast<int>(next));
      if (it == pending.end() || it->second.remaining > 0) return absl::OkStatus();
      const PlannedSet& plan = sets_[next];
      v1::FrameSet set;
      set.set_sequence(++sequence);
      set.set_stamp_ns(plan.stamp_ns);
      set.set_skew_ns(plan.skew_ns);
      for (const std::string& id : plan.missing_sensor_ids) set.add_missing_sensor_ids(id);
      for (const FrameKey& key : plan.frames) {
        PendingFrame& frame = it->second.frames.at(key);
        buffered_bytes -= frame.bytes;
        set.add_frames()->Swap(&frame.frame);
      }
      pending.erase(it);
      ++next;
      RETURN_IF_ERROR(on_set(std::move(set)));
    }
    return absl::OkStatus();
  };
  const std::string& path = reader_->mcap().path();
  RETURN_IF_ERROR(reader_->mcap().ForEachMessage([&](const McapChannel& channel,
                                                     const McapMessage& message) -> absl::Status {
    if (!absl::StartsWith(channel.topic, kSensorPrefix)) return absl::OkStatus();
    absl::StatusOr<Route> route = RouteOf(channel);
    if (absl::IsNotFound(route.status())) return absl::OkStatus();
    if (!route.ok()) return route.status();
    auto fail = [&] {
      return absl::DataLossError(absl::StrCat(path, ": message on ", channel.topic, " at log time ",
                                              message.log_time_ns, " ns does not parse"));
    };
    // Parsed straight into the frame it belongs to.
    v1::Frame scratch;
    int64_t frame_index = 0;
    switch (route->stream) {
      case Stream::kDepth:
        if (!scratch.mutable_depth()->ParseFromString(message.data)) return fail();
        frame_index = scratch.depth().frame_index();
        break;
      case Stream::kColor:
        if (!scratch.mutable_color()->ParseFromString(message.data)) return fail();
        frame_index = scratch.color().frame_index();
        break;
      case Stream::kMask:
        if (!scratch.mutable_mask()->ParseFromString(message.data)) return fail();
        frame_index = scratch.mask().frame_index();
        break;
      case Stream::kSkeleton:
        if (!scratch.add_skeletons()->ParseFromString(message.data)) return fail();
        frame_index = scratch.skeletons(0).frame_index();
        break;
    }
    const FrameKey key{route->sensor, frame_index};
    const auto planned = frames_.find(key);
    if (planned == frames_.end() || planned->second.set < static_cast<int>(next)) {
      return absl::OkStatus();
    }
    const int set_index = planned->second.set;
    auto [entry, added] = pending.try_emplace(set_index);
    if (added) entry->second.remaining = remaining_of(sets_[static_cast<size_t>(set_index)]);
    PendingFrame& frame = entry->second.frames[key];
    bool take = false;
    switch (route->stream) {
      case Stream::kDepth:
        take = !frame.depth;
        if (take) {
          frame.depth = true;
          frame.frame.set_sensor_id(sensor_ids_[static_cast<size_t>(key.sensor)]);
          frame.frame.set_device_stamp_ns(scratch.depth().device_stamp_ns());
          frame.frame.set_host_stamp_ns(scratch.depth().host_stamp_ns());
          frame.frame.set_frame_index(frame_index);
          frame.frame.mutable_depth()->Swap(scratch.mutable_depth());
        }
        break;
      case Stream::kColor:
        take = !frame.color && planned->second.color;
        if (take) {
          frame.color = true;
          frame.frame.mutable_color()->Swap(scratch.mutable_color());
        }
        break;
      case Stream::kMask:
        take = !frame.mask && planned->second.mask;
        if (take) {
          frame.mask = true;
          frame.frame.mutable_mask()->Swap(scratch.mutable_mask());
        }
        break;
      case Stream::kSkeleton:
        take = frame.skeletons < planned->second.skeletons;
        if (take) {
          ++frame.skeletons;
          frame.frame.add_skeletons()->Swap(scratch.mutable_skeletons(0));
        }
        break;
    }
    if (!take) return absl::OkStatus();
    frame.bytes += static_cast<int64_t>(message.data.size());
    buffered_bytes += static_cast<int64_t>(message.data.size());
    if (buffered_bytes > options_.max_buffered_bytes) {
      return absl::ResourceExhaustedError(absl::StrCat(
          path, ": more than ", options_.max_buffered_bytes >> 20,
          " MiB of frames wait for the rest of their sets; the take's messages are too far "
          "out of time order to stream (rewrite it in order, e.g. with `reenact import`)"));
    }
    --entry->second.remaining;
    return emit_ready();
  }));
  if (next < sets_.size()) {
    return absl::DataLossError(absl::StrCat(path, ": frame set ", next + 1, " of ", sets_.size(),
                                            " lost messages between the two reads of the file"));
  }
  return absl::OkStatus();
}

}  // namespace reenact::ingest
