// `reenactd`: the capture daemon. See capture_daemon/reenactd_cli.h.
#include <sys/stat.h>

#include <iostream>
#include <string>
#include <vector>

#include "capture_daemon/reenactd_cli.h"

int main(int argc, char** argv) {
  // Takes, spools, reenactments and logs hold images of people: everything
  // this process creates is its user's alone (files 0600, folders 0700).
  ::umask(077);
  std::vector<std::string> args(argv + 1, argv + argc);
  return reenact::capture::RunReenactd(args, std::cout, std::cerr);
}
