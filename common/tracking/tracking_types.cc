#include "common/tracking/tracking_types.h"

namespace reenact::tracking {

std::string_view JointStateName(JointState state) {
  switch (state) {
    case JointState::kNotTracked:
      return "not_tracked";
    case JointState::kInferred:
      return "inferred";
    case JointState::kTracked:
      return "tracked";
  }
  return "not_tracked";
}

}  // namespace reenact::tracking
