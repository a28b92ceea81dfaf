// reenact-viewer: watch a reenactment from any side (orbit window), over the
// live camera image where it was captured (AR), or render it headless to
// PNG frames and an MP4. See clients/viewer/viewer_cli.h.
#include <iostream>
#include <string>
#include <vector>

#include "clients/viewer/viewer_cli.h"

int main(int argc, char** argv) {
  return reenact::viewer::RunViewer(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                    std::cerr);
}
