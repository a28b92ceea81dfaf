#include "common/io/take_selection.h"

#include <algorithm>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact {
namespace {

// [first, end) runs of frame indices, sorted and merged.
class FrameSet {
 public:
  void Add(int64_t first, int64_t end) {
    if (end > first) runs_.emplace_back(first, end);
  }
  void Finish() {
    std::sort(runs_.begin(), runs_.end());
    std::vector<std::pair<int64_t, int64_t>> merged;
    for (const auto& run : runs_) {
      if (!merged.empty() && run.first <= merged.back().second) {
        merged.back().second = std::max(merged.back().second, run.second);
      } else {
        merged.push_back(run);
      }
    }
    runs_ = std::move(merged);
  }
  bool Contains(int64_t frame) const {
    auto it = std::upper_bound(runs_.begin(), runs_.end(), frame,
                               [](int64_t f, const auto& run) { return f < run.first; });
    return it != runs_.begin() && frame < std::prev(it)->second;
  }

 private:
  std::vector<std::pair<int64_t, int64_t>> runs_;
};

enum class Stream { kDepth, kMask, kColor, kSkeleton, kFrameSet, kSensorLost };

struct Route {
  Stream stream;
  const FrameSet* frames = nullptr;  // Images: those whose bytes are kept.
  const char* type = "";
};

}  // namespace

absl::Status ValidateTakeSelection(const TakeReader& take, const v1::TakeSelection& selection) {
  if (selection.depth_size() + selection.color_size() > kMaxSelectionRanges) {
    return absl::InvalidArgumentError(
        absl::StrCat("a take selection holds at most ", kMaxSelectionRanges, " frame ranges"));
  }
  for (const auto* ranges : {&selection.depth(), &selection.color()}) {
    for (const v1::FrameRange& range : *ranges) {
      if (!take.sensors().contains(range.sensor_id())) {
        return absl::InvalidArgumentError(
            absl::StrCat("the take has no sensor \"", range.sensor_id().substr(0, 64), "\""));
      }
      if (range.first() < 0 || range.end() < range.first()) {
        return absl::InvalidArgumentError(absl::StrCat("frame range [", range.first(), ", ",
                                                       range.end(), ") of sensor ",
                                                       range.sensor_id(), " is not a range"));
      }
    }
  }
  return absl::OkStatus();
}

absl::Status WriteTakeSelection(const TakeReader& take, const v1::TakeSelection& selection,
                                const std::string& path, const std::function<bool()>& cancelled) {
  RETURN_IF_ERROR(ValidateTakeSelection(take, selection));
  std::map<std::string, FrameSet> depth;
  std::map<std::string, FrameSet> color;
  for (const v1::FrameRange& r : selection.depth()) depth[r.sensor_id()].Add(r.first(), r.end());
  for (const v1::FrameRange& r : selection.color()) color[r.sensor_id()].Add(r.first(), r.end());
  std::map<std::string, Route, std::less<>> routes;
  for (const auto& [id, calibration] : take.sensors()) {
    FrameSet& d = depth[id];
    FrameSet& c = color[id];
    d.Finish();
    c.Finish();
    routes[SensorTopic(id, "depth")] = {Stream::kDepth, &d, "reenact.v1.DepthImage"};
    routes[SensorTopic(id, "mask")] = {Stream::kMask, &d, "reenact.v1.ActorMask"};
    routes[SensorTopic(id, "color")] = {Stream::kColor, &c, "reenact.v1.ColorImage"};
    routes[SensorTopic(id, "skeleton")] = {Stream::kSkeleton, nullptr, "reenact.v1.Skeleton"};
  }
  routes[std::string(kIngestFrameSetTopic)] = {Stream::kFrameSet, nullptr,
                                               "reenact.v1.FrameSetRecord"};
  routes[std::string(kIngestSensorLostTopic)] = {Stream::kSensorLost, nullptr,
                                                 "reenact.v1.SensorLostRecord"};

  // The images are JPEG and RVL already: the fastest zstd level does.
  TakeWriterOptions options;
  options.mcap.zstd_level = 1;
  ASSIGN_OR_RETURN(std::unique_ptr<TakeWriter> writer,
                   TakeWriter::Open(path, take.info(), options));
  for (const auto& [id, calibration] : take.sensors()) {
    RETURN_IF_ERROR(writer->AddSensor(calibration));
  }
  const McapReader& mcap = take.mcap();
  std::map<uint16_t, bool> checked;  // Channel id -> schema checked.
  v1::DepthImage depth_image;
  v1::ActorMask mask;
  v1::ColorImage color_image;
  v1::Skeleton skeleton;
  v1::FrameSetRecord frame_set;
  v1::SensorLostRecord lost;
  const auto parse = [&](const McapChannel& channel, const McapMessage& message,
                         google::protobuf::Message* out) -> absl::Status {
    if (!out->ParseFromString(message.data)) {
      return absl::DataLossError(absl::StrCat(mcap.path(), ": message on ", channel.topic,
                                              " at log time ", message.log_time_ns,
                                              " ns does not parse"));
    }
    return absl::OkStatus();
  };
  RETURN_IF_ERROR(mcap.ForEachMessage(
      [&](const McapChannel& channel, const McapMessage& message) -> absl::Status {
        if (cancelled && cancelled())
          return absl::CancelledError("the take selection was cancelled");
        const auto route = routes.find(channel.topic);
        if (route == routes.end()) return absl::OkStatus();
        const Route& r = route->second;
        if (!checked[channel.id]) {
          const auto schema = mcap.schemas().find(channel.schema_id);
          if (schema == mcap.schemas().end() || schema->second.name != r.type) {
            return absl::InvalidArgumentError(
                absl::StrCat(mcap.path(), ": channel ", channel.topic, " does not hold ", r.type));
          }
          checked[channel.id] = true;
        }
        switch (r.stream) {
          case Stream::kDepth:
            RETURN_IF_ERROR(parse(channel, message, &depth_image));
            if (!r.frames->Contains(depth_image.frame_index())) depth_image.clear_data();
            return writer->WriteDepth(depth_image);
          case Stream::kMask:
            RETURN_IF_ERROR(parse(channel, message, &mask));
            if (!r.frames->Contains(mask.frame_index())) mask.clear_data();
            return writer->WriteMask(mask);
          case Stream::kColor:
            RETURN_IF_ERROR(parse(channel, message, &color_image));
            if (!r.frames->Contains(color_image.frame_index())) color_image.clear_data();
            return writer->WriteColor(color_image);
          case Stream::kSkeleton:
            RETURN_IF_ERROR(parse(channel, message, &skeleton));
            return writer->WriteSkeleton(skeleton);
          case Stream::kFrameSet:
            RETURN_IF_ERROR(parse(channel, message, &frame_set));
            return writer->WriteFrameSetRecord(frame_set);
          case Stream::kSensorLost:
            RETURN_IF_ERROR(parse(channel, message, &lost));
            return writer->WriteSensorLost(lost);
        }
        return absl::OkStatus();
      }));
  return writer->Close();
}

}  // namespace reenact
