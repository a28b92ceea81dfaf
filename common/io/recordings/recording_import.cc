#include "common/io/recordings/recording_import.h"

#include <filesystem>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"

namespace reenact::recordings {

v1::SensorCalibration MakeCalibration(const RecordingInfo& info, const std::string& sensor_id,
                                      double* depth_fit_px, double* color_fit_px) {
  v1::SensorCalibration c;
  c.set_sensor_id(sensor_id);
  c.set_model(info.model);
  c.set_serial(info.serial);
  *c.mutable_depth_intrinsics() = ToProto(FitPolynomialLens(info.depth_lens, depth_fit_px));
  if (info.has_color) {
    *c.mutable_color_intrinsics() = ToProto(FitPolynomialLens(info.color_lens, color_fit_px));
  } else if (color_fit_px != nullptr) {
    *color_fit_px = 0.0;
  }
  *c.mutable_color_from_depth() = ToProto(info.color_from_depth);
  *c.mutable_world_from_depth() = ToProto(Rigid3d());
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(info.nominal_fps);
  return c;
}

namespace {

std::string LensText(const char* name, const LensModel& lens) {
  const CameraIntrinsics& k = lens.pinhole;
  return absl::StrCat(name, " ", k.width, "x", k.height, " fx ", k.fx, " fy ", k.fy, " cx ", k.cx,
                      " cy ", k.cy, " k1..k6 ", k.k1, " ", k.k2, " ", k.k3, " ", lens.k4, " ",
                      lens.k5, " ", lens.k6, " p1 ", k.p1, " p2 ", k.p2);
}

absl::StatusOr<ImportReport> WriteTake(RecordingReader& reader, const std::string& out_path,
                                       const ImportOptions& options) {
  const RecordingInfo& info = reader.info();
  ImportReport report;
  report.sensor_id = !options.sensor_id.empty()             ? options.sensor_id
                     : info.format == RecordingFormat::kOni ? "o0"
                                                            : "k0";
  const v1::SensorCalibration calibration_without_offset =
      MakeCalibration(info, report.sensor_id, &report.depth_lens_fit_px, &report.color_lens_fit_px);

  // The first frame fixes the clock offset, which the calibration carries.
  ASSIGN_OR_RETURN(std::optional<RecordedFrame> frame, reader.Next());
  if (!frame) {
    return absl::FailedPreconditionError(
        absl::StrCat(info.source, " holds no complete depth frame (empty or truncated recording)"));
  }
  const int64_t anchor_ns = WallNowNs();
  const int64_t offset_ns = anchor_ns - frame->stamp_ns;
  v1::SensorCalibration calibration = calibration_without_offset;
  calibration.set_clock_offset_ns(offset_ns);

  v1::TakeInfo take_info;
  take_info.set_name(options.take_name.empty() ? std::filesystem::path(out_path).stem().string()
                                               : options.take_name);
  take_info.set_created_unix_ns(anchor_ns);
  take_info.set_generator(absl::StrCat("reenact import (", FormatName(info.format), ")"));
  take_info.set_sensor_count(1);
  take_info.set_fps(info.nominal_fps);
  take_info.set_start_stamp_ns(anchor_ns);
  std::string notes = absl::StrCat("Imported from ", info.source, "; ", info.calibration_note, ". ",
                                   LensText("Depth lens:", info.depth_lens));
  if (info.has_color) absl::StrAppend(&notes, "; ", LensText("colour lens:", info.color_lens));
  if (info.depth_lens.rational() || info.color_lens.rational()) {
    absl::StrAppend(&notes,
                    ". The calibration's five-coefficient distortion is fitted to the rational "
                    "model (largest difference ",
                    std::max(report.depth_lens_fit_px, report.color_lens_fit_px), " px)");
  }
  take_info.set_notes(notes);

  ASSIGN_OR_RETURN(std::unique_ptr<TakeWriter> writer, TakeWriter::Open(out_path, take_info));
  RETURN_IF_ERROR(writer->AddSensor(calibration));
  report.first_stamp_ns = frame->stamp_ns;
  DepthCodecOptions codec;  // RVL + zstd, as the daemon's default.
  while (frame) {
    const int64_t host_ns = frame->stamp_ns + offset_ns;
    v1::DepthImage depth;
    depth.set_sensor_id(report.sensor_id);
    depth.set_device_stamp_ns(frame->stamp_ns);
    depth.set_host_stamp_ns(host_ns);
    depth.set_frame_index(report.frames);
    depth.set_width_px(frame->depth_mm.width);
    depth.set_height_px(frame->depth_mm.height);
    depth.set_encoding(codec.zstd ? "rvl+zstd" : "rvl");
    ASSIGN_OR_RETURN(*depth.mutable_data(), EncodeDepth(frame->depth_mm, codec));
    RETURN_IF_ERROR(writer->WriteDepth(depth));
    if (frame->has_color()) {
      v1::ColorImage color;
      color.set_sensor_id(report.sensor_id);
      // The depth frame's stamps: the two are one capture (as the daemon's
      // frame processor stamps them).
      color.set_device_stamp_ns(frame->stamp_ns);
      color.set_host_stamp_ns(host_ns);
      color.set_frame_index(report.frames);
      color.set_width_px(frame->color_width);
      color.set_height_px(frame->color_height);
      color.set_encoding("jpeg");
      if (!frame->color_jpeg.empty()) {
        color.set_quality(0);  // Unknown: the recording's own JPEG.
        color.set_data(std::move(frame->color_jpeg));
      } else {
        color.set_quality(options.jpeg_quality);
        ASSIGN_OR_RETURN(*color.mutable_data(),
                         EncodeJpeg(*frame->color_rgb, options.jpeg_quality));
      }
      RETURN_IF_ERROR(writer->WriteColor(color));
      ++report.frames_with_color;
    }
    report.last_stamp_ns = frame->stamp_ns;
    ++report.frames;
    if (options.progress) options.progress(report.frames);
    if (options.max_frames > 0 && report.frames >= options.max_frames) break;
    ASSIGN_OR_RETURN(frame, reader.Next());
  }
  RETURN_IF_ERROR(writer->Close());
  return report;
}

}  // namespace

absl::StatusOr<ImportReport> ImportRecording(RecordingReader& reader, const std::string& out_path,
                                             const ImportOptions& options) {
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100) {
    return absl::InvalidArgumentError("JPEG quality must be in 1..100");
  }
  if (options.max_frames < 0) return absl::InvalidArgumentError("max_frames must be >= 0");
  std::error_code ec;
  const bool existed = std::filesystem::exists(out_path, ec);
  absl::StatusOr<ImportReport> report = WriteTake(reader, out_path, options);
  if (!report.ok() && !existed) {
    std::filesystem::remove(out_path, ec);
  }
  return report;
}

}  // namespace reenact::recordings
