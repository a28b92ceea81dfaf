#include "common/io/mcap_reader.h"
#include "common/io/mcap_writer.h"

#include <sys/resource.h>

#include <cstdint>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/io/mcap_format.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

struct WrittenMessage {
  uint16_t channel_id;
  uint64_t log_time_ns;
  std::string data;
};

// What a test file holds: its messages in write order and how many of them
// each chunk took, in file order.
struct WrittenFile {
  std::vector<WrittenMessage> messages;
  std::vector<size_t> messages_per_chunk;
};

WrittenFile WriteTestFile(const std::string& path, const McapWriterOptions& options,
                          int message_count, uint32_t seed) {
  WrittenFile file;
  auto writer = McapWriter::Open(path, options);
  EXPECT_TRUE(writer.ok()) << writer.status();
  auto schema = (*writer)->AddSchema("test.Blob", "raw", "schema bytes");
  EXPECT_TRUE(schema.ok()) << schema.status();
  std::vector<uint16_t> channels;
  for (const char* topic : {"/a", "/b", "/c"}) {
    auto channel = (*writer)->AddChannel(*schema, topic, "raw", {{"topic", topic}});
    EXPECT_TRUE(channel.ok()) << channel.status();
    channels.push_back(*channel);
  }
  std::mt19937 rng(seed);
  size_t in_chunk = 0;
  for (int i = 0; i < message_count; ++i) {
    WrittenMessage m{channels[rng() % channels.size()], 1000 + 10 * static_cast<uint64_t>(i), ""};
    m.data.resize(5 + rng() % 120);
    for (char& c : m.data) c = static_cast<char>(rng() % 7);  // Compressible.
    const uint64_t before = (*writer)->bytes_written();
    EXPECT_TRUE((*writer)->WriteMessage(m.channel_id, m.log_time_ns, m.log_time_ns, m.data).ok());
    file.messages.push_back(m);
    ++in_chunk;
    if ((*writer)->bytes_written() != before) {  // A chunk was flushed.
      file.messages_per_chunk.push_back(in_chunk);
      in_chunk = 0;
    }
  }
  if (in_chunk > 0) file.messages_per_chunk.push_back(in_chunk);
  EXPECT_TRUE((*writer)->Close().ok());
  return file;
}

void ExpectMessagesEqual(const std::vector<WrittenMessage>& expected,
                         const std::vector<McapMessage>& actual) {
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(actual[i].channel_id, expected[i].channel_id) << "message " << i;
    EXPECT_EQ(actual[i].log_time_ns, expected[i].log_time_ns) << "message " << i;
    EXPECT_EQ(actual[i].data, expected[i].data) << "message " << i;
  }
}

std::string SmallChunkFile(const std::string& name, const std::string& compression,
                           WrittenFile* written, int message_count = 60) {
  const std::string path = testing::MakeTempDir(name) + "/file.mcap";
  McapWriterOptions options;
  options.chunk_size_bytes = 600;
  options.compression = compression;
  *written = WriteTestFile(path, options, message_count, 7);
  return path;
}

TEST(Crc32, MatchesStandardCheckValue) {
  // The CRC-32/ISO-HDLC check value of "123456789" from the CRC catalogue.
  EXPECT_EQ(mcap_format::Crc32("123456789"), 0xCBF43926u);
  EXPECT_EQ(mcap_format::Crc32("6789", mcap_format::Crc32("12345")), 0xCBF43926u);
}

TEST(McapWriterOptions, RejectsUnknownCompression) {
  McapWriterOptions options;
  options.compression = "lz4";
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
  options.compression = "zstd";
  options.chunk_size_bytes = 0;
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
}

