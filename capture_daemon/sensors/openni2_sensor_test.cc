#include "capture_daemon/sensors/openni2_sensor.h"

#include <gtest/gtest.h>

#include "capture_daemon/sensors/backends.h"

namespace reenact::capture {
namespace {

TEST(Openni2Sensor, NoDeviceIsNotFound) {
  auto devices = ListOpenni2Devices();
  ASSERT_TRUE(devices.ok()) << devices.status();
  if (!devices->empty()) GTEST_SKIP() << "an OpenNI2 device is attached: " << devices->front().uri;
  auto sensors = OpenOpenni2Sensors("", {});
  ASSERT_FALSE(sensors.ok());
  EXPECT_EQ(sensors.status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(sensors.status().message(), "no OpenNI2 device found (looked for: any)");
  sensors = OpenOpenni2Sensors("any", {});
  EXPECT_EQ(sensors.status().code(), absl::StatusCode::kNotFound);
}

TEST(Openni2Sensor, UnknownUriIsNotFoundNamingIt) {
  auto sensors = OpenOpenni2Sensors("/nonexistent/recording.oni", {});
  ASSERT_FALSE(sensors.ok());
  EXPECT_EQ(sensors.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(sensors.status().message().find("looked for: /nonexistent/recording.oni"),
            std::string_view::npos)
      << sensors.status();
}

TEST(Freenect2Sensor, ReportsHowItWasBuilt) {
  auto sensors = OpenFreenect2Sensors("", {});
  if (Freenect2Built()) {
    // With libfreenect2 and no Kinect v2 attached.
    if (!sensors.ok()) {
      EXPECT_EQ(sensors.status().code(), absl::StatusCode::kNotFound);
    }
    return;
  }
  ASSERT_FALSE(sensors.ok());
  EXPECT_EQ(sensors.status().code(), absl::StatusCode::kUnimplemented);
  EXPECT_NE(sensors.status().message().find("built without libfreenect2"), std::string_view::npos);
}

}  // namespace
}  // namespace reenact::capture
