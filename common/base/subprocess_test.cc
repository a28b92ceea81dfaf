#include "common/base/subprocess.h"

#include <signal.h>

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact {
namespace {

TEST(Subprocess, ReportsExitCodeAndCapturesOutputWithEnvironment) {
  const std::string dir = testing::MakeTempDir("subprocess");
  SubprocessOptions options;
  options.env["REENACT_PROBE"] = "forty-two";
  options.stdout_path = dir + "/out.txt";
  auto child = Subprocess::Start({"sh", "-c", "echo $REENACT_PROBE; exit 3"}, options);
  ASSERT_TRUE(child.ok()) << child.status();
  auto info = (*child)->Wait(10);
  ASSERT_TRUE(info.ok()) << info.status();
  EXPECT_TRUE(info->exited);
  EXPECT_EQ(info->exit_code, 3);
  std::ifstream in(dir + "/out.txt");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "forty-two\n");
}

TEST(Subprocess, SignalsEndAChildAndWaitTimesOut) {
  auto child = Subprocess::Start({"sleep", "30"});
  ASSERT_TRUE(child.ok()) << child.status();
  EXPECT_TRUE((*child)->Running());
  EXPECT_EQ((*child)->Wait(0.05).status().code(), absl::StatusCode::kDeadlineExceeded);
  ASSERT_TRUE((*child)->Signal(SIGKILL).ok());
  auto info = (*child)->Wait(10);
  ASSERT_TRUE(info.ok());
  EXPECT_FALSE(info->exited);
  EXPECT_EQ(info->signal, SIGKILL);
  EXPECT_TRUE((*child)->Signal(SIGTERM).ok());  // Already ended: fine.
}

TEST(Subprocess, MissingProgramIsNotFound) {
  auto child = Subprocess::Start({"/nonexistent/reenact-nothing"});
  EXPECT_EQ(child.status().code(), absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace reenact
