#include "capture_daemon/processing/frame_processor.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/geometry/camera.h"
#include "common/geometry/registration.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"

namespace reenact::capture {

absl::Status ProcessingOptions::Validate() const {
  if (!(background_seconds >= 0 && background_seconds <= 600)) {
    return absl::InvalidArgumentError("background_seconds must be in [0, 600]");
  }
  if (jpeg_quality < 1 || jpeg_quality > 100) {
    return absl::InvalidArgumentError("jpeg_quality must be in 1..100");
  }
  if (depth_encoding != "rvl" && depth_encoding != "rvl+zstd") {
    return absl::InvalidArgumentError(
        absl::StrCat("depth_encoding must be 'rvl' or 'rvl+zstd', got '", depth_encoding, "'"));
  }
  if ((registered_width_px == 0) != (registered_height_px == 0) || registered_width_px < 0 ||
      registered_height_px < 0 || registered_width_px > 8192 || registered_height_px > 8192) {
    return absl::InvalidArgumentError(
        "registered_width_px and registered_height_px must both be 0 or both in 1..8192");
  }
  SegmenterOptions tuning = segmentation_tuning;
  tuning.background_seconds = background_seconds;
  if (absl::Status s = tuning.Validate(); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("segmentation_tuning: ", s.message()));
  }
  if (absl::Status s = tracker.Validate(); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("tracker: ", s.message()));
  }
  return absl::OkStatus();
}

namespace {

template <typename Message>
void SetStamps(const v1::Frame& frame, Message* m) {
  m->set_sensor_id(frame.sensor_id());
  m->set_device_stamp_ns(frame.device_stamp_ns());
  m->set_host_stamp_ns(frame.host_stamp_ns());
  m->set_frame_index(frame.frame_index());
}

std::optional<CameraIntrinsics> ValidIntrinsics(const v1::SensorCalibration& c, bool color) {
  const v1::CameraIntrinsics& proto = color ? c.color_intrinsics() : c.depth_intrinsics();
  if (proto.width_px() <= 0) return std::nullopt;
  auto k = FromProto(proto);
  if (!k.ok() || !k->Validate().ok()) return std::nullopt;
  return *k;
}

// The automatic registered grid: the colour size divided by the smallest
// integer that brings its width to max(640, depth width) or less.
std::pair<int, int> AutoRegisteredSize(const CameraIntrinsics& depth,
                                       const CameraIntrinsics& color) {
  const int limit = std::max(640, depth.width);
  const int factor = std::max(1, (color.width + limit - 1) / limit);
  return {color.width / factor, color.height / factor};
}

class FrameProcessorImpl : public FrameProcessor {
 public:
  FrameProcessorImpl(const v1::SensorInfo& info, const ProcessingOptions& options)
      : info_(info), options_(options), calibration_(info.calibration()) {
    if (calibration_.sensor_id().empty()) calibration_.set_sensor_id(info.sensor_id());
  }

  absl::Status Init() {
    depth_k_ = ValidIntrinsics(info_.calibration(), false);
    const std::optional<CameraIntrinsics> color_k = ValidIntrinsics(info_.calibration(), true);
    using Mode = ProcessingOptions::Mode;
    const bool wants_registration = options_.registration != Mode::kOff &&
                                    !info_.provides_registration() && info_.backend() != "playback";
    if (wants_registration) {
      if (!depth_k_ || !color_k) {
        if (options_.registration == Mode::kOn) {
          return absl::InvalidArgumentError(absl::StrCat(
              info_.sensor_id(), ": registration is on but the calibration lacks valid ",
              depth_k_ ? "colour" : "depth", " intrinsics"));
        }
      } else {
        RETURN_IF_ERROR(InitRegistration(*depth_k_, *color_k));
      }
    }
    if (options_.segmentation != Mode::kOff) {
      if (!depth_k_) {
        if (options_.segmentation == Mode::kOn) {
          return absl::InvalidArgumentError(absl::StrCat(
              info_.sensor_id(),
              ": segmentation is on but the calibration lacks valid depth intrinsics"));
        }
      } else {
        SegmenterOptions tuning = options_.segmentation_tuning;
        tuning.background_seconds = options_.background_seconds;
        tuning.noise_model = info_.model().empty() ? calibration_.model() : info_.model();
        auto world_from_depth = FromProto(calibration_.world_from_depth());
        ASSIGN_OR_RETURN(
            ActorSegmenter segmenter,
            ActorSegmenter::Create(*depth_k_, world_from_depth.value_or(Rigid3d()), tuning));
        segmenter_.emplace(std::move(segmenter));
      }
    }
    return InitTracker();
  }

