// Helpers the SDK's clients share for their calls (not part of the SDK's
// interface).
#pragma once

#include <chrono>
#include <cstdint>
#include <set>
#include <string>

#include <grpcpp/client_context.h>
#include <grpcpp/support/status.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "proto/grpc_status.h"

namespace reenact::client::internal {

// Sets the call's deadline `timeout_s` seconds from now.
inline void SetDeadline(grpc::ClientContext& context, double timeout_s) {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6)));
}

// The status with the peer's address in front, so that a user sees where a
// call went ("127.0.0.1:50051: ..."); OK stays OK.
inline absl::Status WithAddress(const absl::Status& s, const std::string& address) {
  if (s.ok()) return s;
  return absl::Status(s.code(), absl::StrCat(address, ": ", std::string(s.message())));
}

inline absl::Status WithAddress(const grpc::Status& status, const std::string& address) {
  return WithAddress(FromGrpcStatus(status), address);
}

// Calls `fetch` with `request` and then with each next_page_token that
// `fetch` returns, until one is empty (the List RPCs' pagination). Internal
// when the server hands back a token it gave before (no end in sight).
template <typename Request, typename Fetch>
absl::Status ForEachPage(Request request, Fetch fetch) {
  std::set<std::string> seen;
  for (;;) {
    absl::StatusOr<std::string> next = fetch(request);
    if (!next.ok()) return next.status();
    if (next->empty()) return absl::OkStatus();
    if (!seen.insert(*next).second) {
      return absl::InternalError("the server repeated a page token; the list does not end");
    }
    request.set_page_token(*next);
  }
}

}  // namespace reenact::client::internal
