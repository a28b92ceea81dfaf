// `reenactd`: the capture daemon. See capture_daemon/reenactd_cli.h.
#include <iostream>
#include <string>
#include <vector>

#include "capture_daemon/reenactd_cli.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  return reenact::capture::RunReenactd(args, std::cout, std::cerr);
}
