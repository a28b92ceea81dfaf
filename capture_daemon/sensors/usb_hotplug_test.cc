#include "capture_daemon/sensors/usb_hotplug.h"

#include <filesystem>
#include <set>

#include <gtest/gtest.h>

namespace reenact::capture {
namespace {

TEST(KnownUsbSensors, LooksUpSensorIds) {
  const KnownUsbSensor* kinect = LookupKnownUsbSensor(0x045e, 0x02ae);
  ASSERT_NE(kinect, nullptr);
  EXPECT_EQ(kinect->model, "kinect_v1");
  EXPECT_EQ(kinect->backend, "freenect");
  ASSERT_NE(LookupKnownUsbSensor(0x045e, 0x02d8), nullptr);
  EXPECT_EQ(LookupKnownUsbSensor(0x045e, 0x02d8)->model, "kinect_v2");
  ASSERT_NE(LookupKnownUsbSensor(0x045e, 0x097c), nullptr);
  EXPECT_EQ(LookupKnownUsbSensor(0x045e, 0x097c)->model, "azure_kinect");
  ASSERT_NE(LookupKnownUsbSensor(0x1d27, 0x0601), nullptr);
  EXPECT_EQ(LookupKnownUsbSensor(0x1d27, 0x0601)->backend, "openni2");
  ASSERT_NE(LookupKnownUsbSensor(0x2bc5, 0x0403), nullptr);
  EXPECT_EQ(LookupKnownUsbSensor(0x2bc5, 0x0403)->model, "orbbec_astra");
  // A mouse and a Microsoft id that is not a sensor.
  EXPECT_EQ(LookupKnownUsbSensor(0x046d, 0xc077), nullptr);
  EXPECT_EQ(LookupKnownUsbSensor(0x045e, 0x0040), nullptr);
}

TEST(KnownUsbSensors, TableHasNoDuplicates) {
  std::set<uint32_t> ids;
  for (const KnownUsbSensor& known : KnownUsbSensors()) {
    EXPECT_TRUE(ids.insert(known.vendor_id << 16 | known.product_id).second)
        << UsbIdString(known.vendor_id, known.product_id);
    EXPECT_FALSE(known.model.empty());
  }
  EXPECT_GE(ids.size(), 20u);
  EXPECT_EQ(UsbIdString(0x045e, 0x02ae), "045e:02ae");
}

TEST(DiffUsbDeviceLists, AnnouncesKnownArrivalsAndDepartures) {
  const UsbDeviceEntry hub{0x1d6b, 0x0002, 1, ""};
  const UsbDeviceEntry kinect{0x045e, 0x02ae, 1, "1.4"};
  const UsbDeviceEntry motor{0x045e, 0x02b0, 1, "1.2"};
  const UsbDeviceEntry xtion{0x1d27, 0x0600, 2, "3"};
  const UsbDeviceEntry mouse{0x046d, 0xc077, 1, "2"};

  auto events = DiffUsbDeviceLists({hub}, {hub, kinect, motor, mouse});
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, UsbHotplugKind::kArrived);
  EXPECT_EQ(events[0].usb_id(), "045e:02ae");
  EXPECT_EQ(events[0].port_path, "1.4");
  EXPECT_EQ(events[0].model, "kinect_v1");
  EXPECT_EQ(events[1].usb_id(), "045e:02b0");

  events = DiffUsbDeviceLists({hub, kinect, motor, mouse}, {hub, motor, xtion});
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, UsbHotplugKind::kLeft);
  EXPECT_EQ(events[0].usb_id(), "045e:02ae");
  EXPECT_EQ(events[1].kind, UsbHotplugKind::kArrived);
  EXPECT_EQ(events[1].usb_id(), "1d27:0600");
  EXPECT_EQ(events[1].bus, 2);

  // The same device moved to another port: it left one and arrived at the other.
  const UsbDeviceEntry moved{0x045e, 0x02ae, 1, "1.3"};
  events = DiffUsbDeviceLists({kinect}, {moved});
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, UsbHotplugKind::kLeft);
  EXPECT_EQ(events[1].kind, UsbHotplugKind::kArrived);
  EXPECT_EQ(events[1].port_path, "1.3");
  EXPECT_TRUE(DiffUsbDeviceLists({kinect, mouse}, {mouse, kinect}).empty());
}

TEST(UsbHotplugMonitor, StartsOrFailsCleanly) {
  UsbHotplugOptions options;
  options.poll_interval_s = 0.05;
  int calls = 0;
  auto monitor = UsbHotplugMonitor::Start([&](const UsbHotplugEvent&) { ++calls; }, options);
  if (!std::filesystem::exists("/dev/bus/usb")) {
    ASSERT_FALSE(monitor.ok());
    EXPECT_EQ(monitor.status().code(), absl::StatusCode::kUnavailable);
    EXPECT_NE(monitor.status().message().find("/dev/bus/usb"), std::string_view::npos);
    return;
  }
  if (!monitor.ok()) {
    EXPECT_EQ(monitor.status().code(), absl::StatusCode::kUnavailable) << monitor.status();
    return;
  }
  (*monitor)->Stop();
  (*monitor)->Stop();  // Idempotent.
  EXPECT_EQ(static_cast<size_t>(calls), (*monitor)->present().size());
}

TEST(UsbHotplugMonitor, RejectsBadOptions) {
  UsbHotplugOptions options;
  options.poll_interval_s = 0;
  auto monitor = UsbHotplugMonitor::Start({}, options);
  ASSERT_FALSE(monitor.ok());
  EXPECT_EQ(monitor.status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::capture
