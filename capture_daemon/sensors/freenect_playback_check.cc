// Test helper: opens Kinect v1 "0" through the freenect backend, streams until
// the source ends, and writes what arrived into OUT_DIR for
// freenect_sensor_test to compare with the recording it made. Run with
// libfreenect's fakenect library (LD_LIBRARY_PATH=<libdir>/fakenect,
// FAKENECT_PATH=<recording>).
//
//   freenect_playback_check OUT_DIR
//
// OUT_DIR receives frame_<i>.depth (uint16 mm, little-endian, row-major),
// frame_<i>.rgb when the frame had colour, and summary.txt:
//   info <sensor_id> <backend> <model> <depth w> <depth h> <color w> <color h>
//   frame <index> <device_stamp_ns> <host_stamp_ns> <has_color>   (per frame)
//   end <absl status code number> <message>
// Exit code: 0 when the stream ended by itself, 1 on an open/start error,
// 2 when it did not end within 60 s.
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "capture_daemon/sensors/backends.h"

namespace {

void WriteBytes(const std::string& path, const void* data, size_t size) {
  std::ofstream out(path, std::ios::binary);
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: freenect_playback_check OUT_DIR\n");
    return 1;
  }
  const std::string out_dir = argv[1];
  auto sensors = reenact::capture::OpenFreenectSensors("0", {});
  if (!sensors.ok()) {
    std::fprintf(stderr, "open: %s\n", sensors.status().ToString().c_str());
    return 1;
  }
  auto& sensor = *sensors->front();
  const auto info = sensor.info();
  std::ofstream summary(out_dir + "/summary.txt");
  summary << "info " << info.sensor_id() << " " << info.backend() << " " << info.model() << " "
          << info.depth_width_px() << " " << info.depth_height_px() << " " << info.color_width_px()
          << " " << info.color_height_px() << "\n";
  std::mutex mutex;
  std::condition_variable ended;
  bool done = false;
  absl::Status why;
  const absl::Status started = sensor.Start(
      [&](reenact::capture::CapturedFrame frame) {
        const int64_t i = frame.frame.frame_index();
        std::lock_guard<std::mutex> lock(mutex);
        summary << "frame " << i << " " << frame.frame.device_stamp_ns() << " "
                << frame.frame.host_stamp_ns() << " " << (frame.color ? 1 : 0) << "\n";
        if (frame.depth_mm) {
          WriteBytes(absl::StrCat(out_dir, "/frame_", i, ".depth"), frame.depth_mm->data.data(),
                     frame.depth_mm->data.size() * sizeof(uint16_t));
        }
        if (frame.color) {
          WriteBytes(absl::StrCat(out_dir, "/frame_", i, ".rgb"), frame.color->data.data(),
                     frame.color->data.size());
        }
      },
      [&](const absl::Status& status) {
        std::lock_guard<std::mutex> lock(mutex);
        why = status;
        done = true;
        ended.notify_all();
      });
  if (!started.ok()) {
    std::fprintf(stderr, "start: %s\n", started.ToString().c_str());
    return 1;
  }
  bool finished = false;
  {
    std::unique_lock<std::mutex> lock(mutex);
    finished = ended.wait_for(lock, std::chrono::seconds(60), [&] { return done; });
  }
  sensor.Stop();
  std::lock_guard<std::mutex> lock(mutex);
  summary << "end " << static_cast<int>(why.code()) << " " << why.message() << "\n";
  summary.close();
  return finished ? 0 : 2;
}
