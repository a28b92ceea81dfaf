#include "common/board/board_image.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <zlib.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/board/aruco_dictionary.h"

namespace reenact::board {
namespace {

constexpr double kMetresPerInch = 0.0254;

// Answers "is this board point black?" for a valid spec.
class BoardRaster {
 public:
  static absl::StatusOr<BoardRaster> Create(const BoardSpec& spec) {
    RETURN_IF_ERROR(spec.Validate());
    ASSIGN_OR_RETURN(cv::Ptr<cv::aruco::Dictionary> dictionary,
                     internal::GetArucoDictionary(spec.dictionary));
    BoardRaster raster(spec, dictionary->markerSize + 2);
    for (int i = 0; i < spec.num_markers(); ++i) {
      cv::Mat cells;  // One pixel per cell, border included; 0 black, 255 white.
      dictionary->drawMarker(spec.first_marker_id + i, raster.cells_per_side_, cells, 1);
      raster.marker_cells_.push_back(cells);
    }
    return raster;
  }

  // True when the board point (x_m, z_m) (board frame, y = 0) is black.
  bool IsBlack(double x_m, double z_m) const {
    const double u = x_m + half_width_m_;
    const double v = z_m + half_depth_m_;
    if (u < 0.0 || v < 0.0) return false;
    const int column = static_cast<int>(u / pitch_m_);
    const int row = static_cast<int>(v / pitch_m_);
    if (column >= spec_.columns || row >= spec_.rows) return false;
    const double du = u - column * pitch_m_;
    const double dv = v - row * pitch_m_;
    if (du >= spec_.marker_side_m || dv >= spec_.marker_side_m) return false;
    const int n = cells_per_side_;
    const int cell_x = std::min(n - 1, static_cast<int>(du / spec_.marker_side_m * n));
    const int cell_y = std::min(n - 1, static_cast<int>(dv / spec_.marker_side_m * n));
    return marker_cells_[row * spec_.columns + column].at<uint8_t>(cell_y, cell_x) < 128;
  }

 private:
  BoardRaster(const BoardSpec& spec, int cells_per_side)
      : spec_(spec),
        cells_per_side_(cells_per_side),
        pitch_m_(spec.marker_side_m + spec.marker_gap_m),
        half_width_m_(0.5 * spec.width_m()),
        half_depth_m_(0.5 * spec.depth_m()) {}

  BoardSpec spec_;
  int cells_per_side_;
  double pitch_m_;
  double half_width_m_;
  double half_depth_m_;
  std::vector<cv::Mat> marker_cells_;
};

// sRGB encoding of a linear intensity in [0, 1], as 0..255.
uint8_t LinearToSrgb8(double linear) {
  const double srgb =
      linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
  return static_cast<uint8_t>(std::clamp(std::lround(255.0 * srgb), 0L, 255L));
}

// Rasterises the board into a width_px x height_px greyscale image at
// `pixels_per_m`, board centre at the image centre, `samples` x `samples`
// samples per pixel averaged in linear light.
cv::Mat Rasterise(const BoardRaster& raster, int width_px, int height_px, double pixels_per_m,
                  int samples) {
  cv::Mat grey(height_px, width_px, CV_8UC1);
  const double inv_ppm = 1.0 / pixels_per_m;
  for (int j = 0; j < height_px; ++j) {
    uint8_t* row = grey.ptr<uint8_t>(j);
    for (int i = 0; i < width_px; ++i) {
      int black = 0;
      for (int sj = 0; sj < samples; ++sj) {
        const double z_m = (j + (sj + 0.5) / samples - 0.5 * height_px) * inv_ppm;
        for (int si = 0; si < samples; ++si) {
          const double x_m = (i + (si + 0.5) / samples - 0.5 * width_px) * inv_ppm;
          black += raster.IsBlack(x_m, z_m) ? 1 : 0;
        }
      }
      row[i] = LinearToSrgb8(1.0 - static_cast<double>(black) / (samples * samples));
    }
  }
  return grey;
}

RgbImage GreyToRgb(const cv::Mat& grey) {
  RgbImage image(grey.cols, grey.rows);
  for (int j = 0; j < grey.rows; ++j) {
    const uint8_t* row = grey.ptr<uint8_t>(j);
    for (int i = 0; i < grey.cols; ++i) {
      for (int c = 0; c < 3; ++c) image.at(i, j, c) = row[i];
    }
  }
  return image;
}

// Writes `lines` left-aligned in the bottom half of the bottom border, shrunk
// to fit the width, so the half next to the grid stays white (the outer
// markers need a quiet zone). Draws nothing when the text would be unreadable.
void DrawCaption(const std::vector<std::string>& lines, double margin_px, cv::Mat* page) {
  constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
  const double line_px = 0.18 * margin_px;  // Baseline to baseline.
  int base = 0;
  const double unit_height_px = cv::getTextSize("Ag", kFont, 1.0, 1, &base).height;
  double scale = line_px / 1.6 / unit_height_px;
  for (const std::string& line : lines) {
    const double width_px = cv::getTextSize(line, kFont, 1.0, 1, &base).width;
    scale = std::min(scale, (page->cols - 2.0 * margin_px) / width_px);
  }
  if (scale * unit_height_px < 8.0) return;
  const int thickness = std::max(1, static_cast<int>(std::lround(scale * 1.5)));
  double baseline_y = page->rows - 0.2 * margin_px - (lines.size() - 1) * line_px;
  for (const std::string& line : lines) {
    cv::putText(*page, line, cv::Point(static_cast<int>(margin_px), static_cast<int>(baseline_y)),
                kFont, scale, cv::Scalar(0), thickness, cv::LINE_AA);
    baseline_y += line_px;
  }
}

std::vector<std::string> CaptionLines(const BoardSpec& spec, int dpi) {
  return {
      absl::StrFormat("%s   marker side %g mm, grid %g x %g mm: print at 100%% (%d dpi)",
                      FormatBoardSpec(spec), spec.marker_side_m * 1e3, spec.width_m() * 1e3,
                      spec.depth_m() * 1e3, dpi),
      "face up on the floor: origin at the grid centre, +X right, +Z down this page, +Y up",
  };
}

void AppendBigEndian32(uint32_t value, std::string* out) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<char>(value >> shift));
}

