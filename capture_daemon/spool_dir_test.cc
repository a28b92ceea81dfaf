// Where reenactd keeps its spool when --spool is not given.
#include <unistd.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "capture_daemon/daemon.h"

namespace reenact::capture {
namespace {

TEST(DefaultSpoolDir, IsNeverTheSharedTemporaryFolder) {
  // The environment of this process, put back afterwards.
  struct SavedEnv {
    std::string name;
    std::optional<std::string> value;
  };
  std::vector<SavedEnv> saved;
  for (const char* name : {"STATE_DIRECTORY", "XDG_STATE_HOME", "HOME"}) {
    const char* value = std::getenv(name);
    saved.push_back({name, value ? std::optional<std::string>(value) : std::nullopt});
  }
  ::unsetenv("STATE_DIRECTORY");
  ::unsetenv("XDG_STATE_HOME");
  ::setenv("HOME", "/home/coach", 1);
  const std::string spool = DefaultSpoolDir();
  EXPECT_FALSE(spool.rfind("/tmp", 0) == 0) << spool;
  EXPECT_EQ(spool, ::getuid() == 0 ? "/var/lib/reenactd/spool"
                                   : "/home/coach/.local/state/reenactd/spool");
  ::setenv("STATE_DIRECTORY", "/var/lib/reenactd:/var/lib/other", 1);
  EXPECT_EQ(DefaultSpoolDir(), "/var/lib/reenactd/spool");
  for (const SavedEnv& env : saved) {
    if (env.value) {
      ::setenv(env.name.c_str(), env.value->c_str(), 1);
    } else {
      ::unsetenv(env.name.c_str());
    }
  }
}

}  // namespace
}  // namespace reenact::capture
