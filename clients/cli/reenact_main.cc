// `reenact`: the command-line tool. See `reenact help`.
#include <sys/stat.h>

#include <iostream>
#include <string>
#include <vector>

#include "clients/cli/command.h"

int main(int argc, char** argv) {
  // Its cache, spools, exports and token files hold people's recordings or
  // credentials: what it creates is its user's alone (0600, folders 0700).
  ::umask(077);
  std::vector<std::string> args(argv + 1, argv + argc);
  return reenact::cli::Dispatch(args, std::cout, std::cerr);
}
