#include "common/io/video_writer.h"

#include <algorithm>
#include <filesystem>
#include <string_view>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/av_log.h"

namespace reenact {
namespace {

// A Status for libav error `error` from `what`, with the logged detail. libav
// errors that wrap errno values (AVERROR(e) == -e) keep their meaning, e.g. a
// missing folder is NotFound.
absl::Status AvStatus(int error, absl::string_view what) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(error, text, sizeof(text));
  std::string message = absl::StrCat(what, ": ", text);
  if (const std::string detail = TakeLastAvError(); !detail.empty()) {
    absl::StrAppend(&message, " (", detail, ")");
  }
  absl::StatusCode code = absl::StatusCode::kInternal;
  if (error < 0 && -error < 4096) {
    code = absl::ErrnoToStatusCode(-error);
    if (code == absl::StatusCode::kUnknown) code = absl::StatusCode::kInternal;
  }
  return absl::Status(code, message);
}

const AVCodec* FindEncoder(VideoCodec codec) {
  if (codec != VideoCodec::kMpeg4) {
    if (const AVCodec* x264 = avcodec_find_encoder_by_name("libx264")) return x264;
    if (codec == VideoCodec::kH264) return nullptr;
  }
  return avcodec_find_encoder(AV_CODEC_ID_MPEG4);
}

}  // namespace

absl::Status VideoWriterOptions::Validate() const {
  static constexpr std::string_view kPresets[] = {"ultrafast", "superfast", "veryfast",
                                                  "faster",    "fast",      "medium",
                                                  "slow",      "slower",    "veryslow"};
  bool known_preset = false;
  for (std::string_view name : kPresets) known_preset |= (name == preset);
  if (crf < 0 || crf > 51 || !known_preset || mpeg4_qscale < 1 || mpeg4_qscale > 31 ||
      keyframe_interval < 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "VideoWriterOptions: crf ", crf, " (0..51), preset \"", preset, "\", mpeg4_qscale ",
        mpeg4_qscale, " (1..31), keyframe_interval ", keyframe_interval, " (>= 0)"));
  }
  return absl::OkStatus();
}

struct VideoWriter::Impl {
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;  // Owned by `format`.
  SwsContext* scaler = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  std::string path;
  std::string codec_name;
  int width = 0;
  int height = 0;
  int64_t frames_written = 0;
  bool file_open = false;
  bool closed = false;

  ~Impl() {
    sws_freeContext(scaler);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    if (format != nullptr) {
      if (file_open) avio_closep(&format->pb);
      avformat_free_context(format);
    }
  }

  absl::Status CreateFormat();
  absl::Status OpenCodec(const AVCodec* encoder, double fps, const VideoWriterOptions& options);
  absl::Status OpenFile(const VideoWriterOptions& options);
  absl::Status AllocateFrame();
  absl::Status Encode(const AVFrame* input);
};

absl::Status VideoWriter::Impl::CreateFormat() {
  int error = avformat_alloc_output_context2(&format, nullptr, nullptr, path.c_str());
  if (error < 0 || format == nullptr) {
    error = avformat_alloc_output_context2(&format, nullptr, "mp4", path.c_str());
  }
  if (error < 0 || format == nullptr) return AvStatus(error, "avformat_alloc_output_context2");
  return absl::OkStatus();
}

absl::Status VideoWriter::Impl::OpenCodec(const AVCodec* encoder, double fps,
                                          const VideoWriterOptions& options) {
  codec = avcodec_alloc_context3(encoder);
  if (codec == nullptr) return absl::ResourceExhaustedError("avcodec_alloc_context3");
  const AVRational frame_rate = av_d2q(fps, 65535);  // MPEG-4 caps the denominator.
  codec->width = width;
  codec->height = height;
  codec->time_base = av_inv_q(frame_rate);
  codec->framerate = frame_rate;
  codec->pix_fmt = AV_PIX_FMT_YUV420P;
  codec->gop_size = options.keyframe_interval > 0 ? options.keyframe_interval
                                                  : std::max(1, static_cast<int>(2.0 * fps));
  codec->color_range = AVCOL_RANGE_MPEG;
  codec->colorspace = AVCOL_SPC_SMPTE170M;
  codec->color_primaries = AVCOL_PRI_BT709;
  codec->color_trc = AVCOL_TRC_IEC61966_2_1;
  if (format->oformat->flags & AVFMT_GLOBALHEADER) codec->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  AVDictionary* settings = nullptr;
  if (encoder->id == AV_CODEC_ID_H264) {
    av_dict_set(&settings, "preset", options.preset.c_str(), 0);
    av_dict_set_int(&settings, "crf", options.crf, 0);
  } else {
    codec->flags |= AV_CODEC_FLAG_QSCALE;
    codec->global_quality = FF_QP2LAMBDA * options.mpeg4_qscale;
  }
  const int error = avcodec_open2(codec, encoder, &settings);
  av_dict_free(&settings);
  if (error < 0) return AvStatus(error, absl::StrCat("opening encoder ", encoder->name));
  codec_name = encoder->name;
  stream = avformat_new_stream(format, nullptr);
  if (stream == nullptr) return absl::ResourceExhaustedError("avformat_new_stream");
  stream->time_base = codec->time_base;
  stream->avg_frame_rate = frame_rate;
  const int copied = avcodec_parameters_from_context(stream->codecpar, codec);
  return copied < 0 ? AvStatus(copied, "avcodec_parameters_from_context") : absl::OkStatus();
}

