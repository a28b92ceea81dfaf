// Readers of RGB-D recordings made by other tools, so that they can become
// takes (`reenact import`) or play as live sensors (`reenactd --source
// azure-mkv:FILE|tum:DIR|oni:FILE`; depth-png folders are imported only). Each recording is one
// sensor; a reader yields its calibration once and then its frames in order: depth in millimetres
// along z (uint16, 0 = no measurement) and the colour frame nearest in time, either as the JPEG
// bytes the recording holds or as RGB pixels.
//
// Formats:
//   azure-mkv  Azure Kinect recordings of k4arecorder (Matroska; see
//              azure_mkv.cc for the track layout and the calibration).
//   tum        TUM RGB-D benchmark folders: rgb.txt and depth.txt list
//              "timestamp filename" lines, depth PNGs are 16-bit with 5000
//              units per metre, colour PNGs 8-bit RGB (tum.cc).
//   oni        OpenNI2 recordings (.oni) through OpenNI2's own file device
//              (oni.cc).
//   depth-png  a folder of 16-bit depth PNGs named in order, with no colour
//              and no timestamps (depth_folder.cc).
//
// Nothing here trusts the file: every size read from it is bounded before
// anything is allocated, and bad input is an error status, never an abort.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact::recordings {

enum class RecordingFormat { kAzureMkv, kTum, kOni, kDepthFolder };

// "azure-mkv", "tum", "oni", "depth-png".
std::string FormatName(RecordingFormat format);
// The inverse; InvalidArgument naming the accepted names otherwise.
absl::StatusOr<RecordingFormat> ParseFormat(const std::string& name);
// From the path: a folder holding depth.txt is TUM, another folder holding
// *.png files (or a frames/ subfolder) a depth-png folder, *.mkv is an Azure
// Kinect recording, *.oni an OpenNI2 one. NotFound when the path does not exist,
// InvalidArgument when it is none of these.
absl::StatusOr<RecordingFormat> DetectFormat(const std::string& path);

// The full lens model of a camera as the recording states it. Azure Kinect
// calibrations use the rational Brown-Conrady model (OpenCV's
// CALIB_RATIONAL_MODEL): with r^2 = x^2 + y^2 in normalised coordinates,
//   radial = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//   x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y.
// With k4 = k5 = k6 = 0 this is the five-coefficient model of
// common/geometry/camera.h.
struct LensModel {
  CameraIntrinsics pinhole;  // Size, fx, fy, cx, cy, k1..k3, p1, p2.
  double k4 = 0.0, k5 = 0.0, k6 = 0.0;
  bool rational() const { return k4 != 0.0 || k5 != 0.0 || k6 != 0.0; }
};

// The five-coefficient model (common/geometry/camera.h, what a take's
// SensorCalibration holds) closest to `lens` over its image: k1..k3 fitted by
// least squares to the radial factor at radii up to the image corner, p1, p2
// and the pinhole kept. `max_error_px` (optional) receives the largest
// distance between the two models' projections over the image.
CameraIntrinsics FitPolynomialLens(const LensModel& lens, double* max_error_px = nullptr);

struct RecordingInfo {
  RecordingFormat format = RecordingFormat::kTum;
  std::string source;  // The path opened.
  // Model and serial of the device when the recording says.
  std::string model;
  std::string serial;
  LensModel depth_lens;
  bool has_color = false;
  LensModel color_lens;  // When has_color.
  // Maps points in the depth camera frame to the colour camera frame, metres.
  Rigid3d color_from_depth;
  // Frames per second the device ran at (0 when unknown).
  double nominal_fps = 0.0;
  // Frames the recording holds, when known without reading it (else -1).
  int64_t frame_count = -1;
  // How the calibration was obtained, one line, for TakeInfo.notes.
  std::string calibration_note;
};

struct RecordedFrame {
  // 0, 1, ... in the order delivered.
  int64_t index = 0;
  // Exposure time of the depth frame on the recording's clock, ns, >= 0.
  int64_t stamp_ns = 0;
  DepthImageMm depth_mm;
  // The colour frame nearest in time, if any: JPEG bytes as recorded
  // (color_jpeg, with its size in color_width/height) or RGB pixels
  // (color_rgb).
  std::string color_jpeg;
  std::optional<RgbImage> color_rgb;
  int color_width = 0, color_height = 0;
  int64_t color_stamp_ns = 0;
  bool has_color() const { return !color_jpeg.empty() || color_rgb.has_value(); }
};

