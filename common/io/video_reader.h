// Reading of one video stream from bytes held in memory through
// libavformat/libavcodec: the counterpart of VideoWriter (an MP4 with H.264
// or MPEG-4 part 2), though any container and codec libav reads will do.
//
// Memory: the bytes are read in place through a custom I/O context; nothing
// is copied, so they must outlive the reader.
//
// Frame indices: index k is the k-th frame in presentation order. A decoded
// frame's index is its timestamp (best effort pts) less the first frame's,
// in frame durations (1 / fps), rounded to the nearest; so a frame the
// stream lacks is an error rather than a silent shift of the frames after it.
// Open decodes the first frame to learn where the stream starts.
//
// Access: sequential reads continue the decoder. A read of an earlier frame
// seeks to the last key frame at or before it and decodes forward; when the
// container's index lands after the frame (key frames are indexed by decoding
// time, which precedes presentation time), it steps back further, up to the
// start. A later frame is always decoded forward, never sought.
//
// Determinism: the decoder runs on one thread, so the same bytes give the same
// pixels on every machine with the same libav.
//
// Colour: frames come back as sRGB, converted by libswscale from whatever the
// decoder gives with the matrix and range the stream is tagged with; untagged
// streams are taken as BT.601 limited range, which is what VideoWriter writes.
//
// Logging: as VideoWriter's (common/io/av_log.h), libav's log goes to a
// process-wide callback that prints nothing and keeps the last error of each
// thread for the returned statuses.
#pragma once

#include <memory>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact {

// Reads one video stream from bytes held in memory (an MP4 as VideoWriter
// writes it). Not thread-safe; one thread at a time.
class VideoReader {
 public:
  // Opens the best video stream in `bytes`, which must outlive the reader (it
  // is not copied). InvalidArgument for bytes that libavformat cannot parse
  // (most truncated headers among them), that hold no video stream or one
  // without a decoder, size or frame rate, or frames larger than
  // kMaxDecodedImagePixels; DataLoss when the stream has no packets or its
  // first frame does not decode.
  static absl::StatusOr<std::unique_ptr<VideoReader>> Open(std::string_view bytes);

  ~VideoReader();
  VideoReader(const VideoReader&) = delete;
  VideoReader& operator=(const VideoReader&) = delete;

  // Size of the frames, pixels, as the stream declares it.
  int width() const;
  int height() const;

  // Frames the container declares for the stream; when it declares none,
  // the packets Open counted in a first pass over the stream.
  int frame_count() const;

  // Frames per second: the stream's average frame rate, else its guessed one.
  double fps() const;

  // The frame with presentation index `index` (0-based), sRGB, top row first.
  // OutOfRange for an index outside [0, frame_count()); DataLoss when the
  // stream ends before that frame, lacks it, or a packet on the way to it
  // does not read or decode (a truncated file). The reader stays usable after
  // an error: the next call seeks afresh.
  absl::StatusOr<RgbImage> Frame(int index);

 private:
  struct Impl;
  explicit VideoReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact
