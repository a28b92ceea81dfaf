// Plain image containers shared by every library: row-major, interleaved
// channels, no padding. Depth is uint16 millimetres with 0 meaning "no
// measurement" (Kinect convention).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace reenact {

// Most pixels any decoder in Reenact allocates for one image (8192 x 8192,
// 128 MiB of depth): a header that states more is refused before anything
// is allocated, whatever the file or message around it. Ingest has its own,
// lower, configurable cap (FrameSetLimits::max_image_pixels).
inline constexpr uint64_t kMaxDecodedImagePixels = uint64_t{1} << 26;

template <typename T, int kChannels>
struct Image {
  int width = 0;
  int height = 0;
  std::vector<T> data;  // width * height * kChannels values.

  static constexpr int channels() { return kChannels; }
  Image() = default;
  Image(int w, int h, T fill = T{})
      : width(w), height(h), data(static_cast<size_t>(w) * h * kChannels, fill) {}
  bool empty() const { return data.empty(); }
  size_t num_pixels() const { return static_cast<size_t>(width) * height; }
  T& at(int x, int y, int c = 0) {
    return data[(static_cast<size_t>(y) * width + x) * kChannels + c];
  }
  const T& at(int x, int y, int c = 0) const {
    return data[(static_cast<size_t>(y) * width + x) * kChannels + c];
  }
  bool operator==(const Image& o) const {
    return width == o.width && height == o.height && data == o.data;
  }
};

using DepthImageMm = Image<uint16_t, 1>;  // Millimetres, 0 = invalid.
using RgbImage = Image<uint8_t, 3>;       // sRGB, R G B.
using MaskImage = Image<uint8_t, 1>;      // 0 = background, else body id.
using FloatImage = Image<float, 1>;

}  // namespace reenact
