// `reenact`: the command-line tool. See `reenact help`.
#include <iostream>
#include <string>
#include <vector>

#include "clients/cli/command.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  return reenact::cli::Dispatch(args, std::cout, std::cerr);
}
