#include "capture_daemon/board_anchor.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/board/board_detector.h"
#include "common/board/board_spec.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"

namespace reenact::capture {
namespace {

// Detections farther than this from the best one are dropped as outliers.
constexpr double kInlierRotationRad = 2.0 * M_PI / 180.0;
constexpr double kInlierTranslationM = 0.030;

double RotationDistanceRad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b);
}

Rigid3d ToRigid(const Eigen::Isometry3d& transform) {
  return Rigid3d(Eigen::Quaterniond(transform.rotation()).normalized(), transform.translation());
}

}  // namespace

absl::Status AnchorOptions::Validate() const {
  if (!board_spec.empty()) {
    if (absl::StatusOr<board::BoardSpec> spec = board::ParseBoardSpec(board_spec); !spec.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("--anchor: ", spec.status().message()));
    }
  }
  if (frames < 1 || frames > 100) {
    return absl::InvalidArgumentError("anchor frames must be within 1..100");
  }
  if (max_frames < frames) {
    return absl::InvalidArgumentError("anchor max_frames must be at least anchor frames");
  }
  if (!(timeout_s > 0)) return absl::InvalidArgumentError("anchor timeout_s must be positive");
  if (queued_frames < 1 || queued_frames > 100) {
    return absl::InvalidArgumentError("anchor queued_frames must be within 1..100");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> WorldAnchorName(const std::string& board_spec) {
  ASSIGN_OR_RETURN(const board::BoardSpec spec, board::ParseBoardSpec(board_spec));
  return absl::StrCat("board:", board::FormatBoardSpec(spec));
}

absl::StatusOr<v1::SensorCalibration> AnchorCalibration(const v1::SensorCalibration& calibration,
                                                        const AnchorResult& anchor,
                                                        const std::string& world_anchor) {
  Rigid3d colour_from_depth;
  if (calibration.has_color_from_depth()) {
    ASSIGN_OR_RETURN(colour_from_depth, FromProto(calibration.color_from_depth()));
  }
  v1::SensorCalibration anchored = calibration;
  *anchored.mutable_world_from_depth() = ToProto(anchor.board_from_colour * colour_from_depth);
  anchored.set_world_anchor(world_anchor);
  anchored.set_world_anchor_rms_px(anchor.rms_px);
  return anchored;
}

absl::StatusOr<AnchorResult> CombineDetections(
    const std::vector<std::pair<Rigid3d, double>>& detections) {
  if (detections.empty()) return absl::NotFoundError("no detection of the board");
  const auto best =
      std::min_element(detections.begin(), detections.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; });
  const Rigid3d& reference = best->first;
  Eigen::Vector4d quaternion_sum = Eigen::Vector4d::Zero();
  Eigen::Vector3d translation_sum = Eigen::Vector3d::Zero();
  AnchorResult result;
  for (const auto& [board_from_colour, rms_px] : detections) {
    if (RotationDistanceRad(board_from_colour.rotation, reference.rotation) > kInlierRotationRad ||
        (board_from_colour.translation - reference.translation).norm() > kInlierTranslationM) {
      continue;
    }
    Eigen::Vector4d q = board_from_colour.rotation.coeffs();
    if (q.dot(reference.rotation.coeffs()) < 0) q = -q;
    quaternion_sum += q;
    translation_sum += board_from_colour.translation;
    result.rms_px += rms_px;
    ++result.detections;
  }
  const Eigen::Vector4d mean = quaternion_sum.normalized();
  result.board_from_colour = Rigid3d(Eigen::Quaterniond(mean.w(), mean.x(), mean.y(), mean.z()),
                                     translation_sum / result.detections);
  result.rms_px /= result.detections;
  return result;
}

absl::StatusOr<std::unique_ptr<SensorAnchor>> SensorAnchor::Create(
    const AnchorOptions& options, const v1::SensorCalibration& calibration) {
  RETURN_IF_ERROR(options.Validate());
  if (!options.enabled()) return absl::InvalidArgumentError("anchoring needs a board spec");
  absl::StatusOr<CameraIntrinsics> intrinsics = FromProto(calibration.color_intrinsics());
  if (!intrinsics.ok() || !intrinsics->Validate().ok() || intrinsics->width <= 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        calibration.sensor_id(), ": no valid colour intrinsics to find the board with"));
  }
  return std::unique_ptr<SensorAnchor>(new SensorAnchor(options, *intrinsics));
}

SensorAnchor::SensorAnchor(const AnchorOptions& options, const CameraIntrinsics& colour_intrinsics)
    : options_(options), colour_intrinsics_(colour_intrinsics) {
  worker_ = std::thread([this] { Work(); });
}

SensorAnchor::~SensorAnchor() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void SensorAnchor::Offer(const v1::ColorImage& color) {
  if (color.data().empty() || color.encoding() != "jpeg") return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const int in_hand = static_cast<int>(queue_.size()) + (busy_ ? 1 : 0);
    if (stop_ || static_cast<int>(queue_.size()) >= options_.queued_frames || FinishedLocked() ||
        frames_tried_ + in_hand >= options_.max_frames) {
      return;
    }
    queue_.push_back(color.data());
  }
  cv_.notify_all();
}

bool SensorAnchor::finished() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return FinishedLocked();
}

bool SensorAnchor::FinishedLocked() const {
  return frames_tried_ >= options_.max_frames ||
         static_cast<int>(detections_.size()) >= options_.frames;
}

absl::StatusOr<AnchorResult> SensorAnchor::Finish() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  if (detections_.empty()) {
    std::string message =
        absl::StrCat("the board was not found in ", frames_tried_, " colour frames");
    if (!last_error_.empty()) absl::StrAppend(&message, " (", last_error_, ")");
    return absl::NotFoundError(message);
  }
  ASSIGN_OR_RETURN(AnchorResult result, CombineDetections(detections_));
  result.frames_tried = frames_tried_;
  return result;
}

void SensorAnchor::Work() {
  while (true) {
    std::string jpeg;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      // Frames queued before the stop are still searched (while they may
      // still count): Finish waits for them.
      if (queue_.empty() || FinishedLocked()) return;
      jpeg = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
    }
    Detect(jpeg);
    std::lock_guard<std::mutex> lock(mutex_);
    busy_ = false;
  }
}

void SensorAnchor::Detect(const std::string& jpeg) {
  absl::Status error = absl::OkStatus();
  std::optional<std::pair<Rigid3d, double>> found;
  absl::StatusOr<board::BoardSpec> spec = board::ParseBoardSpec(options_.board_spec);
  absl::StatusOr<RgbImage> image = DecodeJpeg(jpeg);
  if (!spec.ok() || !image.ok()) {
    error = spec.ok() ? image.status() : spec.status();
  } else {
    absl::StatusOr<board::BoardDetection> detection =
        board::DetectBoard(*image, colour_intrinsics_, *spec);
    if (detection.ok()) {
      found.emplace(ToRigid(detection->camera_from_board.inverse()),
                    detection->reprojection_rms_px);
    } else {
      error = detection.status();
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_tried_;
  if (found) {
    detections_.push_back(*found);
  } else {
    last_error_ = std::string(error.message());
  }
}

}  // namespace reenact::capture
