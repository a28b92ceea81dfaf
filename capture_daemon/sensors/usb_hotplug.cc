#include "capture_daemon/sensors/usb_hotplug.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>
#include <utility>

#include <libusb.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"

namespace reenact::capture {
namespace {

// Ids verified against the udev rules and sources named in the header.
constexpr KnownUsbSensor kKnown[] = {
    // Kinect v1 (Xbox 360) and Kinect for Windows v1, Microsoft 045e.
    {0x045e, 0x02ae, "kinect_v1", "camera (Xbox 360 Kinect, models 1414/1473)", "freenect"},
    {0x045e, 0x02b0, "kinect_v1", "motor (Xbox 360 Kinect, model 1414)", ""},
    {0x045e, 0x02ad, "kinect_v1", "audio (Xbox 360 Kinect)", ""},
    {0x045e, 0x02bf, "kinect_v1", "camera (Kinect for Windows v1, model 1517)", "freenect"},
    {0x045e, 0x02be, "kinect_v1", "audio (Kinect for Windows v1)", ""},
    {0x045e, 0x02c3, "kinect_v1", "audio (Kinect for Windows v1, alternate id)", ""},
    {0x045e, 0x02bb, "kinect_v1", "audio (Kinect for Windows v1, alternate id)", ""},
    {0x045e, 0x02c2, "kinect_v1", "motor/hub (Kinect for Windows v1)", ""},
    // Kinect v2 (Xbox One Kinect / Kinect for Windows v2).
    {0x045e, 0x02d8, "kinect_v2", "sensor (Kinect v2)", "freenect2"},
    {0x045e, 0x02c4, "kinect_v2", "sensor (Kinect for Windows v2 developer preview)", "freenect2"},
    {0x045e, 0x02d9, "kinect_v2", "companion device (Kinect v2)", ""},
    // Azure Kinect DK.
    {0x045e, 0x097a, "azure_kinect", "USB hub (Azure Kinect)", ""},
    {0x045e, 0x097b, "azure_kinect", "USB hub (Azure Kinect)", ""},
    {0x045e, 0x097c, "azure_kinect", "depth camera (Azure Kinect)", ""},
    {0x045e, 0x097d, "azure_kinect", "4K colour camera (Azure Kinect)", ""},
    {0x045e, 0x097e, "azure_kinect", "microphone array (Azure Kinect)", ""},
    // PrimeSense reference design and Asus Xtion, vendor 1d27.
    {0x1d27, 0x0600, "primesense", "Asus Xtion PRO / PRO LIVE, PrimeSense Carmine 1.08", "openni2"},
    {0x1d27, 0x0601, "primesense", "Asus Xtion PRO LIVE (later revision) / Xtion 2", "openni2"},
    {0x1d27, 0x0609, "primesense", "PrimeSense Carmine 1.09", "openni2"},
    // Orbbec Astra family, vendor 2bc5 (Orbbec's OpenNI2 driver opens them).
    {0x2bc5, 0x0401, "orbbec_astra", "Astra", "openni2"},
    {0x2bc5, 0x0402, "orbbec_astra", "Astra S", "openni2"},
    {0x2bc5, 0x0403, "orbbec_astra", "Astra Pro", "openni2"},
    {0x2bc5, 0x0404, "orbbec_astra", "Astra Mini", "openni2"},
    {0x2bc5, 0x0407, "orbbec_astra", "Astra Mini S", "openni2"},
};

std::string LibusbError(int rc) { return absl::StrCat(libusb_error_name(rc), " (", rc, ")"); }

UsbDeviceEntry EntryOf(libusb_device* device) {
  UsbDeviceEntry entry;
  libusb_device_descriptor descriptor{};
  if (libusb_get_device_descriptor(device, &descriptor) == 0) {
    entry.vendor_id = descriptor.idVendor;
    entry.product_id = descriptor.idProduct;
  }
  entry.bus = libusb_get_bus_number(device);
  uint8_t ports[8];
  const int n = libusb_get_port_numbers(device, ports, sizeof(ports));
  std::vector<int> path;
  path.reserve(std::max(0, n));
  for (int i = 0; i < n; ++i) path.push_back(ports[i]);
  entry.port_path = absl::StrJoin(path, ".");
  return entry;
}

std::vector<UsbDeviceEntry> ListDevices(libusb_context* ctx) {
  std::vector<UsbDeviceEntry> entries;
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  for (ssize_t i = 0; i < n; ++i) entries.push_back(EntryOf(list[i]));
  if (list != nullptr) libusb_free_device_list(list, 1);
  return entries;
}

UsbHotplugEvent MakeEvent(UsbHotplugKind kind, const UsbDeviceEntry& entry,
                          const KnownUsbSensor& known) {
  UsbHotplugEvent event;
  event.kind = kind;
  event.vendor_id = entry.vendor_id;
  event.product_id = entry.product_id;
  event.bus = entry.bus;
  event.port_path = entry.port_path;
  event.model = std::string(known.model);
  event.component = std::string(known.component);
  event.backend = std::string(known.backend);
  return event;
}

class LibusbHotplugMonitor : public UsbHotplugMonitor {
 public:
  LibusbHotplugMonitor(libusb_context* ctx, UsbHotplugCallback callback, UsbHotplugOptions options)
      : ctx_(ctx), callback_(std::move(callback)), options_(options) {}

