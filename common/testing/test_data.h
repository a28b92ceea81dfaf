// Where tests find the shared real test data (../shared/data beside the
// checkout, or $REENACT_TEST_DATA_DIR). Tests fail with a clear message when a
// file is missing rather than passing silently.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

namespace reenact::testing {

inline std::string TestDataDir() {
  if (const char* env = std::getenv("REENACT_TEST_DATA_DIR"); env && *env) return env;
  return REENACT_TEST_DATA_DIR;
}

// Absolute path of `relative` under the shared data folder.
inline std::string TestDataPath(const std::string& relative) {
  return (std::filesystem::path(TestDataDir()) / relative).string();
}

// A fresh empty folder for one test's outputs.
inline std::string MakeTempDir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("reenact_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

}  // namespace reenact::testing

// Fails the current test when a shared data file is absent.
#define REENACT_REQUIRE_TEST_FILE(path)         \
  ASSERT_TRUE(std::filesystem::exists(path))    \
      << "missing shared test data: " << (path) \
      << " (expected ../shared/data beside the checkout or $REENACT_TEST_DATA_DIR)"