TEST(McapReader, RoundTripsThroughSummary) {
  for (const std::string compression : {"zstd", ""}) {
    WrittenFile written;
    const std::string path = SmallChunkFile("mcap_roundtrip", compression, &written, 200);
    auto reader = McapReader::Open(path);
    ASSERT_TRUE(reader.ok()) << reader.status();
    EXPECT_TRUE((*reader)->report().indexed) << (*reader)->report().Summary();
    EXPECT_TRUE((*reader)->report().complete);
    EXPECT_GT(written.messages_per_chunk.size(), 5u);
    EXPECT_EQ((*reader)->chunks().size(), written.messages_per_chunk.size());
    auto messages = (*reader)->ReadMessages();
    ASSERT_TRUE(messages.ok()) << messages.status();
    ExpectMessagesEqual(written.messages, *messages);

    const McapStatistics& stats = (*reader)->statistics();
    EXPECT_EQ(stats.message_count, written.messages.size());
    EXPECT_EQ(stats.start_time_ns, written.messages.front().log_time_ns);
    EXPECT_EQ(stats.end_time_ns, written.messages.back().log_time_ns);
    ASSERT_EQ((*reader)->channels().size(), 3u);
    ASSERT_EQ((*reader)->schemas().size(), 1u);
    EXPECT_EQ((*reader)->schemas().begin()->second.data, "schema bytes");
    for (const auto& [id, channel] : (*reader)->channels()) {
      EXPECT_EQ(channel.metadata.at("topic"), channel.topic);
      std::vector<WrittenMessage> on_topic;
      for (const WrittenMessage& m : written.messages) {
        if (m.channel_id == id) on_topic.push_back(m);
      }
      EXPECT_EQ(stats.channel_message_counts.at(id), on_topic.size());
      auto filtered = (*reader)->ReadMessages(channel.topic);
      ASSERT_TRUE(filtered.ok());
      ExpectMessagesEqual(on_topic, *filtered);
    }
  }
}

TEST(McapReader, EveryTruncationYieldsTheCompleteChunks) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_truncate", "zstd", &written);
  auto full = McapReader::Open(path);
  ASSERT_TRUE(full.ok());
  const std::vector<McapChunkInfo> chunks = (*full)->chunks();
  ASSERT_EQ(chunks.size(), written.messages_per_chunk.size());
  ASSERT_GT(chunks.size(), 3u);
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  // Shrink one copy from the full size down to 0 bytes, opening it at each size.
  const std::string cut_path = path + ".cut";
  ASSERT_TRUE(WriteFileAtomically(cut_path, *bytes).ok());
  int recovered_files = 0;
  for (size_t size = bytes->size() - 1; size != static_cast<size_t>(-1); --size) {
    std::filesystem::resize_file(cut_path, size);
    auto reader = McapReader::Open(cut_path);
    if (size < mcap_format::kMagic.size()) {
      ASSERT_FALSE(reader.ok()) << "size " << size;
      EXPECT_EQ(reader.status().code(), absl::StatusCode::kDataLoss);
      EXPECT_NE(reader.status().message().find("byte offset"), std::string::npos);
      continue;
    }
    ASSERT_TRUE(reader.ok()) << "size " << size << ": " << reader.status();
    const McapReadReport& report = (*reader)->report();
    EXPECT_FALSE(report.indexed) << "size " << size;
    EXPECT_FALSE(report.summary_problem.empty()) << "size " << size;
    size_t expected_count = 0;
    for (size_t c = 0; c < chunks.size(); ++c) {
      if (chunks[c].chunk_offset + chunks[c].chunk_length <= size) {
        expected_count += written.messages_per_chunk[c];
      }
    }
    if (!report.complete) {
      EXPECT_FALSE(report.stop_reason.empty());
      EXPECT_LE(report.stop_offset, size);
    }
    auto messages = (*reader)->ReadMessages();
    ASSERT_TRUE(messages.ok()) << "size " << size << ": " << messages.status();
    const std::vector<WrittenMessage> expected(written.messages.begin(),
                                               written.messages.begin() + expected_count);
    ExpectMessagesEqual(expected, *messages);
    EXPECT_EQ((*reader)->statistics().message_count, expected_count);
    ++recovered_files;
  }
  EXPECT_EQ(recovered_files, static_cast<int>(bytes->size() - mcap_format::kMagic.size()));
}

TEST(McapReader, RefusesTruncatedFileWhenRecoveryIsOff) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_norecover", "zstd", &written);
  auto bytes = ReadFileToString(path);
  ASSERT_TRUE(bytes.ok());
  ASSERT_TRUE(WriteFileAtomically(path, bytes->substr(0, bytes->size() / 2)).ok());
  auto reader = McapReader::Open(path, McapReaderOptions{.allow_recovery = false});
  EXPECT_EQ(reader.status().code(), absl::StatusCode::kDataLoss);
}

// Flips one byte in the middle of chunk `index`'s record.
std::string CorruptChunk(const std::string& path, size_t index, uint64_t* chunk_offset) {
  auto reader = McapReader::Open(path);
  EXPECT_TRUE(reader.ok());
  const McapChunkInfo chunk = (*reader)->chunks().at(index);
  *chunk_offset = chunk.chunk_offset;
  std::string bytes = *ReadFileToString(path);
  bytes[chunk.chunk_offset + chunk.chunk_length - 20] ^= 0x5A;
  return bytes;
}

