// ImportMakeHuman with base.obj from the input up to its first NUL byte and,
// after it, the text of the macro targets; the other files are those of the
// small synthetic asset folder (fuzz/makehuman_assets.h).
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
  const auto [obj, target] = reenact::fuzz::SplitAtNul(reenact::fuzz::AsView(data, size));
  reenact::fuzz::MakeHumanFiles files = *fixed;
  files.obj = obj;
  files.target = target.value_or(fixed->target);
  const std::string dir = reenact::fuzz::ScratchDir() + "/makehuman";
  reenact::fuzz::WriteMakeHumanFiles(dir, files);
  (void)reenact::body::ImportMakeHuman(dir);
  return 0;
}