absl::Status VideoWriter::Impl::OpenFile(const VideoWriterOptions& options) {
  if (!(format->oformat->flags & AVFMT_NOFILE)) {
    const int error = avio_open(&format->pb, path.c_str(), AVIO_FLAG_WRITE);
    if (error < 0) return AvStatus(error, absl::StrCat("cannot write ", path));
    file_open = true;
  }
  AVDictionary* settings = nullptr;
  if (options.faststart) av_dict_set(&settings, "movflags", "+faststart", 0);
  const int error = avformat_write_header(format, &settings);
  av_dict_free(&settings);
  return error < 0 ? AvStatus(error, absl::StrCat("writing the header of ", path))
                   : absl::OkStatus();
}

absl::Status VideoWriter::Impl::AllocateFrame() {
  frame = av_frame_alloc();
  packet = av_packet_alloc();
  if (frame == nullptr || packet == nullptr) return absl::ResourceExhaustedError("av_frame_alloc");
  frame->format = AV_PIX_FMT_YUV420P;
  frame->width = width;
  frame->height = height;
  const int error = av_frame_get_buffer(frame, 0);
  if (error < 0) return AvStatus(error, "av_frame_get_buffer");
  scaler = sws_getContext(width, height, AV_PIX_FMT_RGB24, width, height, AV_PIX_FMT_YUV420P,
                          SWS_BICUBIC | SWS_ACCURATE_RND, nullptr, nullptr, nullptr);
  if (scaler == nullptr) return absl::InternalError("sws_getContext: RGB24 -> YUV420P");
  // sRGB (full range) to limited-range Y'CbCr with the BT.601 matrix.
  const int* bt601 = sws_getCoefficients(SWS_CS_ITU601);
  sws_setColorspaceDetails(scaler, bt601, 1, bt601, 0, 0, 1 << 16, 1 << 16);
  return absl::OkStatus();
}

// Sends `input` (nullptr: flush) and writes every packet the encoder returns.
absl::Status VideoWriter::Impl::Encode(const AVFrame* input) {
  int error = avcodec_send_frame(codec, input);
  if (error < 0) return AvStatus(error, "avcodec_send_frame");
  while (true) {
    error = avcodec_receive_packet(codec, packet);
    if (error == AVERROR(EAGAIN) || error == AVERROR_EOF) return absl::OkStatus();
    if (error < 0) return AvStatus(error, "avcodec_receive_packet");
    av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
    packet->stream_index = stream->index;
    error = av_interleaved_write_frame(format, packet);  // Takes the packet's data.
    if (error < 0) return AvStatus(error, absl::StrCat("writing ", path));
  }
}

absl::StatusOr<std::unique_ptr<VideoWriter>> VideoWriter::Open(const std::string& path, int width,
                                                               int height, double fps,
                                                               const VideoWriterOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (width <= 0 || height <= 0 || width % 2 != 0 || height % 2 != 0 || !(fps > 0.0) ||
      fps > 1000.0) {
    return absl::InvalidArgumentError(absl::StrCat("VideoWriter: ", width, "x", height, " at ", fps,
                                                   " fps (sizes must be even and positive, "
                                                   "fps in (0, 1000])"));
  }
  InstallQuietAvLog();
  const AVCodec* encoder = FindEncoder(options.codec);
  if (encoder == nullptr)
    return absl::UnavailableError("VideoWriter: libavcodec has no encoder of the requested kind");
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->width = width;
  impl->height = height;
  RETURN_IF_ERROR(impl->CreateFormat());
  RETURN_IF_ERROR(impl->OpenCodec(encoder, fps, options));
  RETURN_IF_ERROR(impl->AllocateFrame());
  if (absl::Status status = impl->OpenFile(options); !status.ok()) {
    if (impl->file_open) {
      impl.reset();  // Closes the file before it goes.
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
    return status;
  }
  return std::unique_ptr<VideoWriter>(new VideoWriter(std::move(impl)));
}

VideoWriter::VideoWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

VideoWriter::~VideoWriter() { (void)Close(); }

absl::Status VideoWriter::Append(const RgbImage& frame) {
  if (impl_->closed) return absl::FailedPreconditionError("VideoWriter::Append after Close");
  if (frame.width != impl_->width || frame.height != impl_->height ||
      frame.data.size() != frame.num_pixels() * 3) {
    return absl::InvalidArgumentError(absl::StrCat("VideoWriter::Append: frame of ", frame.width,
                                                   "x", frame.height, ", the video is ",
                                                   impl_->width, "x", impl_->height));
  }
  const int writable = av_frame_make_writable(impl_->frame);
  if (writable < 0) return AvStatus(writable, "av_frame_make_writable");
  const uint8_t* source[1] = {frame.data.data()};
  const int source_stride[1] = {3 * frame.width};
  sws_scale(impl_->scaler, source, source_stride, 0, frame.height, impl_->frame->data,
            impl_->frame->linesize);
  impl_->frame->pts = impl_->frames_written;
  RETURN_IF_ERROR(impl_->Encode(impl_->frame));
  ++impl_->frames_written;
  return absl::OkStatus();
}

absl::Status VideoWriter::Close() {
  if (impl_->closed) return absl::OkStatus();
  impl_->closed = true;
  absl::Status status = impl_->Encode(nullptr);
  const int trailer = av_write_trailer(impl_->format);
  if (status.ok() && trailer < 0) status = AvStatus(trailer, "av_write_trailer");
  if (impl_->file_open) {
    const int closed = avio_closep(&impl_->format->pb);
    impl_->file_open = false;
    if (status.ok() && closed < 0) status = AvStatus(closed, absl::StrCat("closing ", impl_->path));
  }
  return status;
}

const std::string& VideoWriter::codec_name() const { return impl_->codec_name; }

int64_t VideoWriter::frames_written() const { return impl_->frames_written; }

}  // namespace reenact
