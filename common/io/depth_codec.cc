#include "common/io/depth_codec.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "common/base/status_macros.h"

namespace reenact {
namespace {

constexpr char kMagic[4] = {'R', 'V', 'L', 'D'};
constexpr uint8_t kVersion = 1;
constexpr uint8_t kFlagZstd = 0x1;
constexpr size_t kHeaderSize = 28;
constexpr size_t kChecksumOffset = 24;
constexpr uint32_t kMaxSidePx = 32768;
// Largest zigzag-mapped difference between two 16-bit values: 2 * 65535.
constexpr uint32_t kMaxZigzag = 131070;

// Upper bound of the RVL stream size for `num_pixels` pixels: at most six
// nibbles per value (kMaxZigzag has 18 bits) plus run counts, which add at
// most two nibbles per value when runs alternate every pixel.
uint64_t MaxRvlBytes(uint64_t num_pixels) { return 4 * num_pixels + 16; }

void StoreLe32(uint32_t value, char* out) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((value >> (8 * i)) & 0xFF);
}

uint32_t LoadLe32(const char* in) {
  uint32_t value = 0;
  for (int i = 0; i < 4; ++i)
    value |= static_cast<uint32_t>(static_cast<uint8_t>(in[i])) << (8 * i);
  return value;
}

// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), one table lookup per
// byte.
constexpr std::array<uint32_t, 256> MakeCrc32cTable() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t crc = i;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ ((crc & 1) ? 0x82F63B78u : 0u);
    table[i] = crc;
  }
  return table;
}
constexpr std::array<uint32_t, 256> kCrc32cTable = MakeCrc32cTable();

