#include "common/io/video_reader.h"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/log.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/av_log.h"

namespace reenact {
namespace {

// A Status of `code` for libav error `error` from `what`, with the logged
// detail; an allocation failure is ResourceExhausted whatever `code` says.
absl::Status AvStatus(absl::StatusCode code, int error, absl::string_view what) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(error, text, sizeof(text));
  std::string message = absl::StrCat("VideoReader: ", what, ": ", text);
  if (const std::string detail = TakeLastAvError(); !detail.empty()) {
    absl::StrAppend(&message, " (", detail, ")");
  }
  if (error == AVERROR(ENOMEM)) code = absl::StatusCode::kResourceExhausted;
  return absl::Status(code, message);
}

// The code of a failure to parse the container: data that end too early are
// DataLoss, data that are no container libav knows are InvalidArgument.
absl::StatusCode ContainerErrorCode(int error) {
  return error == AVERROR_EOF ? absl::StatusCode::kDataLoss : absl::StatusCode::kInvalidArgument;
}

// The bytes behind the custom I/O context, and the read position in them.
struct MemoryInput {
  std::string_view bytes;
  int64_t position = 0;
};

int ReadMemory(void* opaque, uint8_t* buffer, int size) {
  auto* input = static_cast<MemoryInput*>(opaque);
  const int64_t left = static_cast<int64_t>(input->bytes.size()) - input->position;
  if (left <= 0) return AVERROR_EOF;
  const int count = static_cast<int>(std::min<int64_t>(size, left));
  std::memcpy(buffer, input->bytes.data() + input->position, count);
  input->position += count;
  return count;
}

// lseek over the bytes, plus AVSEEK_SIZE; a position outside the bytes is an
// error, so that a demuxer that seeks past the end of a truncated file says
// so instead of reading nothing.
int64_t SeekMemory(void* opaque, int64_t offset, int whence) {
  auto* input = static_cast<MemoryInput*>(opaque);
  const int64_t size = static_cast<int64_t>(input->bytes.size());
  if (whence & AVSEEK_SIZE) return size;
  int64_t base = 0;
  switch (whence & ~AVSEEK_FORCE) {
    case SEEK_SET:
      base = 0;
      break;
    case SEEK_CUR:
      base = input->position;
      break;
    case SEEK_END:
      base = size;
      break;
    default:
      return AVERROR(EINVAL);
  }
  if (offset < -base || offset > size - base) return AVERROR(EINVAL);
  input->position = base + offset;
  return input->position;
}

// The libswscale matrix for a stream's colour space tag; untagged and unknown
// ones are BT.601.
int SwsColorspace(AVColorSpace colorspace) {
  switch (colorspace) {
    case AVCOL_SPC_BT709:
      return SWS_CS_ITU709;
    case AVCOL_SPC_FCC:
      return SWS_CS_FCC;
    case AVCOL_SPC_SMPTE240M:
      return SWS_CS_SMPTE240M;
    case AVCOL_SPC_BT2020_NCL:
    case AVCOL_SPC_BT2020_CL:
      return SWS_CS_BT2020;
    default:
      return SWS_CS_ITU601;
  }
}

}  // namespace

struct VideoReader::Impl {
  MemoryInput input;
  AVIOContext* io = nullptr;
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;  // Owned by `format`.
  SwsContext* scaler = nullptr;
  AVFrame* frame = nullptr;  // The last frame decoded, when frame_index >= 0.
  AVPacket* packet = nullptr;
  AVRational frame_rate = {0, 1};
  int width = 0;
  int height = 0;
  int frame_count = 0;
  // Timestamps in the stream's time base: frame 0's presentation time, and
  // the first packet's decoding time (where the stream starts, for seeking).
  int64_t first_pts = AV_NOPTS_VALUE;
  int64_t start_timestamp = AV_NOPTS_VALUE;
  int64_t frame_index = -1;  // Index of `frame`; -1 when none is held.
  bool flushing = false;     // The demuxer ended and the decoder was told.
  bool lost = false;         // An error left the position unknown; seek first.
  // What `scaler` converts from: pixel format, size, matrix and range.
  int scaler_key[5] = {-1, 0, 0, 0, 0};

  ~Impl() {
    sws_freeContext(scaler);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    avformat_close_input(&format);  // Leaves the custom I/O context alone.
    if (io != nullptr) {
      av_freep(&io->buffer);  // libavformat may have replaced the buffer.
      avio_context_free(&io);
    }
  }

