// Images of a board (board_spec.h): a page to print at a stated resolution,
// and a texture of known metric extent to draw the board in a 3D scene.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/board/board_spec.h"

namespace reenact::board {

// Options of RenderBoardForPrint.
struct PrintOptions {
  int dpi = 300;           // Printer resolution, dots per inch (50..600).
  double margin_m = 0.02;  // White border around the marker grid, metres (>= one marker cell
                           // keeps the outer markers detectable).
  bool caption = true;     // Print the spec and sizes in the bottom border when it fits.

  // InvalidArgument for a resolution outside 50..600 or a negative or
  // non-finite margin.
  absl::Status Validate() const;
};

// A printable page: black markers on white, the board's top row at the top.
struct BoardPrint {
  RgbImage image;        // sRGB, grey levels only, top row first.
  int dpi = 0;           // The resolution it must be printed at (100% scale).
  double width_m = 0.0;  // Physical size of the whole image at `dpi`, metres.
  double height_m = 0.0;
};

// Draws `spec` for printing: each pixel is black or white by the marker cell
// under its centre, with the board centre at the image centre, so every edge
// lands within half a dot of its metric position. The caption (the spec text,
// the marker side and the frame convention) goes in the bottom border, outside
// the markers. InvalidArgument for a bad spec or options, or a page of over
// 100 million pixels (A3 at 600 dpi has 65 million).
absl::StatusOr<BoardPrint> RenderBoardForPrint(const BoardSpec& spec,
                                               const PrintOptions& options = {});

// The page as a greyscale PNG whose pHYs chunk records the resolution, so
// that printing at 100% gives the metric size. Internal when encoding fails.
absl::StatusOr<std::string> EncodePrintPng(const BoardPrint& print);

// Options of RenderBoardTexture.
struct TextureOptions {
  double texels_per_m = 4000.0;  // Resolution, texels per metre (100..20000).
  double margin_m = 0.02;        // White paper border around the marker grid, metres.
  int supersampling = 4;         // Samples per texel side (1..8) for antialiased edges.

  // InvalidArgument for values outside the stated ranges.
  absl::Status Validate() const;
};

// The board as a texture: a flat sheet centred on the board origin, spanning
// X in [-width_m/2, width_m/2] and Z in [-depth_m/2, depth_m/2] at y = 0. The
// image's top row lies at Z = -depth_m/2 and its left column at X = -width_m/2,
// i.e. texture uv (0, 0) (bottom-left, OffscreenRenderer convention) is at
// (-width_m/2, 0, +depth_m/2) and uv (1, 1) at (+width_m/2, 0, -depth_m/2).
struct BoardTexture {
  RgbImage image_srgb;   // Edges antialiased by coverage in linear light.
  double width_m = 0.0;  // Extent along X, metres (the grid plus both margins).
  double depth_m = 0.0;  // Extent along Z, metres.
};

// Draws `spec` as a texture. InvalidArgument for a bad spec or options, or a
// texture over 16384 texels on a side.
absl::StatusOr<BoardTexture> RenderBoardTexture(const BoardSpec& spec,
                                                const TextureOptions& options = {});

}  // namespace reenact::board
