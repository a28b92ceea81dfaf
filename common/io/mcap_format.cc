#include "common/io/mcap_format.h"

#include <zlib.h>

namespace reenact::mcap_format {
namespace {

template <typename T>
void PutLittleEndian(std::string* out, T v) {
  for (size_t i = 0; i < sizeof(T); ++i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

}  // namespace

// CRC-32 (ISO-HDLC polynomial, as the MCAP spec requires), computed by zlib,
// whose crc32 is the same function with the running value passed through.
uint32_t Crc32(std::string_view data, uint32_t crc) {
  return static_cast<uint32_t>(
      crc32_z(crc, reinterpret_cast<const Bytef*>(data.data()), data.size()));
}

void PutU8(std::string* out, uint8_t v) { out->push_back(static_cast<char>(v)); }
void PutU16(std::string* out, uint16_t v) { PutLittleEndian(out, v); }
void PutU32(std::string* out, uint32_t v) { PutLittleEndian(out, v); }
void PutU64(std::string* out, uint64_t v) { PutLittleEndian(out, v); }

void PutString(std::string* out, std::string_view s) {
  PutU32(out, static_cast<uint32_t>(s.size()));
  out->append(s);
}

void PutRecord(std::string* out, uint8_t opcode, std::string_view content) {
  PutU8(out, opcode);
  PutU64(out, content.size());
  out->append(content);
}

bool ByteCursor::Need(uint64_t n) {
  if (!ok_ || n > remaining()) ok_ = false;
  return ok_;
}

uint8_t ByteCursor::U8() { return Need(1) ? static_cast<uint8_t>(data_[pos_++]) : 0; }

uint16_t ByteCursor::U16() {
  uint16_t lo = U8();
  return static_cast<uint16_t>(lo | (uint16_t{U8()} << 8));
}

uint32_t ByteCursor::U32() {
  if (!Need(4)) return 0;
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= uint32_t{static_cast<uint8_t>(data_[pos_ + i])} << (8 * i);
  pos_ += 4;
  return v;
}

uint64_t ByteCursor::U64() {
  if (!Need(8)) return 0;
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t{static_cast<uint8_t>(data_[pos_ + i])} << (8 * i);
  pos_ += 8;
  return v;
}

std::string_view ByteCursor::String() {
  const uint32_t n = U32();
  return Bytes(n);
}

std::string_view ByteCursor::Bytes(uint64_t n) {
  if (!Need(n)) return {};
  std::string_view v = data_.substr(pos_, n);
  pos_ += n;
  return v;
}

}  // namespace reenact::mcap_format
