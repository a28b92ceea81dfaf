// reenact-mirror: the magic mirror. The learner's mirror image beside or under
// the teacher's reenactment, turned to face the way the learner faces, with
// per-joint feedback and per-repetition reports. See clients/mirror/mirror_cli.h.
#include <sys/stat.h>

#include <iostream>
#include <string>
#include <vector>

#include "clients/mirror/mirror_cli.h"

int main(int argc, char** argv) {
  // Its cache, spools, exports and token files hold people's recordings or
  // credentials: what it creates is its user's alone (0600, folders 0700).
  ::umask(077);
  return reenact::mirror::RunMirror(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                    std::cerr);
}
