// McapReader on arbitrary bytes with recovery allowed: files whose summary
// is missing or damaged (a writer that died) are scanned record by record.
// The seeds are truncated recordings, so most inputs take the scan.
#include <cstddef>
#include <cstdint>
#include <memory>

#include "common/io/mcap_reader.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      reenact::fuzz::WriteScratchFile("recovery.mcap", reenact::fuzz::AsView(data, size));
  absl::StatusOr<std::unique_ptr<reenact::McapReader>> reader = reenact::McapReader::Open(path);
  if (!reader.ok()) return 0;
  (void)(*reader)->report().Summary();
  absl::StatusOr<std::vector<reenact::McapMessage>> messages = (*reader)->ReadMessages();
  // A recovered file's message count comes from the scan itself, so reading
  // the messages again must find as many.
  if (!(*reader)->report().indexed && messages.ok() &&
      messages->size() != (*reader)->statistics().message_count) {
    reenact::fuzz::Fail("recovered message count differs from the messages read");
  }
  return 0;
}
