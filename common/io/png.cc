#include "common/io/png.h"

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact {
namespace {

void AppendBigEndian32(uint32_t value, std::string& out) {
  out.push_back(static_cast<char>(value >> 24));
  out.push_back(static_cast<char>(value >> 16));
  out.push_back(static_cast<char>(value >> 8));
  out.push_back(static_cast<char>(value));
}

// Length, type, data, CRC-32 of type and data.
void AppendChunk(const char type[4], const uint8_t* data, size_t size, std::string& out) {
  AppendBigEndian32(static_cast<uint32_t>(size), out);
  out.append(type, 4);
  out.append(reinterpret_cast<const char*>(data), size);
  uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(type), 4);
  if (size > 0) crc = crc32(crc, data, static_cast<uInt>(size));
  AppendBigEndian32(static_cast<uint32_t>(crc), out);
}

}  // namespace

absl::StatusOr<std::string> EncodePng(const RgbImage& image, const PngOptions& options) {
  if (image.width <= 0 || image.height <= 0 ||
      image.data.size() != static_cast<size_t>(image.width) * image.height * 3) {
    return absl::InvalidArgumentError("EncodePng: empty or malformed image");
  }
  if (options.compression_level < 0 || options.compression_level > 9) {
    return absl::InvalidArgumentError("EncodePng: compression level must be 0..9");
  }
  const MaskImage* mask = options.alpha_mask;
  if (mask != nullptr && (mask->width != image.width || mask->height != image.height)) {
    return absl::InvalidArgumentError(absl::StrCat("EncodePng: alpha mask is ", mask->width, "x",
                                                   mask->height, ", image is ", image.width, "x",
                                                   image.height));
  }
  const int channels = mask != nullptr ? 4 : 3;
  const size_t row_bytes = static_cast<size_t>(image.width) * channels;

  // Scanlines, each a filter byte then the row; "Up" (2): each byte minus
  // the byte above it (the row above the first is zero).
  std::vector<uint8_t> raw((row_bytes + 1) * image.height);
  std::vector<uint8_t> previous(row_bytes, 0), current(row_bytes);
  for (int y = 0; y < image.height; ++y) {
    const uint8_t* rgb = &image.data[static_cast<size_t>(y) * image.width * 3];
    if (mask == nullptr) {
      std::memcpy(current.data(), rgb, row_bytes);
    } else {
      const uint8_t* labels = &mask->data[static_cast<size_t>(y) * image.width];
      for (int x = 0; x < image.width; ++x) {
        std::memcpy(&current[x * 4], rgb + x * 3, 3);
        current[x * 4 + 3] = labels[x] != 0 ? 255 : 0;
      }
    }
    uint8_t* out = &raw[y * (row_bytes + 1)];
    out[0] = 2;
    for (size_t i = 0; i < row_bytes; ++i) {
      out[1 + i] = static_cast<uint8_t>(current[i] - previous[i]);
    }
    previous.swap(current);
  }

  uLongf deflated_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<uint8_t> deflated(deflated_size);
  if (compress2(deflated.data(), &deflated_size, raw.data(), static_cast<uLong>(raw.size()),
                options.compression_level) != Z_OK) {
    return absl::InternalError("EncodePng: zlib could not deflate the image");
  }

  std::string png("\x89PNG\r\n\x1a\n", 8);
  uint8_t header[13];
  const uint32_t size[2] = {static_cast<uint32_t>(image.width),
                            static_cast<uint32_t>(image.height)};
  for (int k = 0; k < 2; ++k) {
    for (int b = 0; b < 4; ++b) header[k * 4 + b] = static_cast<uint8_t>(size[k] >> (24 - 8 * b));
  }
  header[8] = 8;                             // Bit depth.
  header[9] = mask != nullptr ? 6 : 2;       // Colour type: RGBA or RGB.
  header[10] = header[11] = header[12] = 0;  // Deflate, adaptive filters, no interlace.
  AppendChunk("IHDR", header, sizeof(header), png);
  AppendChunk("IDAT", deflated.data(), deflated_size, png);
  AppendChunk("IEND", nullptr, 0, png);
  return png;
}

absl::Status WritePng(const RgbImage& image, const std::string& path, const PngOptions& options) {
  ASSIGN_OR_RETURN(const std::string png, EncodePng(image, options));
  return WriteFileAtomically(path, png);
}

}  // namespace reenact
