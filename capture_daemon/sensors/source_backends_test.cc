#include "capture_daemon/sensors/source_backends.h"

#include <set>
#include <string>

#include <gtest/gtest.h>

#include "capture_daemon/sensors/usb_hotplug.h"

namespace reenact::capture {
namespace {

TEST(SourceBackends, EveryEntryIsCompleteAndNamedOnce) {
  std::set<std::string> names;
  for (const SourceBackend& backend : SourceBackends()) {
    SCOPED_TRACE(std::string(backend.name));
    EXPECT_TRUE(names.insert(std::string(backend.name)).second);
    EXPECT_EQ(std::string(backend.syntax.substr(0, backend.name.size() + 1)),
              std::string(backend.name) + ":");
    EXPECT_FALSE(backend.description.empty());
    // Either a default argument or a word on what is needed, never both.
    EXPECT_NE(backend.default_argument.empty(), backend.needs.empty());
    ASSERT_NE(backend.built, nullptr);
    ASSERT_NE(backend.open, nullptr);
    EXPECT_EQ(FindSourceBackend(backend.name), &backend);
    EXPECT_NE(SourceSyntaxList().find(std::string(backend.syntax)), std::string::npos);
  }
  EXPECT_EQ(FindSourceBackend("webcam"), nullptr);
  EXPECT_EQ(FindSourceBackend(""), nullptr);
  EXPECT_EQ(FindSourceBackend("freenect2")->built(), Freenect2Built());
}

// The USB id table names backends by the same names, and every hardware
// backend has devices there for hotplug to notice.
TEST(SourceBackends, UsbIdsNameHardwareBackends) {
  std::set<std::string> named;
  for (const KnownUsbSensor& known : KnownUsbSensors()) {
    if (known.backend.empty()) continue;
    const std::string name(known.backend);
    const SourceBackend* backend = FindSourceBackend(name);
    ASSERT_NE(backend, nullptr) << name;
    EXPECT_TRUE(backend->hardware) << name;
    named.insert(name);
  }
  for (const SourceBackend& backend : SourceBackends()) {
    EXPECT_EQ(backend.hardware, named.contains(std::string(backend.name))) << backend.name;
  }
}

// Opening a path that is not there is NotFound from every file backend,
// through the table's own function.
TEST(SourceBackends, FileBackendsSayNotFound) {
  for (const SourceBackend& backend : SourceBackends()) {
    if (backend.hardware) continue;
    const absl::StatusOr<SensorList> opened = backend.open("/no/such/recording", {});
    EXPECT_TRUE(absl::IsNotFound(opened.status())) << backend.name << ": " << opened.status();
  }
}

}  // namespace
}  // namespace reenact::capture
