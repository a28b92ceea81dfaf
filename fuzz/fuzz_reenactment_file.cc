// ReadReenactment on arbitrary bytes (written to a scratch file): the file,
// its checks and the conversion to plain values; then what a viewer does
// with a body-model reenactment: pose it at the first frame and turn the fit
// into a Motion.
#include <cstddef>
#include <cstdint>

#include "common/io/body_reenactment_motion.h"
#include "common/io/reenactment_convert.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      reenact::fuzz::WriteScratchFile("reenactment.mcap", reenact::fuzz::AsView(data, size));
  absl::StatusOr<reenact::Reenactment> reenactment = reenact::ReadReenactment(path);
  if (!reenactment.ok()) return 0;
  if (!reenact::ValidateReenactment(*reenactment).ok()) {
    reenact::fuzz::Fail("a converted reenactment does not validate");
  }
  if (!reenactment->is_body()) return 0;
  if (!reenactment->frames.empty()) {
    (void)reenact::PoseBodyMesh(*reenactment->body, *reenactment->frames[0].body);
  }
  if (!reenact::BodyReenactmentMotion(*reenactment).ok()) {
    reenact::fuzz::Fail("a converted body reenactment gives no Motion");
  }
  return 0;
}