TEST(McapReader, CorruptChunkIsDataLossNamingItsOffset) {
  for (const std::string compression : {"zstd", ""}) {
    WrittenFile written;
    const std::string path = SmallChunkFile("mcap_corrupt", compression, &written);
    uint64_t chunk_offset = 0;
    const std::string bytes = CorruptChunk(path, 1, &chunk_offset);
    ASSERT_TRUE(WriteFileAtomically(path, bytes).ok());
    auto reader = McapReader::Open(path);
    ASSERT_TRUE(reader.ok()) << reader.status();
    auto messages = (*reader)->ReadMessages();
    ASSERT_EQ(messages.status().code(), absl::StatusCode::kDataLoss) << compression;
    EXPECT_NE(messages.status().message().find("byte offset " + std::to_string(chunk_offset)),
              std::string::npos)
        << messages.status();
  }
}

TEST(McapReader, RecoverySkipsCorruptChunkAndReportsIt) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_corrupt_recover", "", &written);
  uint64_t chunk_offset = 0;
  const std::string bytes = CorruptChunk(path, 1, &chunk_offset);
  ASSERT_TRUE(WriteFileAtomically(path, bytes.substr(0, bytes.size() - 30)).ok());
  auto reader = McapReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  const McapReadReport& report = (*reader)->report();
  EXPECT_FALSE(report.complete);
  ASSERT_EQ(report.skipped_chunks.size(), 1u) << report.Summary();
  EXPECT_NE(report.skipped_chunks[0].find("byte offset " + std::to_string(chunk_offset)),
            std::string::npos);
  auto messages = (*reader)->ReadMessages();
  ASSERT_TRUE(messages.ok());
  std::vector<WrittenMessage> expected = written.messages;
  const auto first = expected.begin() + written.messages_per_chunk[0];
  expected.erase(first, first + written.messages_per_chunk[1]);
  ExpectMessagesEqual(expected, *messages);
}

// Byte offset where the data section of a finished file ends (its DataEnd
// record), from the footer's summary_start.
uint64_t DataEndOffset(const std::string& bytes) {
  const size_t footer_fields = bytes.size() - mcap_format::kMagic.size() - 20;
  uint64_t summary_start = 0;
  for (int i = 7; i >= 0; --i) {
    summary_start = (summary_start << 8) | static_cast<uint8_t>(bytes[footer_fields + i]);
  }
  return summary_start - (mcap_format::kRecordPrefixBytes + 4);
}

// Appends `count` messages to `writer` on its channels in turn; returns them.
std::vector<WrittenMessage> AppendMessages(McapWriter& writer, int count, uint64_t first_time_ns) {
  std::vector<WrittenMessage> out;
  if (writer.ChannelTopics().empty()) {  // The cut took every Channel record.
    const McapSchemaId schema =
        writer.SchemaNames().empty() ? *writer.AddSchema("test.Blob", "raw", "") : 1;
    EXPECT_TRUE(writer.AddChannel(schema, "/new", "raw").ok());
  }
  const auto channels = writer.ChannelTopics();
  for (int i = 0; i < count; ++i) {
    WrittenMessage m{channels[i % channels.size()].first, first_time_ns + 10 * i,
                     "appended " + std::to_string(i)};
    EXPECT_TRUE(writer.WriteMessage(m.channel_id, m.log_time_ns, m.log_time_ns, m.data).ok());
    out.push_back(m);
  }
  return out;
}

// Every channel's sequence numbers run 0, 1, 2, ... in file order.
void ExpectDenseSequences(const std::vector<McapMessage>& messages) {
  std::map<uint16_t, uint32_t> next;
  for (const McapMessage& m : messages) {
    EXPECT_EQ(m.sequence, next[m.channel_id]++) << "channel " << m.channel_id;
  }
}