  absl::Status OpenInput();
  absl::Status OpenDecoder();
  absl::Status CountFrames();
  absl::Status SendPacket();
  absl::StatusOr<bool> DecodeNext();
  absl::Status SeekTo(int64_t timestamp);
  absl::Status SeekBefore(int index);
  absl::StatusOr<RgbImage> Read(int index);
  absl::StatusOr<RgbImage> Convert();

  int64_t IndexOf(int64_t timestamp) const {
    return av_rescale_q_rnd(timestamp - first_pts, stream->time_base, av_inv_q(frame_rate),
                            AV_ROUND_NEAR_INF);
  }
  int64_t TimestampOf(int64_t index) const {
    return first_pts + av_rescale_q(index, av_inv_q(frame_rate), stream->time_base);
  }
};

absl::Status VideoReader::Impl::OpenInput() {
  constexpr int kBufferSize = 1 << 16;
  auto* buffer = static_cast<uint8_t*>(av_malloc(kBufferSize));
  if (buffer == nullptr) return absl::ResourceExhaustedError("VideoReader: av_malloc");
  io = avio_alloc_context(buffer, kBufferSize, /*write_flag=*/0, &input, ReadMemory, nullptr,
                          SeekMemory);
  if (io == nullptr) {
    av_free(buffer);
    return absl::ResourceExhaustedError("VideoReader: avio_alloc_context");
  }
  format = avformat_alloc_context();
  if (format == nullptr) return absl::ResourceExhaustedError("VideoReader: avformat_alloc_context");
  format->pb = io;
  int error = avformat_open_input(&format, nullptr, nullptr, nullptr);  // Frees it on failure.
  if (error < 0) return AvStatus(ContainerErrorCode(error), error, "not a readable container");
  error = avformat_find_stream_info(format, nullptr);
  if (error < 0) return AvStatus(ContainerErrorCode(error), error, "avformat_find_stream_info");
  return absl::OkStatus();
}

absl::Status VideoReader::Impl::OpenDecoder() {
  const AVCodec* decoder = nullptr;
  const int found = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &decoder, 0);
  if (found == AVERROR_STREAM_NOT_FOUND)
    return absl::InvalidArgumentError("VideoReader: the bytes hold no video stream");
  if (found < 0 || decoder == nullptr) {
    const AVCodecID id = found >= 0 ? format->streams[found]->codecpar->codec_id : AV_CODEC_ID_NONE;
    return absl::InvalidArgumentError(
        absl::StrCat("VideoReader: no decoder for the video stream (", avcodec_get_name(id), ")"));
  }
  stream = format->streams[found];
  for (unsigned i = 0; i < format->nb_streams; ++i) {
    if (format->streams[i] != stream) format->streams[i]->discard = AVDISCARD_ALL;
  }
  width = stream->codecpar->width;
  height = stream->codecpar->height;
  if (width <= 0 || height <= 0)
    return absl::InvalidArgumentError("VideoReader: the video stream declares no frame size");
  if (static_cast<uint64_t>(width) * static_cast<uint64_t>(height) > kMaxDecodedImagePixels) {
    return absl::InvalidArgumentError(absl::StrCat("VideoReader: frames of ", width, "x", height,
                                                   " (at most ", kMaxDecodedImagePixels,
                                                   " pixels)"));
  }
  frame_rate = stream->avg_frame_rate;
  if (frame_rate.num <= 0 || frame_rate.den <= 0)
    frame_rate = av_guess_frame_rate(format, stream, nullptr);
  if (frame_rate.num <= 0 || frame_rate.den <= 0)
    return absl::InvalidArgumentError("VideoReader: the video stream has no frame rate");
  frame_count = static_cast<int>(std::min<int64_t>(stream->nb_frames, INT_MAX));

  codec = avcodec_alloc_context3(decoder);
  frame = av_frame_alloc();
  packet = av_packet_alloc();
  if (codec == nullptr || frame == nullptr || packet == nullptr)
    return absl::ResourceExhaustedError("VideoReader: avcodec_alloc_context3");
  int error = avcodec_parameters_to_context(codec, stream->codecpar);
  if (error < 0) return AvStatus(absl::StatusCode::kInvalidArgument, error, "codec parameters");
  codec->thread_count = 1;  // Deterministic output (see the header).
  codec->pkt_timebase = stream->time_base;
  error = avcodec_open2(codec, decoder, nullptr);
  if (error < 0) {
    return AvStatus(absl::StatusCode::kInvalidArgument, error,
                    absl::StrCat("opening decoder ", decoder->name));
  }
  return absl::OkStatus();
}