uint32_t ExtendCrc32c(uint32_t crc, std::string_view bytes) {
  crc = ~crc;
  for (char byte : bytes)
    crc = kCrc32cTable[(crc ^ static_cast<uint8_t>(byte)) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

uint32_t HeaderAndPayloadCrc(std::string_view header, std::string_view payload) {
  return ExtendCrc32c(ExtendCrc32c(0, header.substr(0, kChecksumOffset)), payload);
}

// Packs nibbles eight to a 32-bit word, most significant nibble first.
class NibbleWriter {
 public:
  explicit NibbleWriter(char* out) : out_(out) {}

  // Variable-length code: 3 data bits per nibble, low bits first, 0x8 marks
  // that more nibbles follow.
  void PutVle(uint32_t value) {
    do {
      uint32_t nibble = value & 0x7;
      value >>= 3;
      if (value != 0) nibble |= 0x8;
      word_ = (word_ << 4) | nibble;
      if (++nibbles_in_word_ == 8) Flush();
    } while (value != 0);
  }

  // Pads the last word with zero nibbles; returns the bytes written.
  size_t Finish() {
    if (nibbles_in_word_ > 0) {
      word_ <<= 4 * (8 - nibbles_in_word_);
      Flush();
    }
    return bytes_written_;
  }

 private:
  void Flush() {
    StoreLe32(word_, out_ + bytes_written_);
    bytes_written_ += 4;
    word_ = 0;
    nibbles_in_word_ = 0;
  }

  char* out_;
  size_t bytes_written_ = 0;
  uint32_t word_ = 0;
  int nibbles_in_word_ = 0;
};

// Reads what NibbleWriter wrote, never past the end of its input.
class NibbleReader {
 public:
  explicit NibbleReader(std::string_view words) : words_(words) {}

  // False at the end of the input or for a code longer than 11 nibbles
  // (33 bits); `value` is then unspecified.
  bool GetVle(uint64_t* value) {
    *value = 0;
    for (int shift = 0; shift <= 30; shift += 3) {
      if (nibbles_left_ == 0) {
        if (next_byte_ + 4 > words_.size()) return false;
        word_ = LoadLe32(words_.data() + next_byte_);
        next_byte_ += 4;
        nibbles_left_ = 8;
      }
      const uint32_t nibble = word_ >> 28;
      word_ <<= 4;
      --nibbles_left_;
      *value |= static_cast<uint64_t>(nibble & 0x7) << shift;
      if ((nibble & 0x8) == 0) return true;
    }
    return false;
  }

  // True when the input is used up and the unread nibbles are zero padding.
  bool AtCleanEnd() const { return next_byte_ == words_.size() && word_ == 0; }

  // Byte offset of the word being read (for error messages).
  size_t byte_offset() const { return nibbles_left_ > 0 ? next_byte_ - 4 : next_byte_; }
  bool exhausted() const { return nibbles_left_ == 0 && next_byte_ + 4 > words_.size(); }

 private:
  std::string_view words_;
  size_t next_byte_ = 0;
  uint32_t word_ = 0;
  int nibbles_left_ = 0;
};

absl::Status RvlError(const NibbleReader& reader, size_t base_offset, absl::string_view what) {
  return absl::DataLossError(
      absl::StrCat("depth codec: ", what, " at byte offset ", base_offset + reader.byte_offset()));
}

// RvlDecompress with byte offsets reported relative to `base_offset`.
absl::Status RvlDecode(std::string_view rvl, absl::Span<uint16_t> out, size_t base_offset) {
  if (rvl.size() % 4 != 0) {
    return absl::DataLossError(absl::StrCat("depth codec: RVL stream of ", rvl.size(),
                                            " bytes is not whole 32-bit words at byte offset ",
                                            base_offset));
  }
  NibbleReader reader(rvl);
  const auto read_failure = [&](absl::string_view what) {
    return RvlError(reader, base_offset,
                    reader.exhausted() ? absl::StrCat("stream ends inside ", what)
                                       : absl::StrCat("over-long code for ", what));
  };
  const size_t num_pixels = out.size();
  size_t pixel = 0;
  int32_t previous = 0;
  uint64_t code = 0;
  while (pixel < num_pixels) {
    if (!reader.GetVle(&code)) return read_failure("a zero-run length");
    if (code > num_pixels - pixel) return RvlError(reader, base_offset, "zero run past image end");
    std::memset(out.data() + pixel, 0, code * sizeof(uint16_t));
    pixel += code;
    if (!reader.GetVle(&code)) return read_failure("a value-run length");
    if (code > num_pixels - pixel) return RvlError(reader, base_offset, "value run past image end");
    const size_t run_end = pixel + code;
    for (; pixel < run_end; ++pixel) {
      if (!reader.GetVle(&code)) return read_failure("a depth difference");
      if (code > kMaxZigzag) return RvlError(reader, base_offset, "depth difference out of range");
      const uint32_t zigzag = static_cast<uint32_t>(code);
      const int32_t delta = static_cast<int32_t>(zigzag >> 1) ^ -static_cast<int32_t>(zigzag & 1);
      const int32_t current = previous + delta;
      if (current <= 0 || current > 65535) {
        return RvlError(reader, base_offset, "depth value out of 1..65535 in a value run");
      }
      out[pixel] = static_cast<uint16_t>(current);
      previous = current;
    }
  }
  if (!reader.AtCleanEnd())
    return RvlError(reader, base_offset, "unexpected data after last pixel");
  return absl::OkStatus();
}

absl::Status HeaderError(size_t offset, absl::string_view what) {
  return absl::DataLossError(absl::StrCat("depth codec: ", what, " at byte offset ", offset));
}

}  // namespace

absl::Status DepthCodecOptions::Validate() const {
  if (zstd && (zstd_level < 1 || zstd_level > 19)) {
    return absl::InvalidArgumentError(
        absl::StrCat("DepthCodecOptions: zstd_level must be in 1..19, got ", zstd_level));
  }
  return absl::OkStatus();
}

std::string RvlCompress(absl::Span<const uint16_t> depth_values) {
  std::string rvl(MaxRvlBytes(depth_values.size()), '\0');
  NibbleWriter writer(rvl.data());
  const size_t num_pixels = depth_values.size();
  size_t pixel = 0;
  int32_t previous = 0;
  while (pixel < num_pixels) {
    const size_t zeros_begin = pixel;
    while (pixel < num_pixels && depth_values[pixel] == 0) ++pixel;
    writer.PutVle(static_cast<uint32_t>(pixel - zeros_begin));
    const size_t values_begin = pixel;
    while (pixel < num_pixels && depth_values[pixel] != 0) ++pixel;
    writer.PutVle(static_cast<uint32_t>(pixel - values_begin));
    for (size_t i = values_begin; i < pixel; ++i) {
      const int32_t current = depth_values[i];
      const int32_t delta = current - previous;
      writer.PutVle(static_cast<uint32_t>((delta << 1) ^ (delta >> 31)));  // Zigzag.
      previous = current;
    }
  }
  rvl.resize(writer.Finish());
  return rvl;
}

absl::Status RvlDecompress(std::string_view rvl, absl::Span<uint16_t> depth_values) {
  return RvlDecode(rvl, depth_values, 0);
}

absl::StatusOr<std::string> EncodeDepth(const DepthImageMm& depth_mm,
                                        const DepthCodecOptions& options) {
  if (absl::Status status = options.Validate(); !status.ok()) return status;
  if (depth_mm.width < 0 || depth_mm.height < 0 ||
      static_cast<uint32_t>(depth_mm.width) > kMaxSidePx ||
      static_cast<uint32_t>(depth_mm.height) > kMaxSidePx ||
      depth_mm.data.size() != depth_mm.num_pixels()) {
    return absl::InvalidArgumentError(absl::StrCat("EncodeDepth: bad image ", depth_mm.width, "x",
                                                   depth_mm.height, " with ", depth_mm.data.size(),
                                                   " values (sides up to ", kMaxSidePx, " px)"));
  }
  std::string rvl = RvlCompress(depth_mm.data);
  std::string encoded(kHeaderSize, '\0');
  if (options.zstd) {
    const size_t bound = ZSTD_compressBound(rvl.size());
    encoded.resize(kHeaderSize + bound);
    const size_t compressed = ZSTD_compress(encoded.data() + kHeaderSize, bound, rvl.data(),
                                            rvl.size(), options.zstd_level);
    if (ZSTD_isError(compressed)) {
      return absl::InternalError(
          absl::StrCat("EncodeDepth: zstd failed: ", ZSTD_getErrorName(compressed)));
    }
    encoded.resize(kHeaderSize + compressed);
  } else {
    encoded.append(rvl);
  }
  std::memcpy(encoded.data(), kMagic, 4);
  encoded[4] = static_cast<char>(kVersion);
  encoded[5] = static_cast<char>(options.zstd ? kFlagZstd : 0);
  StoreLe32(static_cast<uint32_t>(depth_mm.width), encoded.data() + 8);
  StoreLe32(static_cast<uint32_t>(depth_mm.height), encoded.data() + 12);
  StoreLe32(static_cast<uint32_t>(rvl.size()), encoded.data() + 16);
  StoreLe32(static_cast<uint32_t>(encoded.size() - kHeaderSize), encoded.data() + 20);
  const std::string_view view(encoded);
  StoreLe32(HeaderAndPayloadCrc(view.substr(0, kHeaderSize), view.substr(kHeaderSize)),
            encoded.data() + kChecksumOffset);
  return encoded;
}

absl::StatusOr<DepthHeader> InspectDepth(std::string_view bytes, uint64_t max_pixels) {
  if (bytes.size() < kHeaderSize) {
    return HeaderError(bytes.size(),
                       absl::StrCat("input of ", bytes.size(), " bytes ends inside the ",
                                    kHeaderSize, "-byte header"));
  }
  if (std::memcmp(bytes.data(), kMagic, 4) != 0) return HeaderError(0, "bad magic (not RVLD)");
  if (static_cast<uint8_t>(bytes[4]) != kVersion) {
    return HeaderError(4, absl::StrCat("unsupported version ", static_cast<uint8_t>(bytes[4])));
  }
  const uint8_t flags = static_cast<uint8_t>(bytes[5]);
  if ((flags & ~kFlagZstd) != 0) return HeaderError(5, "unknown flags");
  if (bytes[6] != 0 || bytes[7] != 0) return HeaderError(6, "reserved bytes not zero");
  DepthHeader header;
  header.width = LoadLe32(bytes.data() + 8);
  header.height = LoadLe32(bytes.data() + 12);
  if (header.width > kMaxSidePx) {
    return HeaderError(8, absl::StrCat("width ", header.width, " too large"));
  }
  if (header.height > kMaxSidePx) {
    return HeaderError(12, absl::StrCat("height ", header.height, " too large"));
  }
  const uint64_t num_pixels = static_cast<uint64_t>(header.width) * header.height;
  if (num_pixels > std::min(max_pixels, kMaxDecodedImagePixels)) {
    return HeaderError(8, absl::StrCat(header.width, "x", header.height, " = ", num_pixels,
                                       " pixels, more than the ",
                                       std::min(max_pixels, kMaxDecodedImagePixels), " allowed"));
  }
  header.rvl_bytes = LoadLe32(bytes.data() + 16);
  if (header.rvl_bytes % 4 != 0 || header.rvl_bytes > MaxRvlBytes(num_pixels)) {
    return HeaderError(16, absl::StrCat("implausible RVL size ", header.rvl_bytes));
  }
  header.payload_bytes = LoadLe32(bytes.data() + 20);
  const std::string_view payload = bytes.substr(kHeaderSize);
  if (payload.size() != header.payload_bytes) {
    return HeaderError(std::min<size_t>(bytes.size(), kHeaderSize + header.payload_bytes),
                       absl::StrCat("payload is ", payload.size(), " bytes but the header says ",
                                    header.payload_bytes));
  }
  header.zstd = (flags & kFlagZstd) != 0;
  if (!header.zstd && header.payload_bytes != header.rvl_bytes) {
    return HeaderError(20, "payload and RVL sizes differ without zstd");
  }
  if (HeaderAndPayloadCrc(bytes.substr(0, kHeaderSize), payload) !=
      LoadLe32(bytes.data() + kChecksumOffset)) {
    return HeaderError(kChecksumOffset, "checksum mismatch (corrupt header or payload)");
  }
  return header;
}

absl::StatusOr<DepthImageMm> DecodeDepth(std::string_view bytes, uint64_t max_pixels) {
  ASSIGN_OR_RETURN(const DepthHeader header, InspectDepth(bytes, max_pixels));
  const uint32_t width = header.width, height = header.height;
  const uint32_t rvl_size = header.rvl_bytes;
  const bool zstd = header.zstd;
  const std::string_view payload = bytes.substr(kHeaderSize);
  std::string rvl_buffer;
  std::string_view rvl = payload;
  if (zstd) {
    const unsigned long long content_size =
        ZSTD_getFrameContentSize(payload.data(), payload.size());
    if (content_size != rvl_size) {
      return HeaderError(kHeaderSize, "zstd frame size does not match the RVL size");
    }
    rvl_buffer.resize(rvl_size);
    const size_t decompressed =
        ZSTD_decompress(rvl_buffer.data(), rvl_buffer.size(), payload.data(), payload.size());
    if (ZSTD_isError(decompressed) || decompressed != rvl_size) {
      return HeaderError(kHeaderSize,
                         absl::StrCat("zstd payload does not decompress: ",
                                      ZSTD_isError(decompressed) ? ZSTD_getErrorName(decompressed)
                                                                 : "short output"));
    }
    rvl = rvl_buffer;
  }
  DepthImageMm depth_mm(static_cast<int>(width), static_cast<int>(height));
  // Offsets inside a zstd stream refer to the decompressed RVL words.
  if (absl::Status status = RvlDecode(rvl, absl::MakeSpan(depth_mm.data), zstd ? 0 : kHeaderSize);
      !status.ok()) {
    if (!zstd) return status;
    return absl::DataLossError(absl::StrCat(status.message(), " of the decompressed RVL stream"));
  }
  return depth_mm;
}

}  // namespace reenact
