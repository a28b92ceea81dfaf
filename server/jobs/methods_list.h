// The reconstruction methods a job may name. The server checks submissions
// against this list without linking the reconstruction library; the worker
// (reenact-worker, which links server/recon) is the one that runs them, and
// its RunMethod answers InvalidArgument for a name it does not know, so a
// list that drifts from reenact::recon::MethodNames() fails jobs loudly
// instead of running the wrong thing. Keep the two in step.
#pragma once

#include <string>
#include <vector>

namespace reenact::server {

// thesis 3.3 (cylinders, Eq. 3.3-3.6), 3.4 (voxel carving, Eq. 3.7-3.15)
// and ch. 4 (the statistical body model, Eq. 4.4-4.8).
inline const std::vector<std::string>& JobMethodNames() {
  static const std::vector<std::string> names = {"rigid-cylinders", "rigid-carved", "body"};
  return names;
}

}  // namespace reenact::server
