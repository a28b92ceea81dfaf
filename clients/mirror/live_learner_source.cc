#include "clients/mirror/live_learner_source.h"

#include <algorithm>
#include <atomic>
#include <limits>
#include <thread>

#include "absl/strings/str_cat.h"
#include "clients/mirror/learner_queue.h"
#include "common/base/status_macros.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"

namespace reenact::mirror {
namespace {

// Frames kept for the app; older ones are dropped when it falls behind.
constexpr size_t kLiveFramesKept = 2;

// The daemon's CaptureControl service through the client SDK (ListSensors,
// StreamFrames). Cancel ends a running stream at once through the SDK's
// StreamCancel, even when the daemon sends nothing.
class DaemonFrameFeed : public LiveFrameFeed {
 public:
  explicit DaemonFrameFeed(const DaemonFeedOptions& options)
      : options_(options), client_(options.connection) {}

  absl::StatusOr<std::vector<v1::SensorInfo>> Sensors() override { return client_.ListSensors(); }

  absl::Status Stream(const std::string& sensor_id,
                      const std::function<bool(const v1::LiveFrameSet&)>& on_set) override {
    absl::Status status = client_.StreamFrames(
        Request(sensor_id),
        [&](const v1::LiveFrameSet& set) { return !cancel_.cancelled() && on_set(set); }, &cancel_);
    if (status.code() == absl::StatusCode::kUnimplemented) {
      return absl::UnimplementedError(
          absl::StrCat("reenactd at ", options_.connection.address,
                       " cannot stream frames to clients (no StreamFrames RPC: an older daemon?)"));
    }
    return status;
  }

  void Cancel() override { cancel_.Cancel(); }

  std::string Describe() const override {
    return absl::StrCat("reenactd ", options_.connection.address);
  }

 private:
  v1::StreamFramesRequest Request(const std::string& sensor_id) const {
    v1::StreamFramesRequest request;
    request.add_sensor_ids(sensor_id);
    request.add_color_sensor_ids(sensor_id);
    request.set_color_max_width_px(options_.color_max_width_px);
    request.set_color_jpeg_quality(options_.color_jpeg_quality);
    return request;
  }

  DaemonFeedOptions options_;
  client::CaptureClient client_;
  client::StreamCancel cancel_;
};

bool Streams(const v1::SensorInfo& sensor) { return sensor.state() == v1::SENSOR_STATE_STREAMING; }

// The sensor to follow: `wanted`, or the first streaming one with skeletons.
absl::StatusOr<v1::SensorInfo> ChooseSensor(const std::vector<v1::SensorInfo>& sensors,
                                            const std::string& wanted, const std::string& where) {
  for (const v1::SensorInfo& sensor : sensors) {
    if (!wanted.empty() && sensor.sensor_id() == wanted) return sensor;
  }
  if (!wanted.empty()) {
    return absl::NotFoundError(absl::StrCat(where, " has no sensor '", wanted, "'"));
  }
  const v1::SensorInfo* first = nullptr;
  for (const v1::SensorInfo& sensor : sensors) {
    if (!Streams(sensor)) continue;
    if (sensor.provides_skeleton()) return sensor;
    if (first == nullptr) first = &sensor;
  }
  if (first == nullptr) {
    return absl::FailedPreconditionError(absl::StrCat(where, " has no streaming sensor"));
  }
  return *first;
}

class LiveLearnerSource : public LearnerSource {
 public:
  LiveLearnerSource(std::unique_ptr<LiveFrameFeed> feed, LearnerSensor sensor,
                    Rigid3d color_from_depth, int64_t clock_offset_ns)
      : feed_(std::move(feed)),
        sensor_(std::move(sensor)),
        color_from_depth_(std::move(color_from_depth)),
        clock_offset_ns_(clock_offset_ns) {
    thread_ = std::thread([this] { Receive(); });
  }
  ~LiveLearnerSource() override {
    stopping_ = true;
    feed_->Cancel();
    queue_.Cancel();
    if (thread_.joinable()) thread_.join();
  }

  const LearnerSensor& sensor() const override { return sensor_; }
  absl::StatusOr<std::optional<LearnerFrame>> Next() override { return queue_.Pop(); }
  std::string Describe() const override {
    return absl::StrCat(feed_->Describe(), ", sensor ", sensor_.sensor_id);
  }
  int64_t frames_dropped() const override { return queue_.dropped() + daemon_dropped_; }

