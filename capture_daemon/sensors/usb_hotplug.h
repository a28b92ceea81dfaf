// USB hotplug of RGB-D sensors: a monitor thread that announces when a known
// sensor is plugged in or pulled out, so reenactd can open or retire it while
// it runs.
//
// The monitor uses libusb-1.0's hotplug callbacks where the platform has them
// (LIBUSB_CAP_HAS_HOTPLUG) and otherwise polls the device list once a second
// and diffs it (DiffUsbDeviceLists). Only devices in KnownUsbSensors() are
// announced. Where USB is not visible at all (a container without
// /dev/bus/usb) Start fails with Unavailable and the daemon runs on without
// hotplug.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/types/span.h"

namespace reenact::capture {

// A USB vendor:product id of a sensor (or one of its sub-devices).
struct KnownUsbSensor {
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  // Our model name, as in SensorInfo.model: "kinect_v1", "kinect_v2",
  // "azure_kinect", "primesense", "orbbec_astra".
  std::string_view model;
  // The sub-device and product, e.g. "camera (Xbox 360 Kinect, models
  // 1414/1473)".
  std::string_view component;
  // Backend that opens it ("freenect", "freenect2", "openni2"), or empty when
  // reenactd has none (Azure Kinect) or the id is not the one to open (a
  // motor, hub or audio device).
  std::string_view backend;
};

// The table of known ids. Sources: libfreenect's udev rules and
// src/freenect_internal.h (Kinect v1 and Kinect for Windows), libfreenect2's
// 90-kinect2.rules (Kinect v2), the Azure Kinect Sensor SDK's 99-k4a.rules,
// OpenNI2's 60-libopenni2-0.rules as Debian installs it (PrimeSense/Asus,
// vendor 1d27) and Orbbec's 56-orbbec-usb.rules (vendor 2bc5).
absl::Span<const KnownUsbSensor> KnownUsbSensors();

// The table entry of vendor:product, or nullptr for an unknown device.
const KnownUsbSensor* LookupKnownUsbSensor(uint16_t vendor_id, uint16_t product_id);

// "vvvv:pppp" in lower-case hex.
std::string UsbIdString(uint16_t vendor_id, uint16_t product_id);

// One device on the bus as the monitor sees it.
struct UsbDeviceEntry {
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  int bus = 0;
  // Port numbers from the root hub, e.g. "1.4.2" (empty for a root hub).
  std::string port_path;
  // Identity on the bus: a device re-plugged into the same port with the
  // same ids is the same entry.
  bool operator==(const UsbDeviceEntry& o) const {
    return vendor_id == o.vendor_id && product_id == o.product_id && bus == o.bus &&
           port_path == o.port_path;
  }
};

enum class UsbHotplugKind { kArrived, kLeft };

struct UsbHotplugEvent {
  UsbHotplugKind kind = UsbHotplugKind::kArrived;
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  int bus = 0;
  std::string port_path;
  // From the KnownUsbSensor entry.
  std::string model;
  std::string component;
  std::string backend;

  std::string usb_id() const { return UsbIdString(vendor_id, product_id); }
  // e.g. "arrived 045e:02ae kinect_v1 camera (...) on bus 1 port 1.4".
  std::string ToString() const;
};

// Events for the known sensors that are in `after` but not `before`
// (arrived) and in `before` but not `after` (left), departures first. Unknown
// devices are ignored.
std::vector<UsbHotplugEvent> DiffUsbDeviceLists(const std::vector<UsbDeviceEntry>& before,
                                                const std::vector<UsbDeviceEntry>& after);

// Called on the monitor's thread.
using UsbHotplugCallback = std::function<void(const UsbHotplugEvent& event)>;

struct UsbHotplugOptions {
  // Poll the device list even where hotplug callbacks exist.
  bool force_polling = false;
  // Interval of the polling fallback, seconds (> 0).
  double poll_interval_s = 1.0;
  // Announce the known sensors already plugged in as arrivals when starting.
  bool announce_present = true;

  absl::Status Validate() const;
};

class UsbHotplugMonitor {
 public:
  // Starts the monitor thread. Unavailable (with the reason) when USB cannot
  // be watched here: no /dev/bus/usb, or libusb fails to initialise.
  static absl::StatusOr<std::unique_ptr<UsbHotplugMonitor>> Start(
      UsbHotplugCallback callback, const UsbHotplugOptions& options = {});
  // Stops and joins the thread.
  virtual ~UsbHotplugMonitor() = default;
  // Stops and joins the thread; idempotent. No callback runs afterwards.
  virtual void Stop() = 0;
  // True when libusb's hotplug callbacks are used, false when polling.
  virtual bool uses_hotplug_callbacks() const = 0;
  // The known sensors plugged in now.
  virtual std::vector<UsbDeviceEntry> present() const = 0;
};

}  // namespace reenact::capture
