#include "capture_daemon/processing/frame_processor.h"

#include "common/io/depth_codec.h"

namespace reenact::capture {

absl::Status ProcessingOptions::Validate() const { return absl::OkStatus(); }

// Placeholder until registration and segmentation land: passes encoded
// frames through.
namespace {
class PassThroughProcessor : public FrameProcessor {
 public:
  explicit PassThroughProcessor(const v1::SensorInfo& info) : calibration_(info.calibration()) {}
  absl::Status Process(CapturedFrame& frame) override {
    if (frame.depth_mm.has_value() || frame.color.has_value()) {
      return absl::UnimplementedError("raw frames need the full FrameProcessor");
    }
    return absl::OkStatus();
  }
  const v1::SensorCalibration& calibration() const override { return calibration_; }

 private:
  v1::SensorCalibration calibration_;
};
}  // namespace

absl::StatusOr<std::unique_ptr<FrameProcessor>> FrameProcessor::Create(
    const v1::SensorInfo& info, const ProcessingOptions& options) {
  return std::make_unique<PassThroughProcessor>(info);
}

}  // namespace reenact::capture
