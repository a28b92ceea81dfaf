// The learner from a recorded take (learner_source.h, OpenTakeLearner).
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "clients/mirror/learner_queue.h"
#include "clients/mirror/learner_source.h"
#include "common/base/status_macros.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/tracking/tracking_proto.h"

namespace reenact::mirror {
namespace {

// Frames decoded ahead of the app.
constexpr size_t kFramesAhead = 4;

uint64_t ChannelCount(const TakeReader& take, const std::string& topic) {
  for (const TakeChannel& channel : take.channels()) {
    if (channel.topic == topic) return channel.message_count;
  }
  return 0;
}

// Skeleton messages on `sensor_id`'s skeleton channel.
uint64_t SkeletonCount(const TakeReader& take, const std::string& sensor_id) {
  return ChannelCount(take, SensorTopic(sensor_id, "skeleton"));
}

uint64_t ColorCount(const TakeReader& take, const std::string& sensor_id) {
  return ChannelCount(take, SensorTopic(sensor_id, "color"));
}

// The sensor can give the learner: stored skeletons, or depth to track.
bool HasLearner(const TakeReader& take, const std::string& sensor_id) {
  return SkeletonCount(take, sensor_id) > 0 ||
         ChannelCount(take, SensorTopic(sensor_id, "depth")) > 0;
}

std::string SensorList(const TakeReader& take) {
  std::vector<std::string> ids;
  for (const auto& [id, calibration] : take.sensors()) ids.push_back(id);
  return ids.empty() ? "none" : absl::StrJoin(ids, ", ");
}

// The sensor to follow: `wanted`, or the first with skeletons, or else the
// first with depth.
absl::StatusOr<std::string> ChooseSensor(const TakeReader& take, const std::string& path,
                                         const std::string& wanted) {
  if (!wanted.empty()) {
    if (take.sensors().count(wanted) == 0) {
      return absl::NotFoundError(absl::StrCat("learner take ", path, " has no sensor '", wanted,
                                              "' (sensors: ", SensorList(take), ")"));
    }
    if (!HasLearner(take, wanted)) {
      return absl::FailedPreconditionError(
          absl::StrCat("sensor ", wanted, " of learner take ", path,
                       " has neither skeletons nor depth: the mirror needs the tracked learner"));
    }
    return wanted;
  }
  for (const auto& [id, calibration] : take.sensors()) {
    if (SkeletonCount(take, id) > 0) return id;
  }
  for (const auto& [id, calibration] : take.sensors()) {
    if (HasLearner(take, id)) return id;
  }
  return absl::FailedPreconditionError(absl::StrCat(
      "learner take ", path, " has neither skeletons nor depth on any sensor (sensors: ",
      SensorList(take), "): the mirror needs the tracked learner"));
}

class TakeLearnerSource : public LearnerSource {
 public:
  static absl::StatusOr<std::unique_ptr<LearnerSource>> Open(const std::string& path,
                                                             const std::string& sensor_id);
  ~TakeLearnerSource() override {
    queue_.Cancel();
    if (thread_.joinable()) thread_.join();
  }

  const LearnerSensor& sensor() const override { return sensor_; }
  absl::StatusOr<std::optional<LearnerFrame>> Next() override { return queue_.Pop(); }
  std::string Describe() const override {
    return absl::StrCat("take ", path_, ", sensor ", sensor_.sensor_id,
                        tracked_ ? " (tracked from its depth)" : "");
  }

 private:
  TakeLearnerSource() = default;
  absl::Status ReadSkeletons();
  std::optional<LearnerSkeleton> SkeletonNear(int64_t stamp_ns) const;
  bool Push(int64_t stamp_ns, std::optional<RgbImage> color);
  absl::Status ProduceFromColor();
  absl::Status ProduceFromSkeletons();
  void Produce();

  std::string path_;
  std::unique_ptr<TakeReader> reader_;
  LearnerSensor sensor_;
  int64_t clock_offset_ns_ = 0;
  Rigid3d color_from_depth_;
  bool has_color_ = false;
  // The take stores no skeletons: the learner was tracked from its depth.
  bool tracked_ = false;
  // The learner per exposure stamp (nullopt: skeletons without a usable joint).
  std::map<int64_t, std::optional<LearnerSkeleton>> skeletons_;
  int64_t last_stamp_ns_ = std::numeric_limits<int64_t>::min();
  LearnerQueue queue_{kFramesAhead, LearnerQueue::WhenFull::kWait};
  std::thread thread_;
};

absl::StatusOr<std::unique_ptr<LearnerSource>> TakeLearnerSource::Open(
    const std::string& path, const std::string& sensor_id) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return absl::NotFoundError(absl::StrCat("learner take ", path, " does not exist"));
  }
  std::unique_ptr<TakeLearnerSource> source(new TakeLearnerSource());
  source->path_ = path;
  ASSIGN_OR_RETURN(source->reader_, TakeReader::Open(path));
  ASSIGN_OR_RETURN(const std::string id, ChooseSensor(*source->reader_, path, sensor_id));
  const v1::SensorCalibration& calibration = source->reader_->sensors().at(id);
  ASSIGN_OR_RETURN(source->sensor_, LearnerSensorFromCalibration(calibration));
  source->sensor_.sensor_id = id;
  source->clock_offset_ns_ = calibration.clock_offset_ns();
  ASSIGN_OR_RETURN(source->color_from_depth_, LearnerColorFromDepth(calibration));
  source->has_color_ = ColorCount(*source->reader_, id) > 0;
  RETURN_IF_ERROR(source->ReadSkeletons());
  TakeLearnerSource* raw = source.get();
  source->thread_ = std::thread([raw] { raw->Produce(); });
  return std::unique_ptr<LearnerSource>(std::move(source));
}

