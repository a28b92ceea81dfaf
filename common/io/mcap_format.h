// Constants and little-endian helpers of the MCAP v0 container format
// (https://mcap.dev/spec), shared by McapWriter and McapReader.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace reenact::mcap_format {

// Leading and trailing magic: 0x89 "MCAP" '0' "\r\n".
inline constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);

// Every record: opcode (uint8) then content length (uint64) then content.
inline constexpr uint64_t kRecordPrefixBytes = 9;

// Record opcodes of the spec.
enum Opcode : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Footer content: summary_start, summary_offset_start (uint64), summary_crc
// (uint32).
inline constexpr uint64_t kFooterContentBytes = 20;

// CRC-32 (ISO-HDLC, the one of zlib) of `data`, continuing from `crc` (0 to
// start).
uint32_t Crc32(std::string_view data, uint32_t crc = 0);

// Appends fixed-width little-endian integers and length-prefixed strings.
void PutU8(std::string* out, uint8_t v);
void PutU16(std::string* out, uint16_t v);
void PutU32(std::string* out, uint32_t v);
void PutU64(std::string* out, uint64_t v);
// uint32 byte length, then the bytes.
void PutString(std::string* out, std::string_view s);
// Appends a record prefix (opcode, content length) and the content.
void PutRecord(std::string* out, uint8_t opcode, std::string_view content);

// Reads the fields of one record's content, failing (without reading past the
// end) when a field does not fit. `ok()` turns false after the first failure
// and every later read returns zero/empty.
class ByteCursor {
 public:
  explicit ByteCursor(std::string_view data) : data_(data) {}
  uint8_t U8();
  uint16_t U16();
  uint32_t U32();
  uint64_t U64();
  // uint32 byte length, then the bytes.
  std::string_view String();
  // `n` raw bytes.
  std::string_view Bytes(uint64_t n);
  bool ok() const { return ok_; }
  uint64_t position() const { return pos_; }
  uint64_t remaining() const { return data_.size() - pos_; }

 private:
  bool Need(uint64_t n);
  std::string_view data_;
  uint64_t pos_ = 0;
  bool ok_ = true;
};

}  // namespace reenact::mcap_format