struct RecordingOptions {
  // TUM and depth-png: a calibration file (ReadIntrinsicsFile); TUM has a
  // default, a depth-png folder needs this or its own meta.json.
  std::string intrinsics_path;
  // TUM and depth-png: depth units per metre (0: the format's own, 5000 for
  // TUM, 1000 (millimetres) for depth-png).
  double depth_units_per_m = 0.0;
  // depth-png: frames per second (0: meta.json's "fps_nominal", else 30).
  double fps = 0.0;
  // Largest image a recording may declare, in pixels (both streams).
  uint64_t max_pixels = uint64_t{4096} * 4096;
  // OpenNI2: how long to wait for the file device's next frame.
  double oni_frame_timeout_s = 2.0;
};

class RecordingReader {
 public:
  virtual ~RecordingReader() = default;
  virtual const RecordingInfo& info() const = 0;
  // The next frame, or nullopt at the end of the recording. DataLoss (naming
  // the file and the frame) for a frame that cannot be read.
  virtual absl::StatusOr<std::optional<RecordedFrame>> Next() = 0;
};

// Opens `path` as `format`. NotFound for a missing path, InvalidArgument or
// DataLoss for a file that is not such a recording (the message says what
// was wrong), Unavailable when the reading library fails.
absl::StatusOr<std::unique_ptr<RecordingReader>> OpenRecording(
    const std::string& path, RecordingFormat format, const RecordingOptions& options = {});

// The format readers (each in its own file).
absl::StatusOr<std::unique_ptr<RecordingReader>> OpenAzureMkv(const std::string& path,
                                                              const RecordingOptions& options);
absl::StatusOr<std::unique_ptr<RecordingReader>> OpenTumFolder(const std::string& path,
                                                               const RecordingOptions& options);
absl::StatusOr<std::unique_ptr<RecordingReader>> OpenOni(const std::string& path,
                                                         const RecordingOptions& options);
absl::StatusOr<std::unique_ptr<RecordingReader>> OpenDepthFolder(const std::string& path,
                                                                 const RecordingOptions& options);

// A lens file: the first line that is not empty or a '#' comment holds
// "fx fy cx cy [d0 d1 d2 d3 d4]" (d0..d4 = k1 k2 p1 p2 k3, OpenCV's order, as
// the TUM benchmark's calibration table gives them); or a JSON object whose
// "intrinsics" array holds the same numbers (../shared/data/rgbd-seq's
// meta.json). Width and height are left 0 for the caller.
absl::StatusOr<CameraIntrinsics> ReadIntrinsicsFile(const std::string& path);
// The same from its 4 or 9 numbers (`origin` names them in errors).
absl::StatusOr<CameraIntrinsics> IntrinsicsFromNumbers(const std::vector<double>& values,
                                                       const std::string& origin);

// PNG helpers for depth maps (OpenCV's libpng decoder behind a bound on the
// size the header declares). DecodePng16 reads a 16-bit (or 8-bit) one-channel
// PNG; DecodePngRgb any PNG as 8-bit RGB. DataLoss for a file that does not
// decode or declares more than `max_pixels`.
absl::StatusOr<Image<uint16_t, 1>> DecodePng16(const std::string& bytes, uint64_t max_pixels);
// Depth of `units_per_m` units per metre (> 0) in millimetres, rounded to
// the nearest, 0 kept as no value, saturated at 65535.
DepthImageMm DepthToMillimetres(const Image<uint16_t, 1>& raw, double units_per_m);
absl::StatusOr<RgbImage> DecodePngRgb(const std::string& bytes, uint64_t max_pixels);
// A 16-bit grey PNG of `depth` (values as they are, e.g. millimetres).
absl::StatusOr<std::string> EncodePng16(const DepthImageMm& depth);
// Width and height a PNG's IHDR declares, without decoding. DataLoss when
// `bytes` does not start with a PNG signature and IHDR.
absl::StatusOr<std::pair<int, int>> PngSize(const std::string& bytes);
// Width and height of a JPEG from its header (libturbojpeg). DataLoss when it
// is not a JPEG.
absl::StatusOr<std::pair<int, int>> JpegSize(const std::string& bytes);

}  // namespace reenact::recordings