TEST(McapWriter, AppendsToFinishedFile) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_append", "zstd", &written, 120);
  const uint64_t old_size = std::filesystem::file_size(path);
  McapAppendReport report;
  McapWriterOptions options;
  options.compression = "";  // New chunks may differ from the old ones.
  auto writer = McapWriter::OpenForAppend(path, options, &report);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ(report.kept_chunks, written.messages_per_chunk.size());
  EXPECT_EQ(report.kept_messages, written.messages.size());
  EXPECT_EQ(report.kept_bytes + report.dropped_bytes, old_size);
  EXPECT_NE(report.stop_reason.find("DataEnd"), std::string::npos) << report.stop_reason;
  EXPECT_EQ((*writer)->bytes_written(), report.kept_bytes);
  ASSERT_EQ((*writer)->ChannelTopics().size(), 3u);
  ASSERT_EQ((*writer)->SchemaNames().size(), 1u);
  const std::vector<WrittenMessage> more = AppendMessages(**writer, 40, 100000);
  auto extra = (*writer)->AddChannel(1, "/d", "raw");
  ASSERT_TRUE(extra.ok());
  EXPECT_EQ(*extra, 3);
  ASSERT_TRUE((*writer)->WriteMessage(*extra, 200000, 200000, "on a new channel").ok());
  ASSERT_TRUE((*writer)->Close().ok());

  auto reader = McapReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.status();
  EXPECT_TRUE((*reader)->report().indexed) << (*reader)->report().Summary();
  std::vector<WrittenMessage> expected = written.messages;
  expected.insert(expected.end(), more.begin(), more.end());
  expected.push_back({*extra, 200000, "on a new channel"});
  auto messages = (*reader)->ReadMessages();
  ASSERT_TRUE(messages.ok()) << messages.status();
  ExpectMessagesEqual(expected, *messages);
  ExpectDenseSequences(*messages);
  const McapStatistics& stats = (*reader)->statistics();
  EXPECT_EQ(stats.message_count, expected.size());
  EXPECT_EQ(stats.start_time_ns, written.messages.front().log_time_ns);
  EXPECT_EQ(stats.end_time_ns, 200000u);
  EXPECT_EQ(stats.chunk_count, written.messages_per_chunk.size() + 1);
}

TEST(McapWriter, AppendAfterEveryTruncationKeepsWholeChunks) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_append_cut", "zstd", &written, 40);
  auto full = McapReader::Open(path);
  ASSERT_TRUE(full.ok());
  const std::vector<McapChunkInfo> chunks = (*full)->chunks();
  ASSERT_GT(chunks.size(), 2u);
  const std::string bytes = *ReadFileToString(path);
  // A chunk survives a cut when it and its Message Index records (which end
  // where the next chunk or DataEnd starts) lie before the cut.
  std::vector<uint64_t> chunk_ends;
  for (size_t c = 0; c < chunks.size(); ++c) {
    chunk_ends.push_back(c + 1 < chunks.size() ? chunks[c + 1].chunk_offset : DataEndOffset(bytes));
  }
  uint64_t header_end = 0;
  for (int i = 7; i >= 0; --i) {
    header_end =
        (header_end << 8) | static_cast<uint8_t>(bytes[mcap_format::kMagic.size() + 1 + i]);
  }
  header_end += mcap_format::kMagic.size() + mcap_format::kRecordPrefixBytes;
  const std::string cut_path = path + ".cut";
  for (size_t size = mcap_format::kMagic.size(); size < bytes.size(); ++size) {
    ASSERT_TRUE(WriteFileAtomically(cut_path, bytes.substr(0, size)).ok());
    McapAppendReport report;
    auto writer = McapWriter::OpenForAppend(cut_path, {}, &report);
    if (size < header_end) {
      EXPECT_EQ(writer.status().code(), absl::StatusCode::kDataLoss) << "size " << size;
      continue;
    }
    ASSERT_TRUE(writer.ok()) << "size " << size << ": " << writer.status();
    size_t kept = 0;
    for (size_t c = 0; c < chunks.size() && chunk_ends[c] <= size; ++c) {
      kept += written.messages_per_chunk[c];
    }
    EXPECT_EQ(report.kept_messages, kept) << "size " << size << ": " << report.stop_reason;
    EXPECT_LE(report.kept_bytes, size);
    const std::vector<WrittenMessage> more = AppendMessages(**writer, 3, 500000);
    ASSERT_TRUE((*writer)->Close().ok());
    auto reader = McapReader::Open(cut_path);
    ASSERT_TRUE(reader.ok()) << "size " << size;
    EXPECT_TRUE((*reader)->report().indexed) << "size " << size;
    std::vector<WrittenMessage> expected(written.messages.begin(), written.messages.begin() + kept);
    expected.insert(expected.end(), more.begin(), more.end());
    auto messages = (*reader)->ReadMessages();
    ASSERT_TRUE(messages.ok()) << "size " << size << ": " << messages.status();
    ExpectMessagesEqual(expected, *messages);
    ExpectDenseSequences(*messages);
  }
}

