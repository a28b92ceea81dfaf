// What a reconstruction job will take of its worker's memory, estimated
// before it runs from the take's size (what the server's catalog knows of
// it) and the job's options, so that a server can refuse a job that would
// take more than its budget (reenact-server --job-memory-mb) instead of
// letting it take the machine down. Each method's options struct has
// `int64_t MemoryBytes(const TakeSize&) const` (its own large terms, built
// from the figures below); recon::JobMemoryBytes (methods.h) adds what
// every run holds.
//
// The estimates are upper bounds, not predictions: they are checked against
// the measured peak of real worker runs (methods_test.cc
// JobMemoryBytes.NeverUnderTheMeasuredPeakOfAWorker), and on small jobs
// they are a few times the peak, which costs nothing under a budget of
// gigabytes. What they must not do is let through a job that takes many
// times its estimate.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace reenact::recon {

// A take as the catalog knows it (v1::Take): no image has to be read.
struct TakeSize {
  int64_t frame_sets = 0;  // Stored frame sets (instants).
  int sensors = 1;
  int64_t file_bytes = 0;  // The take file (its encoded streams).
  double duration_s = 0.0;
  // Instants a run will use: frame_sets, or at most `max_instants` (the
  // option max_frames; 0: all).
  int64_t Instants(int max_instants) const {
    const int64_t all = std::max<int64_t>(frame_sets, 1);
    return max_instants > 0 ? std::min<int64_t>(all, max_instants) : all;
  }
};

namespace memory {

inline constexpr int64_t kMiB = int64_t{1} << 20;

// The largest frames the project reads (Kinect v2 / Azure Kinect class):
// colour 1920 x 1080 RGB, depth 512 x 424 (16-bit depth, an 8-bit actor
// mask and an 8-bit label).
inline constexpr int64_t kColourPixels = int64_t{1920} * 1080;
inline constexpr int64_t kColourFrameBytes = kColourPixels * 3;
inline constexpr int64_t kDepthPixels = int64_t{512} * 424;
inline constexpr int64_t kDepthFrameBytes = kDepthPixels * 4;

// A person's crop of a colour frame at full resolution (taller than wide,
// at most the frame).
inline constexpr int64_t kPersonCropPixels = int64_t{800} * 1080;

// The program: its libraries, the tracker's network, gRPC, the allocator's
// arenas and the loaded take's indexes (measured: 110-170 MiB resident
// before a method allocates).
inline constexpr int64_t kProgramBytes = 256 * kMiB;

// What a run holds apart from its method: the program, the take's encoded
// streams, and one colour and depth decode for each of `threads` (0: one
// per hardware thread, at most 8, as TakeFramesOptions) with colour
// decoded at 1/`colour_denominator` of its size.
inline int64_t RunBytes(const TakeSize& take, int threads, int colour_denominator) {
  const int64_t decoders = threads > 0 ? threads : 8;
  const int64_t scale = std::max(1, colour_denominator);
  // A full-size decode may precede the scaling.
  const int64_t colour = kColourFrameBytes + kColourFrameBytes / (scale * scale);
  return kProgramBytes + std::max<int64_t>(take.file_bytes, 0) +
         decoders * (colour + kDepthFrameBytes);
}

// The side BakePartTextures (texturing.h) gives a part of `triangles`
// triangles asked for `texture_size_px`: doubled (up to 4096) until every
// cell of a pair of triangles is at least 4 px.
inline int64_t GrownTextureSide(int64_t texture_size_px, int64_t triangles) {
  const auto cells = static_cast<double>(std::max<int64_t>(1, (triangles + 1) / 2));
  const int64_t grid = static_cast<int64_t>(std::ceil(std::sqrt(cells)));
  int64_t side = texture_size_px;
  while (side / grid < 4 && side < 4096) side = std::min<int64_t>(2 * side, 4096);
  return side;
}

// One baked part texture of `side` px: the colour and weight sums, the
// finished image, its JPEG and the texel-to-triangle map (about 20 bytes a
// texel).
inline int64_t BakedTextureBytes(int64_t side) { return side * side * 20; }

// A textured mesh of `triangles` triangles once the bake has split its
// vertices (three per triangle: position, normal, uv) and the triangles.
inline int64_t MeshBytes(int64_t triangles) { return triangles * (3 * 32 + 12 + 16); }

// Texture keyframes of a rigid method: `count` crops of a person (JPEG of
// colour decoded at 1/`colour_denominator`, at most `max_crop_side_px` a
// side, 0: no bound), each with its mask and every part's vertex visibility
// bits (`vertices` in all).
inline int64_t KeyframesBytes(int64_t count, int colour_denominator, int max_crop_side_px,
                              int64_t vertices) {
  const int64_t scale = std::max(1, colour_denominator);
  int64_t crop = kPersonCropPixels / (scale * scale);
  if (max_crop_side_px > 0) {
    crop = std::min<int64_t>(crop, int64_t{max_crop_side_px} * max_crop_side_px);
  }
  // JPEG at worst a third of the raw bytes; the mask a byte a pixel; the
  // bits a bit a vertex.
  return count * (crop + crop + vertices / 8 + 1024);
}

}  // namespace memory
}  // namespace reenact::recon