// A first pass over the packets, for containers that do not declare the frame
// count; it stops at the first packet that does not read, so a truncated file
// counts the frames it still has.
absl::Status VideoReader::Impl::CountFrames() {
  int64_t count = 0;
  while (av_read_frame(format, packet) >= 0) {
    if (packet->stream_index == stream->index && !(packet->flags & AV_PKT_FLAG_DISCARD)) {
      if (start_timestamp == AV_NOPTS_VALUE)
        start_timestamp = packet->dts != AV_NOPTS_VALUE ? packet->dts : packet->pts;
      ++count;
    }
    av_packet_unref(packet);
  }
  TakeLastAvError();  // What the counting pass logged is not an error of the caller.
  frame_count = static_cast<int>(std::min<int64_t>(count, INT_MAX));
  if (count == 0) return absl::DataLossError("VideoReader: the video stream has no packets");
  return SeekTo(start_timestamp);
}

// Reads the stream's next packet and sends it to the decoder; at the end of
// the stream, tells the decoder to give out the frames it holds.
absl::Status VideoReader::Impl::SendPacket() {
  if (flushing) return absl::InternalError("VideoReader: the decoder wants input after the end");
  while (true) {
    int error = av_read_frame(format, packet);
    if (error == AVERROR_EOF) {
      flushing = true;
      error = avcodec_send_packet(codec, nullptr);
      return error < 0 ? AvStatus(absl::StatusCode::kDataLoss, error, "flushing the decoder")
                       : absl::OkStatus();
    }
    if (error < 0) return AvStatus(absl::StatusCode::kDataLoss, error, "reading a packet");
    if (packet->stream_index != stream->index) {
      av_packet_unref(packet);
      continue;
    }
    if (start_timestamp == AV_NOPTS_VALUE)
      start_timestamp = packet->dts != AV_NOPTS_VALUE ? packet->dts : packet->pts;
    if (packet->flags & AV_PKT_FLAG_CORRUPT) {
      av_packet_unref(packet);
      return absl::DataLossError("VideoReader: a packet is cut short (truncated data)");
    }
    error = avcodec_send_packet(codec, packet);
    av_packet_unref(packet);
    return error < 0 ? AvStatus(absl::StatusCode::kDataLoss, error, "decoding a packet")
                     : absl::OkStatus();
  }
}

// Decodes the next frame in presentation order into `frame` and sets its
// index; false at the end of the stream.
absl::StatusOr<bool> VideoReader::Impl::DecodeNext() {
  frame_index = -1;
  while (true) {
    const int error = avcodec_receive_frame(codec, frame);
    if (error == AVERROR_EOF) return false;
    if (error == AVERROR(EAGAIN)) {
      RETURN_IF_ERROR(SendPacket());
      continue;
    }
    if (error < 0) return AvStatus(absl::StatusCode::kDataLoss, error, "decoding a frame");
    if ((frame->flags & AV_FRAME_FLAG_CORRUPT) || frame->decode_error_flags != 0)
      return absl::DataLossError("VideoReader: a frame decoded with errors");
    const int64_t timestamp = frame->best_effort_timestamp;
    if (timestamp == AV_NOPTS_VALUE)
      return absl::DataLossError("VideoReader: a frame without a timestamp");
    if (first_pts == AV_NOPTS_VALUE) first_pts = timestamp;
    frame_index = IndexOf(timestamp);
    return true;
  }
}

absl::Status VideoReader::Impl::SeekTo(int64_t timestamp) {
  int error = av_seek_frame(format, stream->index, timestamp, AVSEEK_FLAG_BACKWARD);
  if (error < 0) error = av_seek_frame(format, stream->index, timestamp, 0);
  if (error < 0) return AvStatus(absl::StatusCode::kDataLoss, error, "seeking");
  avcodec_flush_buffers(codec);
  frame_index = -1;
  flushing = false;
  lost = false;
  return absl::OkStatus();
}

// Seeks to a key frame and decodes its first frame, at or before `index`
// where the stream has one. The container's index holds decoding times,
// which precede presentation times, so the key frame found for frame k's time
// may come after frame k: each retry then seeks twice as many frames earlier.
absl::Status VideoReader::Impl::SeekBefore(int index) {
  for (int64_t back = 0;; back = std::max<int64_t>(1, 2 * back)) {
    const int64_t target = index - back;
    RETURN_IF_ERROR(SeekTo(target <= 0 ? start_timestamp : TimestampOf(target)));
    ASSIGN_OR_RETURN(const bool decoded, DecodeNext());
    if (!decoded) {
      return absl::DataLossError(
          absl::StrCat("VideoReader: no frame decodes after seeking to frame ", index));
    }
    if (frame_index <= index || target <= 0) return absl::OkStatus();
  }
}

