// The one place where absl::Status and grpc::Status are converted. RPC
// handlers return ToGrpcStatus(status) and clients turn what they receive
// back with FromGrpcStatus, so codes and messages survive the wire unchanged.
#pragma once

#include <grpcpp/support/status.h>

#include "absl/status/status.h"

namespace reenact {

grpc::Status ToGrpcStatus(const absl::Status& status);
absl::Status FromGrpcStatus(const grpc::Status& status);

}  // namespace reenact
