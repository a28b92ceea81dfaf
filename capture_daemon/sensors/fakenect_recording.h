// Test helper: writes a Kinect v1 recording in the format of libfreenect's
// fakenect playback library, from a known scene, so that tests can run the
// freenect backend (and the whole daemon) without hardware:
//   LD_LIBRARY_PATH=<libdir>/fakenect FAKENECT_PATH=<dir> reenactd --source freenect:0
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/freenect_sensor.h"

namespace reenact::capture::fakenect {

constexpr int kW = 640;
constexpr int kH = 480;
constexpr int kFrames = 8;
// Device stamps start 2 frames before the 32-bit counter wraps.
constexpr uint32_t kFirstTicks = 0xFFFFFFFFu - 3'000'000u;

// Raw 11-bit value whose Burrus depth is closest to `mm` (the model inverted
// here rather than borrowed from the code under test).
inline uint16_t RawForMm(double mm) {
  const double raw = (3.3309495161 - 1000.0 / mm) / 0.0030711016;
  return static_cast<uint16_t>(std::clamp(std::lround(raw), 0L, 2046L));
}

// Half the depth step of one raw unit at `mm`, plus rounding: dz/draw =
// 0.0030711016 z^2 (z in m) -> mm.
inline double ToleranceMm(double mm) {
  const double z_m = mm / 1000.0;
  return 0.5 * 0.0030711016 * z_m * z_m * 1000.0 + 1.0;
}

// The scene of frame `i`: a floor-to-wall ramp from 0.8 m (left) to 4.5 m
// (right) with a box 1.2 m away that moves 8 px per frame, and a corner with
// no measurement.
inline double SceneMm(int i, int x, int y) {
  if (x < 40 && y < 40) return 0.0;
  const int box_x = 200 + 8 * i;
  if (x >= box_x && x < box_x + 120 && y >= 150 && y < 330) return 1200.0;
  return 800.0 + 3700.0 * x / (kW - 1);
}

inline uint8_t ColorValue(int i, int x, int y, int c) {
  return static_cast<uint8_t>((x * (c + 1) + y * 3 + i * 17) & 0xff);
}

inline void WriteFile(const std::string& path, const std::string& header, const void* data,
                      size_t size) {
  std::ofstream out(path, std::ios::binary);
  out << header;
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
}

// One frame of a recording: kW x kH depth in millimetres (0: no
// measurement) and kW x kH RGB bytes.
struct Frame {
  std::vector<uint16_t> depth_mm;
  std::vector<uint8_t> rgb;
};

// Writes `frames` in fakenect's format: INDEX.txt lists one file per line,
// named <type>-<seconds>-<device ticks>.<ext>; depth files are a one-line PGM
// header followed by 640x480 native-endian uint16 raw disparities, colour
// files a one-line PPM header followed by 640x480 RGB bytes. Depth and colour
// alternate in order, the colour first on odd frames. Frames are 4 ms apart
// in host time (played fast) and 1/30 s apart in device ticks.
inline void WriteFrames(const std::string& dir, const std::vector<Frame>& frames) {
  std::ofstream index(dir + "/INDEX.txt");
  for (size_t i = 0; i < frames.size(); ++i) {
    const uint32_t depth_ticks = kFirstTicks + static_cast<uint32_t>(i) * 2'000'000u;
    const uint32_t color_ticks = depth_ticks + 30'000u;  // 0.5 ms later.
    const double t_s = 0.004 * static_cast<double>(i);
    std::vector<uint16_t> raw(kW * kH);
    for (size_t p = 0; p < raw.size(); ++p) {
      const uint16_t mm = frames[i].depth_mm[p];
      raw[p] = mm > 0 ? RawForMm(mm) : kKinectV1RawNoValue;
    }
    const std::string depth_name = absl::StrFormat("d-%f-%u.pgm", t_s, depth_ticks);
    const std::string color_name = absl::StrFormat("r-%f-%u.ppm", t_s + 0.001, color_ticks);
    WriteFile(dir + "/" + depth_name, absl::StrCat("P5 ", kW, " ", kH, " 65535\n"), raw.data(),
              raw.size() * 2);
    WriteFile(dir + "/" + color_name, absl::StrCat("P6 ", kW, " ", kH, " 255\n"),
              frames[i].rgb.data(), frames[i].rgb.size());
    if (i % 2 == 0) {
      index << depth_name << "\n" << color_name << "\n";
    } else {
      index << color_name << "\n" << depth_name << "\n";
    }
  }
}

// Writes the known scene of SceneMm / ColorValue, kFrames frames.
inline void WriteRecording(const std::string& dir) {
  std::vector<Frame> frames(kFrames);
  for (int i = 0; i < kFrames; ++i) {
    Frame& f = frames[i];
    f.depth_mm.resize(kW * kH);
    f.rgb.resize(kW * kH * 3);
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        f.depth_mm[y * kW + x] = static_cast<uint16_t>(std::lround(SceneMm(i, x, y)));
        for (int c = 0; c < 3; ++c) f.rgb[(y * kW + x) * 3 + c] = ColorValue(i, x, y, c);
      }
    }
  }
  WriteFrames(dir, frames);
}

}  // namespace reenact::capture::fakenect