  ~LibusbHotplugMonitor() override {
    Stop();
    libusb_exit(ctx_);
  }

  absl::Status Run() {
    std::vector<UsbDeviceEntry> initial = ListDevices(ctx_);
    use_hotplug_ = !options_.force_polling && libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0;
    if (use_hotplug_) {
      const int rc = libusb_hotplug_register_callback(
          ctx_,
          static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                            LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
          static_cast<libusb_hotplug_flag>(0), LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
          LIBUSB_HOTPLUG_MATCH_ANY, &LibusbHotplugMonitor::HotplugThunk, this, &handle_);
      if (rc != LIBUSB_SUCCESS) use_hotplug_ = false;  // Fall back to polling.
    }
    thread_ = std::thread([this, initial = std::move(initial)]() mutable { Loop(initial); });
    return absl::OkStatus();
  }

  void Stop() override {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    if (stopped_) return;
    {
      std::lock_guard<std::mutex> wake_lock(wake_mutex_);
      stop_requested_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
    if (use_hotplug_) libusb_hotplug_deregister_callback(ctx_, handle_);
    stopped_ = true;
  }

  bool uses_hotplug_callbacks() const override { return use_hotplug_; }

  std::vector<UsbDeviceEntry> present() const override {
    std::lock_guard<std::mutex> lock(present_mutex_);
    return present_;
  }

 private:
  static int HotplugThunk(libusb_context*, libusb_device* device, libusb_hotplug_event event,
                          void* user) {
    auto* self = static_cast<LibusbHotplugMonitor*>(user);
    const UsbDeviceEntry entry = EntryOf(device);
    std::vector<UsbDeviceEntry> after = self->present();
    if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) {
      if (std::find(after.begin(), after.end(), entry) == after.end()) after.push_back(entry);
    } else {
      after.erase(std::remove(after.begin(), after.end(), entry), after.end());
    }
    self->Apply(after);
    return 0;  // Stay registered.
  }

  // Announces the difference between the known devices present and `after`.
  void Apply(const std::vector<UsbDeviceEntry>& after) {
    std::vector<UsbHotplugEvent> events;
    {
      std::lock_guard<std::mutex> lock(present_mutex_);
      events = DiffUsbDeviceLists(present_, after);
      present_.clear();
      for (const auto& entry : after) {
        if (LookupKnownUsbSensor(entry.vendor_id, entry.product_id) != nullptr)
          present_.push_back(entry);
      }
    }
    if (callback_) {
      for (const auto& event : events) callback_(event);
    }
  }

