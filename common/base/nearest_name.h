// "Did you mean ...?": the known name nearest a mistyped one.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace reenact {

// Levenshtein distance (insertions, deletions and substitutions of one
// byte each cost 1) between `a` and `b`.
int EditDistance(const std::string& a, const std::string& b);

// The name of `names` nearest `typed` when it is near enough to be what was
// meant: within max(1, size / 3) edits of `typed`'s size, or one of which
// `typed` is a prefix of at least 3 bytes; the nearest first (ties: the
// first listed). nullopt when none is, or `typed` is itself a name.
std::optional<std::string> NearestName(const std::string& typed,
                                       const std::vector<std::string>& names);

}  // namespace reenact
