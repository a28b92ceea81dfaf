// McapReader on arbitrary bytes through the indexed path: the Footer, the
// Summary section and its Chunk Indexes, with recovery off, then every
// message read back through the index.
#include <cstddef>
#include <cstdint>
#include <memory>

#include "common/io/mcap_reader.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      reenact::fuzz::WriteScratchFile("summary.mcap", reenact::fuzz::AsView(data, size));
  reenact::McapReaderOptions options;
  options.allow_recovery = false;
  absl::StatusOr<std::unique_ptr<reenact::McapReader>> reader =
      reenact::McapReader::Open(path, options);
  if (!reader.ok()) return 0;
  if (!(*reader)->report().indexed) reenact::fuzz::Fail("opened without the summary");
  (void)(*reader)->ReadMessages();
  // One topic's messages: the index's per-chunk channel lists decide which
  // chunks are read.
  if (!(*reader)->channels().empty()) {
    (void)(*reader)->ReadMessages((*reader)->channels().begin()->second.topic);
  }
  return 0;
}
