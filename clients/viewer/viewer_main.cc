// reenact-viewer: watch a reenactment from any side (orbit window), over the
// live camera image where it was captured (AR), or render it headless to
// PNG frames and an MP4. See clients/viewer/viewer_cli.h.
#include <sys/stat.h>

#include <iostream>
#include <string>
#include <vector>

#include "clients/viewer/viewer_cli.h"

int main(int argc, char** argv) {
  // Its cache, spools, exports and token files hold people's recordings or
  // credentials: what it creates is its user's alone (0600, folders 0700).
  ::umask(077);
  return reenact::viewer::RunViewer(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                    std::cerr);
}