// A PNG pHYs chunk: pixels per metre in x and y, unit 1 (metre).
std::string PhysChunk(uint32_t pixels_per_m) {
  std::string body = "pHYs";
  AppendBigEndian32(pixels_per_m, &body);
  AppendBigEndian32(pixels_per_m, &body);
  body.push_back('\x01');
  std::string chunk;
  AppendBigEndian32(9, &chunk);  // Data length, excluding the type.
  chunk += body;
  const uLong crc =
      crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(body.data()), body.size());
  AppendBigEndian32(static_cast<uint32_t>(crc), &chunk);
  return chunk;
}

}  // namespace

absl::Status PrintOptions::Validate() const {
  if (dpi < 50 || dpi > 600) {
    return absl::InvalidArgumentError(
        absl::StrCat("print resolution ", dpi, " dpi outside 50..600"));
  }
  if (!std::isfinite(margin_m) || margin_m < 0.0 || margin_m > 1.0) {
    return absl::InvalidArgumentError(absl::StrCat("print margin ", margin_m, " m outside 0..1"));
  }
  return absl::OkStatus();
}

absl::Status TextureOptions::Validate() const {
  if (!(texels_per_m >= 100.0 && texels_per_m <= 20000.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("texture resolution ", texels_per_m, " texels/m outside 100..20000"));
  }
  if (!std::isfinite(margin_m) || margin_m < 0.0 || margin_m > 1.0) {
    return absl::InvalidArgumentError(absl::StrCat("texture margin ", margin_m, " m outside 0..1"));
  }
  if (supersampling < 1 || supersampling > 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("texture supersampling ", supersampling, " outside 1..8"));
  }
  return absl::OkStatus();
}

absl::StatusOr<BoardPrint> RenderBoardForPrint(const BoardSpec& spec, const PrintOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(const BoardRaster raster, BoardRaster::Create(spec));
  const double pixels_per_m = options.dpi / kMetresPerInch;
  const int width_px =
      static_cast<int>(std::lround((spec.width_m() + 2.0 * options.margin_m) * pixels_per_m));
  const int height_px =
      static_cast<int>(std::lround((spec.depth_m() + 2.0 * options.margin_m) * pixels_per_m));
  if (static_cast<int64_t>(width_px) * height_px > 100'000'000) {
    return absl::InvalidArgumentError(
        absl::StrCat("board page of ", width_px, "x", height_px, " pixels is too large"));
  }
  cv::Mat page = Rasterise(raster, width_px, height_px, pixels_per_m, 1);
  if (options.caption) {
    DrawCaption(CaptionLines(spec, options.dpi), options.margin_m * pixels_per_m, &page);
  }
  BoardPrint print;
  print.image = GreyToRgb(page);
  print.dpi = options.dpi;
  print.width_m = width_px / pixels_per_m;
  print.height_m = height_px / pixels_per_m;
  return print;
}

absl::StatusOr<std::string> EncodePrintPng(const BoardPrint& print) {
  const RgbImage& image = print.image;
  if (image.empty() || image.data.size() != image.num_pixels() * 3 || print.dpi <= 0) {
    return absl::InvalidArgumentError("EncodePrintPng: empty or inconsistent page");
  }
  cv::Mat grey(image.height, image.width, CV_8UC1);
  for (int j = 0; j < image.height; ++j) {
    for (int i = 0; i < image.width; ++i) grey.at<uint8_t>(j, i) = image.at(i, j, 0);
  }
  std::vector<uint8_t> bytes;
  if (!cv::imencode(".png", grey, bytes)) return absl::InternalError("EncodePrintPng: imencode");
  std::string png(bytes.begin(), bytes.end());
  // The signature (8 bytes) and IHDR (4 + 4 + 13 + 4 bytes) come first; pHYs
  // must precede the image data, so it goes right after IHDR.
  constexpr size_t kAfterIhdr = 8 + 25;
  if (png.size() < kAfterIhdr || png.compare(12, 4, "IHDR") != 0) {
    return absl::InternalError("EncodePrintPng: unexpected PNG layout");
  }
  const auto pixels_per_m = static_cast<uint32_t>(std::lround(print.dpi / kMetresPerInch));
  png.insert(kAfterIhdr, PhysChunk(pixels_per_m));
  return png;
}

absl::StatusOr<BoardTexture> RenderBoardTexture(const BoardSpec& spec,
                                                const TextureOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(const BoardRaster raster, BoardRaster::Create(spec));
  const double ppm = options.texels_per_m;
  const int width_px =
      static_cast<int>(std::lround((spec.width_m() + 2.0 * options.margin_m) * ppm));
  const int height_px =
      static_cast<int>(std::lround((spec.depth_m() + 2.0 * options.margin_m) * ppm));
  if (width_px > 16384 || height_px > 16384) {
    return absl::InvalidArgumentError(
        absl::StrCat("board texture of ", width_px, "x", height_px, " texels is too large"));
  }
  BoardTexture texture;
  texture.image_srgb =
      GreyToRgb(Rasterise(raster, width_px, height_px, ppm, options.supersampling));
  texture.width_m = width_px / ppm;
  texture.depth_m = height_px / ppm;
  return texture;
}

}  // namespace reenact::board