 private:
  void Receive() {
    int64_t last_stamp_ns = std::numeric_limits<int64_t>::min();
    const absl::Status status = feed_->Stream(sensor_.sensor_id, [&](const v1::LiveFrameSet& set) {
      if (stopping_) return false;
      daemon_dropped_ = static_cast<int64_t>(set.dropped_sets());
      LearnerFrame frame =
          LearnerFrameFromSet(set, sensor_.sensor_id, color_from_depth_, clock_offset_ns_);
      frame.stamp_ns = std::max(frame.stamp_ns, last_stamp_ns);
      last_stamp_ns = frame.stamp_ns;
      return queue_.Push(std::move(frame));
    });
    queue_.Close(status);
  }

  std::unique_ptr<LiveFrameFeed> feed_;
  LearnerSensor sensor_;
  Rigid3d color_from_depth_;
  int64_t clock_offset_ns_ = 0;
  std::atomic<bool> stopping_{false};
  std::atomic<int64_t> daemon_dropped_{0};
  LearnerQueue queue_{kLiveFramesKept, LearnerQueue::WhenFull::kDropOldest};
  std::thread thread_;
};

}  // namespace

absl::Status DaemonFeedOptions::Validate() const {
  if (connection.address.empty()) return absl::InvalidArgumentError("--daemon HOST:PORT is empty");
  if (color_max_width_px < 1) return absl::InvalidArgumentError("colour width must be > 0");
  if (color_jpeg_quality < 1 || color_jpeg_quality > 100) {
    return absl::InvalidArgumentError("colour JPEG quality must be 1..100");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<LiveFrameFeed>> NewDaemonFrameFeed(
    const DaemonFeedOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  return std::unique_ptr<LiveFrameFeed>(std::make_unique<DaemonFrameFeed>(options));
}

LearnerFrame LearnerFrameFromSet(const v1::LiveFrameSet& set, const std::string& sensor_id,
                                 const Rigid3d& color_from_depth, int64_t clock_offset_ns) {
  LearnerFrame frame;
  frame.stamp_ns = set.stamp_ns();
  std::vector<const v1::Skeleton*> skeletons;
  for (const v1::Skeleton& skeleton : set.skeletons()) {
    if (skeleton.sensor_id() != sensor_id) continue;
    if (skeletons.empty()) {
      frame.stamp_ns =
          ExposureStampNs(skeleton.device_stamp_ns(), skeleton.host_stamp_ns(), clock_offset_ns);
      frame.host_stamp_ns = std::max(frame.host_stamp_ns, skeleton.host_stamp_ns());
    }
    skeletons.push_back(&skeleton);
  }
  if (std::optional<LearnerSkeleton> learner = ChooseLearnerSkeleton(skeletons, color_from_depth)) {
    frame.skeleton_in_color = learner->pose;
    frame.joint_seen = learner->seen;
    frame.people_in_view = learner->people;
  }
  for (const v1::ColorImage& color : set.colors()) {
    if (color.sensor_id() != sensor_id || color.data().empty()) continue;
    frame.stamp_ns =
        ExposureStampNs(color.device_stamp_ns(), color.host_stamp_ns(), clock_offset_ns);
    frame.host_stamp_ns = std::max(frame.host_stamp_ns, color.host_stamp_ns());
    if (!color.encoding().empty() && color.encoding() != "jpeg") break;
    absl::StatusOr<RgbImage> decoded = DecodeJpeg(color.data());
    if (decoded.ok()) frame.color = *std::move(decoded);
    break;
  }
  return frame;
}

absl::StatusOr<std::unique_ptr<LearnerSource>> OpenLiveLearner(std::unique_ptr<LiveFrameFeed> feed,
                                                               const std::string& sensor_id) {
  if (feed == nullptr) return absl::InvalidArgumentError("no live frame feed");
  ASSIGN_OR_RETURN(const std::vector<v1::SensorInfo> sensors, feed->Sensors());
  ASSIGN_OR_RETURN(const v1::SensorInfo chosen, ChooseSensor(sensors, sensor_id, feed->Describe()));
  ASSIGN_OR_RETURN(LearnerSensor sensor, LearnerSensorFromCalibration(chosen.calibration()));
  sensor.sensor_id = chosen.sensor_id();
  sensor.live = true;
  if (chosen.nominal_fps() > 0) sensor.nominal_fps = chosen.nominal_fps();
  ASSIGN_OR_RETURN(const Rigid3d color_from_depth, LearnerColorFromDepth(chosen.calibration()));
  return std::unique_ptr<LearnerSource>(
      std::make_unique<LiveLearnerSource>(std::move(feed), std::move(sensor), color_from_depth,
                                          chosen.calibration().clock_offset_ns()));
}

}  // namespace reenact::mirror