  void Loop(const std::vector<UsbDeviceEntry>& initial) {
    if (options_.announce_present) {
      Apply(initial);
    } else {
      std::lock_guard<std::mutex> lock(present_mutex_);
      for (const auto& entry : initial) {
        if (LookupKnownUsbSensor(entry.vendor_id, entry.product_id) != nullptr)
          present_.push_back(entry);
      }
    }
    while (true) {
      if (use_hotplug_) {
        {
          std::lock_guard<std::mutex> lock(wake_mutex_);
          if (stop_requested_) return;
        }
        timeval timeout{0, 100'000};
        libusb_handle_events_timeout_completed(ctx_, &timeout, nullptr);
      } else {
        std::unique_lock<std::mutex> lock(wake_mutex_);
        const auto interval = std::chrono::duration<double>(options_.poll_interval_s);
        if (wake_.wait_for(lock, interval, [this] { return stop_requested_; })) return;
        lock.unlock();
        Apply(ListDevices(ctx_));
      }
    }
  }

  libusb_context* ctx_;
  UsbHotplugCallback callback_;
  UsbHotplugOptions options_;
  bool use_hotplug_ = false;
  libusb_hotplug_callback_handle handle_ = 0;
  std::thread thread_;
  std::mutex stop_mutex_;
  bool stopped_ = false;
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stop_requested_ = false;
  mutable std::mutex present_mutex_;
  std::vector<UsbDeviceEntry> present_;
};

}  // namespace

absl::Span<const KnownUsbSensor> KnownUsbSensors() { return absl::MakeConstSpan(kKnown); }

const KnownUsbSensor* LookupKnownUsbSensor(uint16_t vendor_id, uint16_t product_id) {
  for (const KnownUsbSensor& known : kKnown) {
    if (known.vendor_id == vendor_id && known.product_id == product_id) return &known;
  }
  return nullptr;
}

std::string UsbIdString(uint16_t vendor_id, uint16_t product_id) {
  return absl::StrFormat("%04x:%04x", vendor_id, product_id);
}

std::string UsbHotplugEvent::ToString() const {
  return absl::StrCat(kind == UsbHotplugKind::kArrived ? "arrived " : "left ", usb_id(), " ", model,
                      " ", component, " on bus ", bus, " port ",
                      port_path.empty() ? "-" : port_path);
}

std::vector<UsbHotplugEvent> DiffUsbDeviceLists(const std::vector<UsbDeviceEntry>& before,
                                                const std::vector<UsbDeviceEntry>& after) {
  auto contains = [](const std::vector<UsbDeviceEntry>& list, const UsbDeviceEntry& e) {
    return std::find(list.begin(), list.end(), e) != list.end();
  };
  std::vector<UsbHotplugEvent> events;
  for (const auto& entry : before) {
    const KnownUsbSensor* known = LookupKnownUsbSensor(entry.vendor_id, entry.product_id);
    if (known != nullptr && !contains(after, entry)) {
      events.push_back(MakeEvent(UsbHotplugKind::kLeft, entry, *known));
    }
  }
  for (const auto& entry : after) {
    const KnownUsbSensor* known = LookupKnownUsbSensor(entry.vendor_id, entry.product_id);
    if (known != nullptr && !contains(before, entry)) {
      events.push_back(MakeEvent(UsbHotplugKind::kArrived, entry, *known));
    }
  }
  return events;
}

absl::Status UsbHotplugOptions::Validate() const {
  if (!(poll_interval_s > 0 && poll_interval_s <= 3600)) {
    return absl::InvalidArgumentError("poll_interval_s must be in (0, 3600] seconds");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<UsbHotplugMonitor>> UsbHotplugMonitor::Start(
    UsbHotplugCallback callback, const UsbHotplugOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  std::error_code ec;
  if (!std::filesystem::exists("/dev/bus/usb", ec)) {
    return absl::UnavailableError(
        "USB hotplug unavailable: /dev/bus/usb does not exist (no USB devices are visible here, "
        "e.g. a container started without them); sensors will not be announced");
  }
  libusb_context* ctx = nullptr;
  if (const int rc = libusb_init(&ctx); rc != LIBUSB_SUCCESS) {
    return absl::UnavailableError(
        absl::StrCat("USB hotplug unavailable: libusb_init failed: ", LibusbError(rc)));
  }
  auto monitor = std::make_unique<LibusbHotplugMonitor>(ctx, std::move(callback), options);
  if (absl::Status started = monitor->Run(); !started.ok()) return started;
  return monitor;
}

}  // namespace reenact::capture
