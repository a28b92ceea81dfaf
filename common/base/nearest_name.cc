#include "common/base/nearest_name.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace reenact {

int EditDistance(const std::string& a, const std::string& b) {
  // One row of the dynamic programme at a time.
  std::vector<int> row(b.size() + 1);
  std::iota(row.begin(), row.end(), 0);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diagonal = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::optional<std::string> NearestName(const std::string& typed,
                                       const std::vector<std::string>& names) {
  if (typed.empty()) return std::nullopt;
  const int limit = std::max(1, static_cast<int>(typed.size()) / 3);
  std::optional<std::string> best;
  int best_distance = std::numeric_limits<int>::max();
  for (const std::string& name : names) {
    if (name == typed) return std::nullopt;
    int distance = EditDistance(typed, name);
    // A prefix ("--reen" for "--reenactment") counts as one edit.
    if (typed.size() >= 3 && name.rfind(typed, 0) == 0) distance = std::min(distance, 1);
    if (distance <= limit && distance < best_distance) {
      best_distance = distance;
      best = name;
    }
  }
  return best;
}

}  // namespace reenact
