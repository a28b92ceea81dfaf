// ReadBvh on arbitrary bytes (written to a scratch file: the reader takes a
// path), then forward kinematics of the motion it returns.
#include <cstddef>
#include <cstdint>

#include "common/body/motion.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      reenact::fuzz::WriteScratchFile("motion.bvh", reenact::fuzz::AsView(data, size));
  absl::StatusOr<reenact::body::Motion> motion = reenact::body::ReadBvh(path);
  if (!motion.ok()) return 0;
  (void)motion->RestWorldFromJoints();
  if (motion->num_frames() > 0) {
    (void)motion->CanonicalPose(0);
    (void)motion->CanonicalPose(motion->num_frames() - 1);
  }
  return 0;
}
