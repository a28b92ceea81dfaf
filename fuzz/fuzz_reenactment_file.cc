// ReadReenactmentFile on arbitrary bytes (written to a scratch file), then
// what a viewer does with a body-model reenactment: decode the mesh, pose it
// at the first frame and turn the fit into a Motion.
#include <cstddef>
#include <cstdint>

#include "common/io/body_reenactment.h"
#include "common/io/body_reenactment_motion.h"
#include "common/io/reenactment_file.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      reenact::fuzz::WriteScratchFile("reenactment.mcap", reenact::fuzz::AsView(data, size));
  absl::StatusOr<reenact::ReenactmentData> reenactment = reenact::ReadReenactmentFile(path);
  if (!reenactment.ok() || !reenactment->is_body()) return 0;
  absl::StatusOr<reenact::DecodedBodyMesh> mesh = reenact::DecodeBodyMesh(reenactment->body[0]);
  if (!mesh.ok()) reenact::fuzz::Fail("a validated reenactment's body mesh does not decode");
  if (!reenactment->frames.empty()) {
    (void)reenact::PoseBodyMesh(*mesh, reenactment->frames[0].body());
  }
  (void)reenact::BodyReenactmentMotion(*reenactment);
  return 0;
}
