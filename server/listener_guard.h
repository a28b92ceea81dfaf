// What keeps reenact-server's gRPC port answering when the process runs out
// of file descriptors (thousands of connections that never start TLS, say).
//
// gRPC 1.51's listener stops for good when accept4() fails with anything
// but EAGAIN or ECONNABORTED: after "Failed accept4: Too many open files"
// it never accepts again, though the process, its health service and its
// metrics go on as if it served. Three things answer that:
//  - the soft descriptor limit is raised to the hard one at start
//    (RaiseDescriptorLimit), and connections that do not finish their TLS
//    and HTTP/2 handshake within a few seconds are closed (server.cc), so an
//    attack must be large and fast to exhaust the table at all;
//  - gRPC's own error log is read (WatchGrpcLog): the line of a failed
//    accept tells that the listener has stopped;
//  - reenact-server then reports NOT_SERVING, stops gracefully (every frame
//    set acknowledged is stored) and starts itself again in the same process
//    (execv of itself, on the ports it had: PinnedArguments), so it answers
//    again within seconds without waiting for a supervisor.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace reenact::server {

// Raises the soft limit on open descriptors to the hard limit; returns the
// soft limit in force afterwards (-1 when it cannot be read).
int64_t RaiseDescriptorLimit();

// The process's open descriptors now (entries of /proc/self/fd); -1 when it
// cannot be read.
int64_t OpenDescriptorCount();

// Routes gRPC's error lines into the structured log (event "grpc_error")
// instead of bare stderr text, and calls `listener_stopped` (from whatever
// thread gRPC logs on; keep it short and non-blocking) each time one of
// them says that a listener failed to accept. Process-wide; a later call
// replaces the callback.
void WatchGrpcLog(std::function<void()> listener_stopped);

// Whether a gRPC log line reports that a listener failed to accept.
bool IsListenerFailure(const std::string& message);

// `argv` (argv[0] first) with the value of each flag of `pinned` replaced,
// in both forms "--flag VALUE" and "--flag=VALUE"; flags not present are
// left out. Used to start the server again on the ports it had bound (an
// address with port 0 would pick new ones).
std::vector<std::string> PinnedArguments(const std::vector<std::string>& argv,
                                         const std::map<std::string, std::string>& pinned);

// Replaces the process image with `argv` (argv[0]: the program's path as
// given; /proc/self/exe is executed) after marking every descriptor above
// stderr close-on-exec and unblocking every signal. Returns only on failure,
// with the reason.
std::string ExecSelf(const std::vector<std::string>& argv);

}  // namespace reenact::server