  absl::Status Process(CapturedFrame& frame) override {
    const int64_t begin_ns = SteadyNowNs();
    v1::Frame& f = frame.frame;
    if (f.sensor_id().empty()) f.set_sensor_id(info_.sensor_id());
    if (f.sensor_id() != info_.sensor_id()) {
      return absl::InvalidArgumentError(absl::StrCat("frame of sensor '", f.sensor_id(),
                                                     "' given to the processor of '",
                                                     info_.sensor_id(), "'"));
    }
    std::optional<DepthImageMm> depth_for_mask;
    if (frame.depth_mm.has_value()) {
      ASSIGN_OR_RETURN(depth_for_mask, ProcessRaw(frame));
    } else {
      RETURN_IF_ERROR(CheckEncoded(frame));
    }
    std::optional<MaskImage> mask;
    RETURN_IF_ERROR(MaybeSegment(frame, depth_for_mask, mask));
    RETURN_IF_ERROR(MaybeTrack(frame, depth_for_mask, mask));
    frame.depth_mm.reset();
    frame.color.reset();
    const double ms = (SteadyNowNs() - begin_ns) * 1e-6;
    ++stats_.frames;
    stats_.total_ms += ms;
    stats_.max_ms = std::max(stats_.max_ms, ms);
    return absl::OkStatus();
  }

  const v1::SensorCalibration& calibration() const override { return calibration_; }

  ProcessingStats stats() const override {
    ProcessingStats s = stats_;
    s.background_ready = segmenter_.has_value() && segmenter_->background_ready();
    s.floor_found = segmenter_.has_value() && segmenter_->floor().has_value();
    return s;
  }

 private:
  absl::Status InitRegistration(const CameraIntrinsics& depth_k, const CameraIntrinsics& color_k) {
    auto color_from_depth = FromProto(calibration_.color_from_depth());
    if (!color_from_depth.ok()) return color_from_depth.status();
    RegistrationOptions reg_options;
    if (options_.registered_width_px > 0) {
      reg_options.color_width = options_.registered_width_px;
      reg_options.color_height = options_.registered_height_px;
    } else {
      std::tie(reg_options.color_width, reg_options.color_height) =
          AutoRegisteredSize(depth_k, color_k);
    }
    ASSIGN_OR_RETURN(
        DepthToColorRegistration registration,
        DepthToColorRegistration::Create(depth_k, color_k, *color_from_depth, reg_options));
    registration_.emplace(std::move(registration));
    raw_depth_k_ = depth_k;
    // The registered depth camera is the colour camera at the output size.
    depth_k_ = registration_->output_intrinsics();
    *calibration_.mutable_depth_intrinsics() = ToProto(*depth_k_);
    auto world_from_depth = FromProto(calibration_.world_from_depth());
    const Rigid3d world_from_color =
        world_from_depth.value_or(Rigid3d()) * color_from_depth->Inverse();
    *calibration_.mutable_world_from_depth() = ToProto(world_from_color);
    *calibration_.mutable_color_from_depth() = ToProto(Rigid3d());
    return absl::OkStatus();
  }

