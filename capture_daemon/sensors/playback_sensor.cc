#include "capture_daemon/sensors/playback_sensor.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/io/take.h"

namespace reenact::capture {

namespace {

enum class Stream { kDepth, kColor, kMask, kSkeleton };

// A frame being gathered from the messages of one sensor.
struct PendingFrame {
  CapturedFrame frame;
  int64_t source_index = 0;
  int64_t source_host_ns = 0;
  int64_t source_device_ns = 0;
  bool has_depth = false;
};

struct Slot {
  std::string source_id;  // Id in the take.
  v1::SensorInfo info;    // With the id it is played under.
  uint64_t depth_messages = 0;
  FrameCallback on_frame;
  EndCallback on_end;
  bool started = false;
  bool stopped = false;
  bool ended = false;
  int64_t delivered_this_pass = 0;
  int64_t max_index_this_pass = -1;
  int64_t index_base = 0;
  int64_t frames_delivered = 0;
  std::optional<PendingFrame> pending;
};

constexpr auto kStartGrace = std::chrono::milliseconds(200);

// The shared player of one take file (see the header).
class Player {
 public:
  Player(std::unique_ptr<TakeReader> reader, const SourceOptions& options, std::string path)
      : reader_(std::move(reader)), options_(options), path_(std::move(path)) {}
  ~Player() { Join(); }

  absl::Status Init();
  int size() const { return static_cast<int>(slots_.size()); }
  v1::SensorInfo Info(int i);
  absl::Status Start(int i, FrameCallback on_frame, EndCallback on_end);
  void Stop(int i);

 private:
  void Join();
  void Run();
  absl::Status PlayOnce(int64_t loop);
  absl::Status OnMessage(const McapChannel& channel, const McapMessage& message, int64_t loop);
  void Deliver(int i, PendingFrame pending, int64_t loop);
  void End(int i, const absl::Status& why);
  bool stopping() {
    std::lock_guard<std::mutex> lock(mutex_);
    return stop_;
  }

  std::unique_ptr<TakeReader> reader_;
  SourceOptions options_;
  std::string path_;
  std::vector<Slot> slots_;
  std::map<uint16_t, std::pair<int, Stream>> channels_;
  int64_t first_stamp_ns_ = 0;
  int64_t loop_period_ns_ = 0;
  int64_t frame_period_ns_ = 33'333'333;
  int64_t anchor_wall_ns_ = 0;
  int64_t anchor_steady_ns_ = 0;

  std::mutex mutex_;
  std::condition_variable cv_;
  std::thread thread_;
  bool thread_started_ = false;
  bool stop_ = false;
  int delivering_ = -1;
  std::optional<std::chrono::steady_clock::time_point> first_start_;
};

int64_t PeriodNs(double fps) { return fps > 0.0 ? static_cast<int64_t>(1e9 / fps) : 33'333'333; }

absl::Status Player::Init() {
  const McapReader& mcap = reader_->mcap();
  int index = options_.first_index;
  double fps = reader_->info().fps();
  for (const auto& [source_id, calibration] : reader_->sensors()) {
    const McapChannel* depth = mcap.FindChannel(SensorTopic(source_id, "depth"));
    if (depth == nullptr) continue;
    Slot slot;
    slot.source_id = source_id;
    const std::string id =
        options_.id_prefix.empty() ? source_id : absl::StrCat(options_.id_prefix, index++);
    auto count = [&mcap](const McapChannel* channel) -> uint64_t {
      if (channel == nullptr) return 0;
      auto it = mcap.statistics().channel_message_counts.find(channel->id);
      return it == mcap.statistics().channel_message_counts.end() ? 0 : it->second;
    };
    slot.depth_messages = count(depth);
    const McapChannel* color = mcap.FindChannel(SensorTopic(source_id, "color"));
    const McapChannel* mask = mcap.FindChannel(SensorTopic(source_id, "mask"));
    const McapChannel* skeleton = mcap.FindChannel(SensorTopic(source_id, "skeleton"));
    const int slot_index = static_cast<int>(slots_.size());
    channels_[depth->id] = {slot_index, Stream::kDepth};
    if (color) channels_[color->id] = {slot_index, Stream::kColor};
    if (mask) channels_[mask->id] = {slot_index, Stream::kMask};
    if (skeleton) channels_[skeleton->id] = {slot_index, Stream::kSkeleton};

    v1::SensorInfo& info = slot.info;
    info.set_sensor_id(id);
    info.set_backend("playback");
    info.set_model(calibration.model());
    info.set_serial(calibration.serial());
    info.set_uri(path_);
    info.set_state(v1::SENSOR_STATE_STREAMING);
    info.set_depth_width_px(calibration.depth_intrinsics().width_px());
    info.set_depth_height_px(calibration.depth_intrinsics().height_px());
    info.set_color_width_px(calibration.color_intrinsics().width_px());
    info.set_color_height_px(calibration.color_intrinsics().height_px());
    info.set_nominal_fps(calibration.nominal_fps() > 0 ? calibration.nominal_fps() : fps);
    info.set_provides_skeleton(count(skeleton) > 0);
    info.set_provides_mask(count(mask) > 0);
    info.set_provides_registration(false);
    *info.mutable_calibration() = calibration;
    info.mutable_calibration()->set_sensor_id(id);
    if (fps <= 0.0) fps = calibration.nominal_fps();
    slots_.push_back(std::move(slot));
  }
  if (slots_.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path_, ": the take has no sensor with depth"));
  }
  const McapStatistics& statistics = mcap.statistics();
  first_stamp_ns_ = reader_->info().start_stamp_ns() > 0
                        ? reader_->info().start_stamp_ns()
                        : static_cast<int64_t>(statistics.start_time_ns);
  const int64_t last_ns = static_cast<int64_t>(statistics.end_time_ns);
  frame_period_ns_ = PeriodNs(fps);
  loop_period_ns_ = std::max<int64_t>(last_ns - first_stamp_ns_, 0) + frame_period_ns_;
  return absl::OkStatus();
}

v1::SensorInfo Player::Info(int i) {
  std::lock_guard<std::mutex> lock(mutex_);
  v1::SensorInfo info = slots_[i].info;
  info.set_frames_delivered(slots_[i].frames_delivered);
  if (slots_[i].ended || slots_[i].stopped) info.set_state(v1::SENSOR_STATE_GONE);
  return info;
}

absl::Status Player::Start(int i, FrameCallback on_frame, EndCallback on_end) {
  std::lock_guard<std::mutex> lock(mutex_);
  Slot& slot = slots_[i];
  if (slot.started) {
    return absl::FailedPreconditionError(
        absl::StrCat("playback sensor ", slot.info.sensor_id(), " already started"));
  }
  if (slot.ended || stop_) {
    return absl::FailedPreconditionError(
        absl::StrCat("playback sensor ", slot.info.sensor_id(), " has ended"));
  }
  slot.on_frame = std::move(on_frame);
  slot.on_end = std::move(on_end);
  slot.started = true;
  if (!first_start_) first_start_ = std::chrono::steady_clock::now();
  if (!thread_started_) {
    thread_started_ = true;
    thread_ = std::thread([this] { Run(); });
  }
  cv_.notify_all();
  return absl::OkStatus();
}

void Player::Stop(int i) {
  bool join = false;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    slots_[i].stopped = true;
    // Stop from inside this sensor's own callback cannot wait for itself.
    if (thread_.get_id() != std::this_thread::get_id()) {
      cv_.wait(lock, [&] { return delivering_ != i; });
    }
    join = std::all_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.stopped; });
    if (join) stop_ = true;
    cv_.notify_all();
  }
  if (join) Join();
}

void Player::Join() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    cv_.notify_all();
  }
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

void Player::Run() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_until(lock, *first_start_ + kStartGrace, [this] {
      return stop_ || std::all_of(slots_.begin(), slots_.end(),
                                  [](const Slot& s) { return s.started || s.stopped; });
    });
    if (stop_) return;
  }
  anchor_wall_ns_ = WallNowNs();
  anchor_steady_ns_ = SteadyNowNs();
  for (int64_t loop = 0;; ++loop) {
    const absl::Status status = PlayOnce(loop);
    if (stopping()) return;
    if (!status.ok()) {
      for (int i = 0; i < size(); ++i) End(i, status);
      return;
    }
    if (!options_.loop) break;
    for (Slot& slot : slots_) {
      slot.index_base += slot.max_index_this_pass + 1;
      slot.max_index_this_pass = -1;
      slot.delivered_this_pass = 0;
    }
  }
  for (int i = 0; i < size(); ++i) End(i, absl::OkStatus());
}

absl::Status Player::PlayOnce(int64_t loop) {
  absl::Status status = reader_->mcap().ForEachMessage(
      [this, loop](const McapChannel& channel, const McapMessage& message) {
        return OnMessage(channel, message, loop);
      });
  if (stopping()) return absl::CancelledError("playback stopped");
  // Frames still gathering at the end of the file.
  for (int i = 0; i < size(); ++i) {
    if (slots_[i].pending) {
      PendingFrame last = std::move(*slots_[i].pending);
      slots_[i].pending.reset();
      if (status.ok()) Deliver(i, std::move(last), loop);
    }
  }
  return status;
}

absl::Status Player::OnMessage(const McapChannel& channel, const McapMessage& message,
                               int64_t loop) {
  if (stopping()) return absl::CancelledError("playback stopped");
  auto it = channels_.find(channel.id);
  if (it == channels_.end()) return absl::OkStatus();
  const auto [i, stream] = it->second;
  Slot& slot = slots_[i];
  v1::Frame scratch;
  google::protobuf::Message* target = nullptr;
  switch (stream) {
    case Stream::kDepth:
      target = scratch.mutable_depth();
      break;
    case Stream::kColor:
      target = scratch.mutable_color();
      break;
    case Stream::kMask:
      target = scratch.mutable_mask();
      break;
    case Stream::kSkeleton:
      target = scratch.add_skeletons();
      break;
  }
  if (!target->ParseFromString(message.data)) {
    return absl::DataLossError(absl::StrCat(path_, ": message on ", channel.topic, " at log time ",
                                            message.log_time_ns, " ns does not parse"));
  }
  int64_t index = 0;
  switch (stream) {
    case Stream::kDepth:
      index = scratch.depth().frame_index();
      break;
    case Stream::kColor:
      index = scratch.color().frame_index();
      break;
    case Stream::kMask:
      index = scratch.mask().frame_index();
      break;
    case Stream::kSkeleton:
      index = scratch.skeletons(0).frame_index();
      break;
  }
  if (slot.pending && slot.pending->source_index != index) {
    PendingFrame done = std::move(*slot.pending);
    slot.pending.reset();
    Deliver(i, std::move(done), loop);
  }
  if (!slot.pending) {
    slot.pending.emplace();
    slot.pending->source_index = index;
    slot.pending->source_host_ns = static_cast<int64_t>(message.log_time_ns);
  }
  v1::Frame& frame = slot.pending->frame.frame;
  switch (stream) {
    case Stream::kDepth:
      slot.pending->has_depth = true;
      slot.pending->source_host_ns = scratch.depth().host_stamp_ns();
      slot.pending->source_device_ns = scratch.depth().device_stamp_ns();
      frame.mutable_depth()->Swap(scratch.mutable_depth());
      break;
    case Stream::kColor:
      frame.mutable_color()->Swap(scratch.mutable_color());
      break;
    case Stream::kMask:
      frame.mutable_mask()->Swap(scratch.mutable_mask());
      break;
    case Stream::kSkeleton:
      frame.add_skeletons()->Swap(scratch.mutable_skeletons(0));
      break;
  }
  // A sensor whose stream went quiet for two frame periods has no more
  // messages for its pending frame: hand it over now, so that a stream that
  // ends early ends early.
  for (int other = 0; other < size(); ++other) {
    std::optional<PendingFrame>& waiting = slots_[other].pending;
    if (other != i && waiting &&
        static_cast<int64_t>(message.log_time_ns) >
            waiting->source_host_ns + 2 * frame_period_ns_) {
      PendingFrame done = std::move(*waiting);
      waiting.reset();
      Deliver(other, std::move(done), loop);
    }
  }
  return absl::OkStatus();
}