TEST(McapWriter, AppendStopsAtDamagedChunk) {
  WrittenFile written;
  const std::string path = SmallChunkFile("mcap_append_damaged", "zstd", &written);
  uint64_t chunk_offset = 0;
  const std::string bytes = CorruptChunk(path, 1, &chunk_offset);
  // Without its summary the file is scanned, and the scan finds the damage.
  ASSERT_TRUE(WriteFileAtomically(path, bytes.substr(0, DataEndOffset(bytes))).ok());
  McapAppendReport report;
  auto writer = McapWriter::OpenForAppend(path, {}, &report);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ(report.kept_bytes, chunk_offset);
  EXPECT_EQ(report.kept_messages, written.messages_per_chunk[0]);
  EXPECT_NE(report.stop_reason.find("byte offset " + std::to_string(chunk_offset)),
            std::string::npos)
      << report.stop_reason;
  const std::vector<WrittenMessage> more = AppendMessages(**writer, 5, 500000);
  ASSERT_TRUE((*writer)->Close().ok());
  auto reader = McapReader::Open(path);
  ASSERT_TRUE(reader.ok());
  std::vector<WrittenMessage> expected(written.messages.begin(),
                                       written.messages.begin() + written.messages_per_chunk[0]);
  expected.insert(expected.end(), more.begin(), more.end());
  auto messages = (*reader)->ReadMessages();
  ASSERT_TRUE(messages.ok()) << messages.status();
  ExpectMessagesEqual(expected, *messages);
}

TEST(McapWriter, AbortKeepsOnlyFlushedChunks) {
  const std::string path = testing::MakeTempDir("mcap_abort") + "/file.mcap";
  McapWriterOptions options;
  options.chunk_size_bytes = uint64_t{1} << 30;  // Chunks end only when flushed.
  auto writer = McapWriter::Open(path, options);
  ASSERT_TRUE(writer.ok());
  auto schema = (*writer)->AddSchema("test.Blob", "raw", "");
  auto channel = (*writer)->AddChannel(*schema, "/a", "raw");
  ASSERT_TRUE(channel.ok());
  for (uint64_t t = 0; t < 10; ++t) ASSERT_TRUE((*writer)->WriteMessage(*channel, t, t, "x").ok());
  ASSERT_TRUE((*writer)->Sync().ok());
  EXPECT_EQ((*writer)->pending_chunk_bytes(), 0u);
  for (uint64_t t = 10; t < 15; ++t) ASSERT_TRUE((*writer)->WriteMessage(*channel, t, t, "y").ok());
  EXPECT_GT((*writer)->pending_chunk_bytes(), 0u);
  ASSERT_TRUE((*writer)->Abort().ok());
  EXPECT_EQ((*writer)->WriteMessage(*channel, 20, 20, "z").code(),
            absl::StatusCode::kFailedPrecondition);
  auto reader = McapReader::Open(path);
  ASSERT_TRUE(reader.ok());
  EXPECT_FALSE((*reader)->report().indexed);
  EXPECT_EQ((*reader)->statistics().message_count, 10u);
}

TEST(McapWriter, OpenForAppendRejectsMissingAndForeignFiles) {
  const std::string dir = testing::MakeTempDir("mcap_append_bad");
  EXPECT_EQ(McapWriter::OpenForAppend(dir + "/missing.mcap").status().code(),
            absl::StatusCode::kNotFound);
  ASSERT_TRUE(WriteFileAtomically(dir + "/text.mcap", "not an MCAP file at all").ok());
  EXPECT_EQ(McapWriter::OpenForAppend(dir + "/text.mcap").status().code(),
            absl::StatusCode::kInvalidArgument);
  // The file is left as it was.
  EXPECT_EQ(*ReadFileToString(dir + "/text.mcap"), "not an MCAP file at all");
}

