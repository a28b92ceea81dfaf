// MP4 export of colour frames through libavformat/libavcodec: H.264
// (libx264) in yuv420p, or MPEG-4 part 2 where libavcodec has no H.264
// encoder. Any player and OpenCV's cv::VideoCapture read the result.
//
// Colour: frames are sRGB; they are converted to limited-range Y'CbCr with
// the BT.601 matrix and tagged so (colorspace smpte170m, primaries bt709,
// transfer iec61966-2-1), which is what decoders that ignore the tags assume.
//
// Logging: libav writes to stderr by default. The first Open installs a log
// callback, process-wide, that prints nothing and keeps the last error of each
// thread, which the returned statuses quote.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact {

// Which encoder Open uses.
enum class VideoCodec {
  kH264OrMpeg4,  // libx264 when available, else the MPEG-4 part 2 encoder.
  kH264,         // libx264 only; Unavailable when absent.
  kMpeg4,        // The MPEG-4 part 2 encoder only.
};

// Options of VideoWriter::Open.
struct VideoWriterOptions {
  VideoCodec codec = VideoCodec::kH264OrMpeg4;
  // H.264 constant rate factor, 0 (lossless) .. 51 (worst); 18 is visually
  // lossless, 23 is libx264's default.
  int crf = 18;
  // libx264 speed/size trade-off: ultrafast, superfast, veryfast, faster,
  // fast, medium, slow, slower, veryslow.
  std::string preset = "medium";
  // MPEG-4 part 2 fixed quantiser, 1 (best) .. 31 (worst).
  int mpeg4_qscale = 2;
  // Frames between key frames; 0 picks one per 2 seconds.
  int keyframe_interval = 0;
  // Move the index to the front when closing, so players can start before the
  // whole file has arrived (one extra pass over the file).
  bool faststart = true;

  // InvalidArgument for values outside the ranges above.
  absl::Status Validate() const;
};

// Writes one video stream to a file. Not thread-safe; one thread at a time.
class VideoWriter {
 public:
  // Creates `path` (container chosen by the extension, MP4 when it has none
  // that libavformat knows) for frames of `width` x `height` pixels at `fps`
  // frames per second. InvalidArgument for odd or non-positive sizes (4:2:0
  // chroma needs even ones), fps outside (0, 1000] or bad options; Unavailable
  // when no requested encoder exists; the file error (e.g. NotFound,
  // PermissionDenied) when `path` cannot be written.
  static absl::StatusOr<std::unique_ptr<VideoWriter>> Open(const std::string& path, int width,
                                                           int height, double fps,
                                                           const VideoWriterOptions& options = {});

  // Closes the file if Close was not called (errors are then lost; call Close
  // to see them).
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  // Encodes the next frame (sRGB, top row first), shown at frames_written() /
  // fps seconds. InvalidArgument when its size differs from Open's;
  // FailedPrecondition after Close; Internal when encoding or writing fails.
  absl::Status Append(const RgbImage& frame);

  // Flushes the encoder, writes the trailer and closes the file. A second
  // call does nothing. Internal when finishing the file fails.
  absl::Status Close();

  // "libx264" or "mpeg4".
  const std::string& codec_name() const;
  int64_t frames_written() const;

 private:
  struct Impl;
  explicit VideoWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact
