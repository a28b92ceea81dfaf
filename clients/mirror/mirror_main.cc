// reenact-mirror: the magic mirror. The learner's mirror image beside or under
// the teacher's reenactment, turned to face the way the learner faces, with
// per-joint feedback and per-repetition reports. See clients/mirror/mirror_cli.h.
#include <iostream>
#include <string>
#include <vector>

#include "clients/mirror/mirror_cli.h"

int main(int argc, char** argv) {
  return reenact::mirror::RunMirror(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                    std::cerr);
}