TEST(McapReader, RejectsFileThatIsNotMcap) {
  const std::string path = testing::MakeTempDir("mcap_not") + "/not.mcap";
  ASSERT_TRUE(WriteFileAtomically(path, "PK\x03\x04 this is a zip file, not MCAP").ok());
  auto reader = McapReader::Open(path);
  ASSERT_EQ(reader.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(reader.status().message().find(path), std::string::npos);
  EXPECT_NE(reader.status().message().find("byte offset 0"), std::string::npos);
  EXPECT_EQ(McapReader::Open(path + ".missing").status().code(), absl::StatusCode::kNotFound);
}

// A file whose only chunk claims `claimed_bytes` uncompressed and holds a
// zstd frame of 10 bytes that does not state its content size (a stream).
std::string ChunkClaimingMoreThanItHolds(uint64_t claimed_bytes) {
  namespace mf = mcap_format;
  std::string frame(ZSTD_compressBound(10), '\0');
  std::unique_ptr<ZSTD_CCtx, size_t (*)(ZSTD_CCtx*)> cctx(ZSTD_createCCtx(), ZSTD_freeCCtx);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 0);
  ZSTD_inBuffer in{"0123456789", 10, 0};
  ZSTD_outBuffer out{frame.data(), frame.size(), 0};
  EXPECT_EQ(ZSTD_compressStream2(cctx.get(), &out, &in, ZSTD_e_end), 0u);
  frame.resize(out.pos);
  EXPECT_EQ(ZSTD_getFrameContentSize(frame.data(), frame.size()), ZSTD_CONTENTSIZE_UNKNOWN);
  std::string bytes(mf::kMagic);
  std::string header;
  mf::PutString(&header, "");
  mf::PutString(&header, "test");
  mf::PutRecord(&bytes, mf::kHeader, header);
  std::string chunk;
  mf::PutU64(&chunk, 0);
  mf::PutU64(&chunk, 0);
  mf::PutU64(&chunk, claimed_bytes);
  mf::PutU32(&chunk, 0);
  mf::PutString(&chunk, "zstd");
  mf::PutU64(&chunk, frame.size());
  chunk += frame;
  mf::PutRecord(&bytes, mf::kChunk, chunk);
  return bytes;
}

int64_t PeakRssKb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

// A chunk's claimed size allocates nothing by itself: over the reader's
// limit it is refused at once; under it, the buffer grows only with what
// the frame produces, and the mismatch is DataLoss.
TEST(McapReader, ChunkClaimingGigabytesAllocatesNothing) {
  const std::string dir = testing::MakeTempDir("mcap_claims");
  const int64_t before_kb = PeakRssKb();
  // Recovered (a header, then the chunk, no summary): the chunk is skipped
  // and the report says why.
  const auto read = [&](uint64_t claimed_bytes, const std::string& why) {
    const std::string path = absl::StrCat(dir, "/claims_", claimed_bytes, ".mcap");
    ASSERT_TRUE(WriteFileAtomically(path, ChunkClaimingMoreThanItHolds(claimed_bytes)).ok());
    auto reader = McapReader::Open(path);
    ASSERT_TRUE(reader.ok()) << reader.status();
    auto messages = (*reader)->ReadMessages();
    ASSERT_TRUE(messages.ok()) << messages.status();
    EXPECT_TRUE(messages->empty());
    const McapReadReport& report = (*reader)->report();
    ASSERT_EQ(report.skipped_chunks.size(), 1u) << report.Summary();
    std::cout << report.skipped_chunks[0] << "\n";
    EXPECT_NE(report.skipped_chunks[0].find(why), std::string::npos);
  };
  read(uint64_t{4} << 30, "limit");
  read(uint64_t{900} << 20, "holds 10 bytes");
  const int64_t grown_mb = (PeakRssKb() - before_kb) / 1024;
  std::cout << "peak memory grew by " << grown_mb << " MB reading chunks that claim 4 GiB and "
            << "900 MiB\n";
  EXPECT_LT(grown_mb, 50);  // MB

  McapReaderOptions bad;
  bad.max_chunk_bytes = 0;
  EXPECT_EQ(McapReader::Open(dir + "/any.mcap", bad).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(McapReader, SurvivesRandomGarbageAfterTheMagic) {
  std::mt19937 rng(3);
  const std::string path = testing::MakeTempDir("mcap_garbage") + "/g.mcap";
  for (int trial = 0; trial < 200; ++trial) {
    std::string bytes(mcap_format::kMagic);
    const size_t n = rng() % 300;
    for (size_t i = 0; i < n; ++i) bytes.push_back(static_cast<char>(rng()));
    if (trial % 2 == 0 && n > 40) bytes.replace(bytes.size() - 8, 8, mcap_format::kMagic);
    ASSERT_TRUE(WriteFileAtomically(path, bytes).ok());
    auto reader = McapReader::Open(path);
    if (!reader.ok()) continue;  // An error is fine; a crash is not.
    auto messages = (*reader)->ReadMessages();
    if (messages.ok() && !(*reader)->report().indexed) {
      EXPECT_EQ(messages->size(), (*reader)->statistics().message_count);
    }
  }
}

}  // namespace
}  // namespace reenact
