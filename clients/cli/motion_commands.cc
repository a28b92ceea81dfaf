#include <ostream>

#include "clients/cli/commands.h"

namespace reenact::cli {

int RunMotionInfo(const std::vector<std::string>&, std::ostream&, std::ostream& err) {
  err << "reenact: motion info is not built yet\n";
  return kExitFailure;
}
int RunMotionJoints(const std::vector<std::string>&, std::ostream&, std::ostream& err) {
  err << "reenact: motion joints is not built yet\n";
  return kExitFailure;
}

}  // namespace reenact::cli
