// Status helpers shared by every library: library code returns absl::Status
// or absl::StatusOr<T> across library boundaries and never aborts on input.
#pragma once

#include "absl/status/status.h"
#include "absl/status/statusor.h"

// NOLINTBEGIN(bugprone-macro-parentheses): `lhs` is a declaration
// ("auto x"), which parentheses would break.
#define REENACT_CONCAT_INNER_(a, b) a##b
#define REENACT_CONCAT_(a, b) REENACT_CONCAT_INNER_(a, b)

// Returns from the enclosing function when `expr` (an absl::Status) is not OK.
#define RETURN_IF_ERROR(expr)                          \
  do {                                                 \
    ::absl::Status _reenact_status = (expr);           \
    if (!_reenact_status.ok()) return _reenact_status; \
  } while (false)

// `ASSIGN_OR_RETURN(auto x, MakeX());` declares x from an absl::StatusOr, or
// returns its error from the enclosing function.
#define ASSIGN_OR_RETURN(lhs, rexpr) \
  ASSIGN_OR_RETURN_IMPL_(REENACT_CONCAT_(_reenact_statusor_, __LINE__), lhs, rexpr)
#define ASSIGN_OR_RETURN_IMPL_(statusor, lhs, rexpr) \
  auto statusor = (rexpr);                           \
  if (!statusor.ok()) return statusor.status();      \
  lhs = std::move(statusor).value()
// NOLINTEND(bugprone-macro-parentheses)
