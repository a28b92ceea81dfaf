// ImportMakeHuman with the skeleton (default.mhskel) from the input up to its
// first NUL byte and, after it, the skin weights (default_weights.mhw); the
// other files are those of the small synthetic asset folder
// (fuzz/makehuman_assets.h), whose mesh has 48 body vertices.
#include <cstddef>
#include <cstdint>

#include "common/body/makehuman_importer.h"
#include "fuzz/fuzz_util.h"
#include "fuzz/makehuman_assets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const reenact::fuzz::MakeHumanFiles* const fixed = [] {
    auto* files = new reenact::fuzz::MakeHumanFiles(reenact::fuzz::SmallMakeHumanFiles());
    reenact::fuzz::WriteMakeHumanFiles(reenact::fuzz::ScratchDir() + "/makehuman", *files);
    return files;
  }();
  const auto [skeleton, weights] = reenact::fuzz::SplitAtNul(reenact::fuzz::AsView(data, size));
  reenact::fuzz::MakeHumanFiles files = *fixed;
  files.skeleton = skeleton;
  files.weights = weights.value_or(fixed->weights);
  const std::string dir = reenact::fuzz::ScratchDir() + "/makehuman";
  reenact::fuzz::WriteMakeHumanFiles(dir, files);
  (void)reenact::body::ImportMakeHuman(dir);
  return 0;
}
