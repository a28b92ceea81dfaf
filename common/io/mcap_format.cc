#include "common/io/mcap_format.h"

#include <array>

namespace reenact::mcap_format {
namespace {

std::array<uint32_t, 256> MakeCrcTable() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}

template <typename T>
void PutLittleEndian(std::string* out, T v) {
  for (size_t i = 0; i < sizeof(T); ++i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

}  // namespace

uint32_t Crc32(std::string_view data, uint32_t crc) {
  static const std::array<uint32_t, 256> kTable = MakeCrcTable();
  uint32_t c = crc ^ 0xFFFFFFFFu;
  for (unsigned char byte : data) c = kTable[(c ^ byte) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
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