absl::Status TakeLearnerSource::ReadSkeletons() {
  std::map<int64_t, std::vector<v1::Skeleton>> by_stamp;
  const auto add = [&](const v1::Skeleton& skeleton) {
    by_stamp[ExposureStampNs(skeleton.device_stamp_ns(), skeleton.host_stamp_ns(),
                             clock_offset_ns_)]
        .push_back(skeleton);
  };
  if (SkeletonCount(*reader_, sensor_.sensor_id) > 0) {
    RETURN_IF_ERROR(reader_->ForEach<v1::Skeleton>(SensorTopic(sensor_.sensor_id, "skeleton"),
                                                   [&](const v1::Skeleton& skeleton) {
                                                     add(skeleton);
                                                     return absl::OkStatus();
                                                   }));
  } else {
    // A recording without skeletons (a sensor that gives none, recorded
    // without reenactd's tracker): tracked here as reenactd would.
    tracked_ = true;
    absl::StatusOr<std::map<int64_t, std::vector<v1::Skeleton>>> tracked =
        tracking::TrackTakeSensor(*reader_, sensor_.sensor_id);
    if (!tracked.ok()) {
      return absl::Status(tracked.status().code(),
                          absl::StrCat("learner take ", path_, ": ", tracked.status().message()));
    }
    for (const auto& [frame, skeletons] : *tracked) {
      for (const v1::Skeleton& skeleton : skeletons) add(skeleton);
    }
  }
  for (const auto& [stamp_ns, bodies] : by_stamp) {
    std::vector<const v1::Skeleton*> pointers;
    for (const v1::Skeleton& skeleton : bodies) pointers.push_back(&skeleton);
    skeletons_[stamp_ns] = ChooseLearnerSkeleton(pointers, color_from_depth_);
  }
  return absl::OkStatus();
}

std::optional<LearnerSkeleton> TakeLearnerSource::SkeletonNear(int64_t stamp_ns) const {
  const int64_t tolerance_ns = static_cast<int64_t>(0.5e9 / sensor_.nominal_fps);
  auto after = skeletons_.lower_bound(stamp_ns);
  auto best = skeletons_.end();
  if (after != skeletons_.end()) best = after;
  if (after != skeletons_.begin()) {
    auto before = std::prev(after);
    if (best == skeletons_.end() || stamp_ns - before->first < best->first - stamp_ns) {
      best = before;
    }
  }
  if (best == skeletons_.end() || std::abs(best->first - stamp_ns) > tolerance_ns) {
    return std::nullopt;
  }
  return best->second;
}

bool TakeLearnerSource::Push(int64_t stamp_ns, std::optional<RgbImage> color) {
  LearnerFrame frame;
  // Stamps never go back, even where chunk order and exposure order differ.
  frame.stamp_ns = std::max(stamp_ns, last_stamp_ns_);
  last_stamp_ns_ = frame.stamp_ns;
  if (std::optional<LearnerSkeleton> learner = SkeletonNear(stamp_ns)) {
    frame.skeleton_in_color = learner->pose;
    frame.joint_seen = learner->seen;
    frame.people_in_view = learner->people;
  }
  frame.color = std::move(color);
  return queue_.Push(std::move(frame));
}

absl::Status TakeLearnerSource::ProduceFromColor() {
  return reader_->ForEach<v1::ColorImage>(
      SensorTopic(sensor_.sensor_id, "color"), [&](const v1::ColorImage& image) -> absl::Status {
        std::optional<RgbImage> color;
        if (image.encoding().empty() || image.encoding() == "jpeg") {
          absl::StatusOr<RgbImage> decoded = DecodeJpeg(image.data());
          if (decoded.ok()) color = *std::move(decoded);  // Else: a frame without colour.
        }
        const int64_t stamp_ns =
            ExposureStampNs(image.device_stamp_ns(), image.host_stamp_ns(), clock_offset_ns_);
        if (!Push(stamp_ns, std::move(color))) return absl::CancelledError("stopped");
        return absl::OkStatus();
      });
}

absl::Status TakeLearnerSource::ProduceFromSkeletons() {
  for (const auto& [stamp_ns, skeleton] : skeletons_) {
    if (!Push(stamp_ns, std::nullopt)) return absl::CancelledError("stopped");
  }
  return absl::OkStatus();
}

void TakeLearnerSource::Produce() {
  absl::Status status = has_color_ ? ProduceFromColor() : ProduceFromSkeletons();
  if (status.code() == absl::StatusCode::kCancelled) status = absl::OkStatus();
  queue_.Close(status);
}

}  // namespace

absl::StatusOr<std::unique_ptr<LearnerSource>> OpenTakeLearner(const std::string& path,
                                                               const std::string& sensor_id) {
  return TakeLearnerSource::Open(path, sensor_id);
}

}  // namespace reenact::mirror
