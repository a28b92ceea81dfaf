#include "common/io/jpeg.h"

#include <memory>

#include <turbojpeg.h>

#include "absl/strings/str_cat.h"

namespace reenact {
namespace {

struct TjDeleter {
  void operator()(void* handle) const { tjDestroy(handle); }
};
using TjHandle = std::unique_ptr<void, TjDeleter>;

}  // namespace

absl::StatusOr<std::string> EncodeJpeg(const RgbImage& image, int quality) {
  if (image.width <= 0 || image.height <= 0 || image.data.size() != image.num_pixels() * 3) {
    return absl::InvalidArgumentError(absl::StrCat("EncodeJpeg: bad image ", image.width, "x",
                                                   image.height, " with ", image.data.size(),
                                                   " values"));
  }
  if (quality < 1 || quality > 100) {
    return absl::InvalidArgumentError(
        absl::StrCat("EncodeJpeg: quality ", quality, " outside 1..100"));
  }
  TjHandle handle(tjInitCompress());
  if (!handle) return absl::InternalError("EncodeJpeg: tjInitCompress failed");
  unsigned char* jpeg = nullptr;
  unsigned long jpeg_size = 0;
  const int rc = tjCompress2(handle.get(), image.data.data(), image.width, 0, image.height,
                             TJPF_RGB, &jpeg, &jpeg_size, TJSAMP_420, quality, TJFLAG_ACCURATEDCT);
  std::string out;
  if (rc == 0) out.assign(reinterpret_cast<const char*>(jpeg), jpeg_size);
  const std::string error = rc == 0 ? "" : tjGetErrorStr2(handle.get());
  tjFree(jpeg);
  if (rc != 0) return absl::InternalError(absl::StrCat("EncodeJpeg: ", error));
  return out;
}

absl::StatusOr<RgbImage> DecodeJpeg(std::string_view jpeg) {
  TjHandle handle(tjInitDecompress());
  if (!handle) return absl::InternalError("DecodeJpeg: tjInitDecompress failed");
  const auto* bytes = reinterpret_cast<const unsigned char*>(jpeg.data());
  int width = 0, height = 0, subsampling = 0, colorspace = 0;
  if (tjDecompressHeader3(handle.get(), bytes, jpeg.size(), &width, &height, &subsampling,
                          &colorspace) != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("DecodeJpeg: not a JPEG (", tjGetErrorStr2(handle.get()), ")"));
  }
  if (width <= 0 || height <= 0 ||
      static_cast<uint64_t>(width) * static_cast<uint64_t>(height) > kMaxDecodedImagePixels) {
    return absl::InvalidArgumentError(
        absl::StrCat("DecodeJpeg: implausible size ", width, "x", height));
  }
  RgbImage image(width, height);
  if (tjDecompress2(handle.get(), bytes, jpeg.size(), image.data.data(), width, 0, height, TJPF_RGB,
                    TJFLAG_ACCURATEDCT) != 0) {
    // Warnings (e.g. a truncated stream) count as errors: a frame must decode
    // whole.
    return absl::InvalidArgumentError(absl::StrCat("DecodeJpeg: ", tjGetErrorStr2(handle.get())));
  }
  return image;
}

}  // namespace reenact