// Sets the ids, stamps and index on a per-stream message.
template <typename M>
void Restamp(M* m, const std::string& id, int64_t device_ns, int64_t host_ns, int64_t index) {
  m->set_sensor_id(id);
  m->set_device_stamp_ns(device_ns);
  m->set_host_stamp_ns(host_ns);
  m->set_frame_index(index);
}

void Player::Deliver(int i, PendingFrame pending, int64_t loop) {
  Slot& slot = slots_[i];
  if (!pending.has_depth) return;
  slot.max_index_this_pass = std::max(slot.max_index_this_pass, pending.source_index);
  const int64_t shift_ns = loop * loop_period_ns_;
  const int64_t host_ns = anchor_wall_ns_ + (pending.source_host_ns - first_stamp_ns_) + shift_ns;
  const int64_t device_ns = pending.source_device_ns + shift_ns;
  const int64_t index = slot.index_base + pending.source_index;
  const std::string& id = slot.info.sensor_id();
  v1::Frame& frame = pending.frame.frame;
  frame.set_sensor_id(id);
  frame.set_device_stamp_ns(device_ns);
  frame.set_host_stamp_ns(host_ns);
  frame.set_frame_index(index);
  Restamp(frame.mutable_depth(), id, device_ns, host_ns, index);
  if (frame.has_color()) Restamp(frame.mutable_color(), id, device_ns, host_ns, index);
  if (frame.has_mask()) Restamp(frame.mutable_mask(), id, device_ns, host_ns, index);
  for (v1::Skeleton& skeleton : *frame.mutable_skeletons()) {
    Restamp(&skeleton, id, device_ns, host_ns, index);
  }

  std::unique_lock<std::mutex> lock(mutex_);
  if (!options_.fast) {
    const auto due = std::chrono::steady_clock::time_point(
        std::chrono::nanoseconds(anchor_steady_ns_ + (host_ns - anchor_wall_ns_)));
    cv_.wait_until(lock, due, [this] { return stop_; });
  }
  ++slot.delivered_this_pass;
  if (stop_ || !slot.started || slot.stopped || slot.ended) return;
  delivering_ = i;
  FrameCallback& callback = slot.on_frame;
  lock.unlock();
  callback(std::move(pending.frame));
  lock.lock();
  ++slot.frames_delivered;
  delivering_ = -1;
  cv_.notify_all();
  const bool last =
      !options_.loop && slot.delivered_this_pass >= static_cast<int64_t>(slot.depth_messages);
  lock.unlock();
  if (last) End(i, absl::OkStatus());
}

void Player::End(int i, const absl::Status& why) {
  std::unique_lock<std::mutex> lock(mutex_);
  Slot& slot = slots_[i];
  if (slot.ended) return;
  slot.ended = true;
  if (!slot.started || slot.stopped || stop_) return;
  delivering_ = i;
  lock.unlock();
  slot.on_end(why);
  lock.lock();
  delivering_ = -1;
  cv_.notify_all();
}

// A view of one slot of the shared Player. Not a ThreadedSensor
// (sensors/threaded_sensor.h): the sensors of a take share the player's one
// thread, which reads the file once for all of them.
class PlaybackSensor : public Sensor {
 public:
  PlaybackSensor(std::shared_ptr<Player> player, int index)
      : player_(std::move(player)), index_(index) {}
  ~PlaybackSensor() override { Stop(); }
  v1::SensorInfo info() const override { return player_->Info(index_); }
  absl::Status Start(FrameCallback on_frame, EndCallback on_end) override {
    return player_->Start(index_, std::move(on_frame), std::move(on_end));
  }
  void Stop() override { player_->Stop(index_); }

 private:
  std::shared_ptr<Player> player_;
  int index_;
};

}  // namespace

absl::StatusOr<SensorList> OpenPlaybackSensors(const std::string& path,
                                               const SourceOptions& options) {
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  auto player = std::make_shared<Player>(std::move(reader), options, path);
  RETURN_IF_ERROR(player->Init());
  SensorList sensors;
  for (int i = 0; i < player->size(); ++i) {
    sensors.push_back(std::make_unique<PlaybackSensor>(player, i));
  }
  return sensors;
}

}  // namespace reenact::capture
