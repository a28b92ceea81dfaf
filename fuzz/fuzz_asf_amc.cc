// ReadAsfAmc on arbitrary bytes: the ASF skeleton up to the first NUL byte,
// the AMC motion after it (both written to scratch files: the reader takes
// paths), then forward kinematics of the motion it returns.
#include <cstddef>
#include <cstdint>

#include "common/body/motion.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto [asf, amc] = reenact::fuzz::SplitAtNul(reenact::fuzz::AsView(data, size));
  const std::string asf_path = reenact::fuzz::WriteScratchFile("skeleton.asf", asf);
  const std::string amc_path = reenact::fuzz::WriteScratchFile("motion.amc", amc.value_or(""));
  absl::StatusOr<reenact::body::Motion> motion = reenact::body::ReadAsfAmc(asf_path, amc_path);
  if (!motion.ok()) return 0;
  (void)motion->RestWorldFromJoints();
  if (motion->num_frames() > 0) {
    (void)motion->CanonicalPose(0);
    (void)motion->CanonicalPose(motion->num_frames() - 1);
  }
  return 0;
}