absl::StatusOr<RgbImage> VideoReader::Impl::Read(int index) {
  if (lost || index < frame_index) RETURN_IF_ERROR(SeekBefore(index));
  while (frame_index < index) {
    const int64_t previous = frame_index;
    ASSIGN_OR_RETURN(const bool decoded, DecodeNext());
    if (!decoded) {
      return absl::DataLossError(
          absl::StrCat("VideoReader: the stream ends after frame ", previous, " of ", frame_count));
    }
  }
  if (frame_index != index) {
    return absl::DataLossError(absl::StrCat("VideoReader: the stream lacks frame ", index,
                                            " (the next one is ", frame_index, ")"));
  }
  return Convert();
}

absl::StatusOr<RgbImage> VideoReader::Impl::Convert() {
  const auto pixel_format = static_cast<AVPixelFormat>(frame->format);
  const int colorspace = SwsColorspace(frame->colorspace);
  const int full_range = frame->color_range == AVCOL_RANGE_JPEG ? 1 : 0;
  const int key[5] = {pixel_format, frame->width, frame->height, colorspace, full_range};
  if (!std::equal(key, key + 5, scaler_key)) {
    scaler = sws_getCachedContext(scaler, frame->width, frame->height, pixel_format, frame->width,
                                  frame->height, AV_PIX_FMT_RGB24,
                                  SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, nullptr,
                                  nullptr, nullptr);
    if (scaler == nullptr) {
      std::fill(scaler_key, scaler_key + 5, -1);
      const char* name = av_get_pix_fmt_name(pixel_format);
      return absl::UnimplementedError(absl::StrCat("VideoReader: no conversion from pixel format ",
                                                   name != nullptr ? name : "unknown"));
    }
    // Fails, harmlessly, for sources that are RGB already.
    const int* table = sws_getCoefficients(colorspace);
    sws_setColorspaceDetails(scaler, table, full_range, table, 1, 0, 1 << 16, 1 << 16);
    std::copy(key, key + 5, scaler_key);
  }
  RgbImage image(frame->width, frame->height);
  uint8_t* destination[4] = {image.data.data(), nullptr, nullptr, nullptr};
  const int destination_stride[4] = {3 * image.width, 0, 0, 0};
  const int rows = sws_scale(scaler, frame->data, frame->linesize, 0, frame->height, destination,
                             destination_stride);
  if (rows != frame->height)
    return absl::InternalError(absl::StrCat("VideoReader: sws_scale gave ", rows, " rows"));
  return image;
}

absl::StatusOr<std::unique_ptr<VideoReader>> VideoReader::Open(std::string_view bytes) {
  if (bytes.empty()) return absl::InvalidArgumentError("VideoReader: no bytes");
  InstallQuietAvLog();
  auto impl = std::make_unique<Impl>();
  impl->input.bytes = bytes;
  RETURN_IF_ERROR(impl->OpenInput());
  RETURN_IF_ERROR(impl->OpenDecoder());
  if (impl->frame_count == 0) RETURN_IF_ERROR(impl->CountFrames());
  ASSIGN_OR_RETURN(const bool decoded, impl->DecodeNext());
  if (!decoded) return absl::DataLossError("VideoReader: no frame of the video stream decodes");
  return std::unique_ptr<VideoReader>(new VideoReader(std::move(impl)));
}

VideoReader::VideoReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

VideoReader::~VideoReader() = default;

int VideoReader::width() const { return impl_->width; }

int VideoReader::height() const { return impl_->height; }

int VideoReader::frame_count() const { return impl_->frame_count; }

double VideoReader::fps() const { return av_q2d(impl_->frame_rate); }

absl::StatusOr<RgbImage> VideoReader::Frame(int index) {
  if (index < 0 || index >= impl_->frame_count) {
    return absl::OutOfRangeError(
        absl::StrCat("VideoReader: frame ", index, " of ", impl_->frame_count));
  }
  absl::StatusOr<RgbImage> image = impl_->Read(index);
  if (!image.ok()) impl_->lost = true;
  return image;
}

}  // namespace reenact