  // Registers and encodes a raw frame; returns the depth that the mask must
  // follow.
  absl::StatusOr<DepthImageMm> ProcessRaw(CapturedFrame& frame) {
    v1::Frame& f = frame.frame;
    DepthImageMm& depth = *frame.depth_mm;
    if (depth.data.size() != depth.num_pixels() || depth.width <= 0) {
      return absl::InvalidArgumentError(absl::StrCat(info_.sensor_id(), ": raw depth holds ",
                                                     depth.data.size(), " values for ", depth.width,
                                                     "x", depth.height, " px"));
    }
    const CameraIntrinsics* expected =
        registration_ ? &raw_depth_k_ : (depth_k_ ? &*depth_k_ : nullptr);
    if (expected != nullptr &&
        (depth.width != expected->width || depth.height != expected->height)) {
      return absl::InvalidArgumentError(
          absl::StrCat(info_.sensor_id(), ": depth frame of ", depth.width, "x", depth.height,
                       " px; the calibration says ", expected->width, "x", expected->height));
    }
    DepthImageMm out_depth;
    if (registration_) {
      ASSIGN_OR_RETURN(out_depth, registration_->Register(depth));
      ++stats_.registered;
    } else {
      out_depth = std::move(depth);
    }
    DepthCodecOptions codec;
    codec.zstd = options_.depth_encoding == "rvl+zstd";
    ASSIGN_OR_RETURN(std::string depth_bytes, EncodeDepth(out_depth, codec));
    v1::DepthImage* d = f.mutable_depth();
    SetStamps(f, d);
    d->set_width_px(out_depth.width);
    d->set_height_px(out_depth.height);
    d->set_encoding(options_.depth_encoding);
    d->set_data(std::move(depth_bytes));

    if (frame.color.has_value()) {
      const RgbImage& color = *frame.color;
      if (color.data.size() != color.num_pixels() * 3 || color.width <= 0) {
        return absl::InvalidArgumentError(absl::StrCat(info_.sensor_id(), ": raw colour holds ",
                                                       color.data.size(), " bytes for ",
                                                       color.width, "x", color.height, " px"));
      }
      if (info_.color_width_px() > 0 &&
          (color.width != info_.color_width_px() || color.height != info_.color_height_px())) {
        return absl::InvalidArgumentError(absl::StrCat(
            info_.sensor_id(), ": colour frame of ", color.width, "x", color.height,
            " px; the sensor delivers ", info_.color_width_px(), "x", info_.color_height_px()));
      }
      ASSIGN_OR_RETURN(std::string jpeg, EncodeJpeg(color, options_.jpeg_quality));
      v1::ColorImage* c = f.mutable_color();
      SetStamps(f, c);
      c->set_width_px(color.width);
      c->set_height_px(color.height);
      c->set_encoding("jpeg");
      c->set_quality(options_.jpeg_quality);
      c->set_data(std::move(jpeg));
    }
    return out_depth;
  }

  absl::Status CheckEncoded(const CapturedFrame& frame) const {
    if (frame.color.has_value()) {
      return absl::InvalidArgumentError(
          absl::StrCat(info_.sensor_id(), ": raw colour without raw depth"));
    }
    if (!frame.frame.has_depth() || frame.frame.depth().data().empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(info_.sensor_id(), ": frame ", frame.frame.frame_index(), " has no depth"));
    }
    if (registration_) {
      return absl::InvalidArgumentError(absl::StrCat(
          info_.sensor_id(), ": encoded frame from a sensor whose raw frames are registered"));
    }
    return absl::OkStatus();
  }

  // Decodes the frame's depth into `depth` unless it holds it already.
  absl::Status EnsureDepth(const v1::Frame& f, std::optional<DepthImageMm>& depth) const {
    if (depth) return absl::OkStatus();
    auto decoded = DecodeDepth(f.depth().data());
    if (!decoded.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(info_.sensor_id(), ": frame ", f.frame_index(),
                                                     ": ", decoded.status().message()));
    }
    depth = *std::move(decoded);
    return absl::OkStatus();
  }

  // Segments the actor when the policy says so; `mask_out` receives the mask
  // it made.
  absl::Status MaybeSegment(CapturedFrame& frame, std::optional<DepthImageMm>& depth,
                            std::optional<MaskImage>& mask_out) {
    using Mode = ProcessingOptions::Mode;
    if (!segmenter_) return absl::OkStatus();
    v1::Frame& f = frame.frame;
    const bool has_mask = f.has_mask() && !f.mask().data().empty();
    if (options_.segmentation == Mode::kAuto && has_mask) return absl::OkStatus();
    RETURN_IF_ERROR(EnsureDepth(f, depth));
    auto mask = segmenter_->Segment(*depth, f.host_stamp_ns());
    if (!mask.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(info_.sensor_id(), ": frame ", f.frame_index(),
                                                     ": ", mask.status().message()));
    }
    v1::ActorMask* m = f.mutable_mask();
    SetStamps(f, m);
    m->set_width_px(mask->width);
    m->set_height_px(mask->height);
    m->set_encoding("rle");
    m->set_data(EncodeMaskRle(*mask));
    ++stats_.segmented;
    if (std::any_of(mask->data.begin(), mask->data.end(), [](uint8_t v) { return v != 0; })) {
      mask_out = *std::move(mask);
    }
    return absl::OkStatus();
  }

  absl::Status InitTracker() {
    using Mode = ProcessingOptions::Mode;
    if (options_.tracking == Mode::kOff) return absl::OkStatus();
    if (options_.tracking == Mode::kAuto && info_.provides_skeleton()) return absl::OkStatus();
    if (!depth_k_) {
      if (options_.tracking == Mode::kOn) {
        return absl::InvalidArgumentError(
            absl::StrCat(info_.sensor_id(),
                         ": tracking is on but the calibration lacks valid depth intrinsics"));
      }
      return absl::OkStatus();
    }
    auto tracker = tracking::BodyTracker::Create(options_.tracker);
    if (!tracker.ok()) {
      return absl::Status(
          tracker.status().code(),
          absl::StrCat(info_.sensor_id(), ": body tracker: ", tracker.status().message()));
    }
    tracker_ = *std::move(tracker);
    return absl::OkStatus();
  }

  // Tracks the people of the frame when the policy says so.
  absl::Status MaybeTrack(CapturedFrame& frame, std::optional<DepthImageMm>& depth,
                          std::optional<MaskImage>& mask) {
    using Mode = ProcessingOptions::Mode;
    if (!tracker_) return absl::OkStatus();
    v1::Frame& f = frame.frame;
    if (options_.tracking == Mode::kAuto && f.skeletons_size() > 0) return absl::OkStatus();
    RETURN_IF_ERROR(EnsureDepth(f, depth));
    if (depth->width != depth_k_->width || depth->height != depth_k_->height) {
      return absl::InvalidArgumentError(absl::StrCat(
          info_.sensor_id(), ": frame ", f.frame_index(), ": depth of ", depth->width, "x",
          depth->height, " px; the calibration says ", depth_k_->width, "x", depth_k_->height));
    }
    if (!mask && f.has_mask() && !f.mask().data().empty()) {
      // The source's own mask (or one segmented before this processor).
      auto decoded = DecodeMask(f.mask().encoding(), f.mask().data());
      if (decoded.ok() && decoded->width == depth->width && decoded->height == depth->height) {
        mask = *std::move(decoded);
      }
    }
    const int64_t begin_ns = SteadyNowNs();
    // Without a mask the tracker segments the people itself; that
    // segmentation becomes the frame's mask, so the methods downstream see
    // the people apart from the floor and the room (as with a device's
    // body index image).
    MaskImage own_labels;
    const bool segments_itself = !mask.has_value();
    auto people = tracker_->Track(*depth, *depth_k_, mask ? &*mask : nullptr,
                                  segments_itself ? &own_labels : nullptr);
    stats_.tracking_ms += (SteadyNowNs() - begin_ns) * 1e-6;
    if (!people.ok()) {
      // The frame still streams, with no skeleton (as a frame with nobody).
      ++stats_.tracking_errors;
      stats_.last_tracking_error = std::string(people.status().message());
      if (options_.tracking == Mode::kOn) f.clear_skeletons();
      return absl::OkStatus();
    }
    ++stats_.tracked;
    if (segments_itself && !people->empty() && own_labels.width == depth->width &&
        own_labels.height == depth->height) {
      v1::ActorMask* m = f.mutable_mask();
      SetStamps(f, m);
      m->set_width_px(own_labels.width);
      m->set_height_px(own_labels.height);
      m->set_encoding("rle");
      m->set_data(EncodeMaskRle(own_labels));
      ++stats_.tracker_masks;
    }
    f.clear_skeletons();
    for (const tracking::TrackedPerson& person : *people) {
      v1::Skeleton* skeleton = f.add_skeletons();
      *skeleton = tracking::TrackedPersonToProto(person);
      SetStamps(f, skeleton);
      ++stats_.tracked_people;
    }
    return absl::OkStatus();
  }

  v1::SensorInfo info_;
  ProcessingOptions options_;
  v1::SensorCalibration calibration_;
  std::optional<CameraIntrinsics> depth_k_;  // Of the output depth.
  CameraIntrinsics raw_depth_k_;             // Of the raw depth, when registering.
  std::optional<DepthToColorRegistration> registration_;
  std::optional<ActorSegmenter> segmenter_;
  std::unique_ptr<tracking::BodyTracker> tracker_;
  ProcessingStats stats_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<FrameProcessor>> FrameProcessor::Create(
    const v1::SensorInfo& info, const ProcessingOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (info.sensor_id().empty()) return absl::InvalidArgumentError("SensorInfo has no sensor_id");
  auto processor = std::make_unique<FrameProcessorImpl>(info, options);
  RETURN_IF_ERROR(processor->Init());
  return processor;
}

}  // namespace reenact::capture
