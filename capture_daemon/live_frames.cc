#include "capture_daemon/live_frames.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "common/base/image.h"
#include "common/io/jpeg.h"

namespace reenact::capture {
namespace {

constexpr int kDefaultColourWidthPx = 640;
constexpr int kDefaultJpegQuality = 80;

bool Contains(const google::protobuf::RepeatedPtrField<std::string>& ids, const std::string& id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

// Averages `factor` x `factor` blocks (the image's right and bottom
// remainders are dropped).
RgbImage Shrink(const RgbImage& image, int factor) {
  RgbImage out(image.width / factor, image.height / factor);
  const int area = factor * factor;
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int dy = 0; dy < factor; ++dy) {
          for (int dx = 0; dx < factor; ++dx) sum += image.at(factor * x + dx, factor * y + dy, c);
        }
        out.at(x, y, c) = static_cast<uint8_t>((sum + area / 2) / area);
      }
    }
  }
  return out;
}

// The colour image shrunk as `request` asks; false when it does not decode.
bool ShrinkColour(const v1::ColorImage& colour, const v1::StreamFramesRequest& request,
                  v1::ColorImage* out) {
  const int max_width =
      request.color_max_width_px() > 0 ? request.color_max_width_px() : kDefaultColourWidthPx;
  const int quality =
      request.color_jpeg_quality() > 0 ? request.color_jpeg_quality() : kDefaultJpegQuality;
  const int factor = std::max(1, (colour.width_px() + max_width - 1) / max_width);
  *out = colour;
  if (factor == 1) return true;
  absl::StatusOr<RgbImage> image = DecodeJpeg(colour.data());
  if (!image.ok()) return false;
  const RgbImage small = Shrink(*image, factor);
  absl::StatusOr<std::string> jpeg = EncodeJpeg(small, quality);
  if (!jpeg.ok()) return false;
  out->set_width_px(small.width);
  out->set_height_px(small.height);
  out->set_quality(quality);
  out->set_data(std::move(*jpeg));
  return true;
}

}  // namespace

v1::LiveFrameSet MakeLiveFrameSet(const v1::FrameSet& set, uint64_t index,
                                  const v1::StreamFramesRequest& request) {
  v1::LiveFrameSet live;
  live.set_stamp_ns(set.stamp_ns());
  live.set_set_index(index);
  for (const v1::Frame& frame : set.frames()) {
    if (request.sensor_ids().empty() || Contains(request.sensor_ids(), frame.sensor_id())) {
      for (const v1::Skeleton& skeleton : frame.skeletons()) *live.add_skeletons() = skeleton;
    }
    if (frame.has_color() && Contains(request.color_sensor_ids(), frame.sensor_id())) {
      v1::ColorImage shrunk;
      if (ShrinkColour(frame.color(), request, &shrunk)) *live.add_colors() = std::move(shrunk);
    }
  }
  return live;
}

LiveFrames::LiveFrames() {
  worker_ = std::thread([this] { Work(); });
}

LiveFrames::~LiveFrames() { Close(); }

uint64_t LiveFrames::Subscribe(const v1::StreamFramesRequest& request, Callback callback) {
  std::lock_guard<std::mutex> subscribers_lock(subscribers_mutex_);
  const uint64_t id = next_id_++;
  subscribers_[id] = Subscriber{request, std::move(callback)};
  std::lock_guard<std::mutex> lock(mutex_);
  for (const std::string& sensor_id : request.color_sensor_ids()) colour_wanted_.insert(sensor_id);
  ++subscriber_count_;
  return id;
}

void LiveFrames::Unsubscribe(uint64_t id) {
  std::lock_guard<std::mutex> subscribers_lock(subscribers_mutex_);
  if (subscribers_.erase(id) == 0) return;
  std::set<std::string> wanted;
  for (const auto& [other, subscriber] : subscribers_) {
    wanted.insert(subscriber.request.color_sensor_ids().begin(),
                  subscriber.request.color_sensor_ids().end());
  }
  std::lock_guard<std::mutex> lock(mutex_);
  colour_wanted_ = std::move(wanted);
  --subscriber_count_;
}

void LiveFrames::Publish(const v1::FrameSet& set) {
  if (subscriber_count_ == 0) return;
  auto published = std::make_unique<Published>();
  published->set.set_stamp_ns(set.stamp_ns());
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return;
  for (const v1::Frame& frame : set.frames()) {
    v1::Frame* light = published->set.add_frames();
    light->set_sensor_id(frame.sensor_id());
    *light->mutable_skeletons() = frame.skeletons();
    if (frame.has_color() && colour_wanted_.count(frame.sensor_id())) {
      *light->mutable_color() = frame.color();
    }
  }
  published->index = ++published_;
  newest_ = std::move(published);  // An older set not yet taken is dropped.
  cv_.notify_all();
}

void LiveFrames::Close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    closed_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  std::lock_guard<std::mutex> subscribers_lock(subscribers_mutex_);
  for (auto& [id, subscriber] : subscribers_) subscriber.callback(nullptr);
  subscribers_.clear();
  subscriber_count_ = 0;
}

void LiveFrames::Work() {
  while (true) {
    std::unique_ptr<Published> published;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return closed_ || newest_ != nullptr; });
      if (closed_) return;
      published = std::move(newest_);
    }
    Deliver(*published);
  }
}

void LiveFrames::Deliver(const Published& published) {
  std::lock_guard<std::mutex> subscribers_lock(subscribers_mutex_);
  for (const auto& [id, subscriber] : subscribers_) {
    subscriber.callback(std::make_shared<const v1::LiveFrameSet>(
        MakeLiveFrameSet(published.set, published.index, subscriber.request)));
  }
}

}  // namespace reenact::capture
