// libav's logging, shared by the video reader and writer: libav writes to
// stderr by default and has one log callback per process. InstallQuietAvLog
// replaces it, once, with one that prints nothing and keeps the last error
// logged on each thread, which TakeLastAvError hands to a returned status.
#pragma once

#include <string>

namespace reenact {

// Installs the quiet callback (once per process; later calls do nothing).
void InstallQuietAvLog();

// The last error libav logged on this thread since the previous call, or
// an empty string; clears it.
std::string TakeLastAvError();

}  // namespace reenact
