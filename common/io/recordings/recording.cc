#include "common/io/recordings/recording.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include <turbojpeg.h>

#include <Eigen/Dense>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::recordings {

std::string FormatName(RecordingFormat format) {
  switch (format) {
    case RecordingFormat::kAzureMkv:
      return "azure-mkv";
    case RecordingFormat::kTum:
      return "tum";
    case RecordingFormat::kOni:
      return "oni";
    case RecordingFormat::kDepthFolder:
      return "depth-png";
  }
  return "unknown";
}

absl::StatusOr<RecordingFormat> ParseFormat(const std::string& name) {
  if (name == "azure-mkv") return RecordingFormat::kAzureMkv;
  if (name == "tum") return RecordingFormat::kTum;
  if (name == "oni") return RecordingFormat::kOni;
  if (name == "depth-png") return RecordingFormat::kDepthFolder;
  return absl::InvalidArgumentError(absl::StrCat("unknown recording format \"", name,
                                                 "\" (expected azure-mkv, tum, oni or depth-png)"));
}

absl::StatusOr<RecordingFormat> DetectFormat(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) return absl::NotFoundError(absl::StrCat(path, ": no such file"));
  if (fs::is_directory(path, ec)) {
    if (fs::exists(fs::path(path) / "depth.txt", ec)) return RecordingFormat::kTum;
    if (fs::is_directory(fs::path(path) / "frames", ec)) return RecordingFormat::kDepthFolder;
    for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
      std::string extension = it->path().extension().string();
      std::transform(extension.begin(), extension.end(), extension.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (extension == ".png") return RecordingFormat::kDepthFolder;
    }
    return absl::InvalidArgumentError(
        absl::StrCat(path,
                     ": a folder with neither depth.txt (TUM RGB-D) nor depth PNGs (depth-png) is "
                     "no recording (give --format)"));
  }
  std::string extension = fs::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".mkv") return RecordingFormat::kAzureMkv;
  if (extension == ".oni") return RecordingFormat::kOni;
  return absl::InvalidArgumentError(absl::StrCat(
      path,
      ": cannot tell the recording format from the name (expected a .mkv or .oni file, a TUM "
      "folder or a folder of depth PNGs; give --format azure-mkv|tum|oni|depth-png)"));
}

namespace {

double RadialFactor(const LensModel& lens, double s) {
  const CameraIntrinsics& k = lens.pinhole;
  const double numerator = 1.0 + s * (k.k1 + s * (k.k2 + s * k.k3));
  const double denominator = 1.0 + s * (lens.k4 + s * (lens.k5 + s * lens.k6));
  return numerator / denominator;
}

}  // namespace

CameraIntrinsics FitPolynomialLens(const LensModel& lens, double* max_error_px) {
  CameraIntrinsics out = lens.pinhole;
  if (max_error_px != nullptr) *max_error_px = 0.0;
  if (!lens.rational() || out.fx <= 0 || out.fy <= 0) return out;
  // The largest distorted radius within the image (at a corner), then the
  // undistorted radius that maps to it: the range the fit must hold over.
  double distorted_max = 0.0;
  for (const double u : {-0.5, out.width - 0.5}) {
    for (const double v : {-0.5, out.height - 0.5}) {
      distorted_max =
          std::max(distorted_max, std::hypot((u - out.cx) / out.fx, (v - out.cy) / out.fy));
    }
  }
  double r_max = 0.0;
  double previous = 0.0;
  for (double r = 0.001; r < 4.0; r += 0.001) {
    const double distorted = r * RadialFactor(lens, r * r);
    if (distorted < previous || !std::isfinite(distorted)) break;  // Past the model's fold.
    previous = distorted;
    r_max = r;
    if (distorted >= distorted_max) break;
  }
  if (r_max <= 0.0) return out;
  // Least squares on the radial displacement r (f(r^2) - g(r^2)), with
  // g(s) = 1 + a1 s + a2 s^2 + a3 s^3: pixel errors scale with r.
  constexpr int kSamples = 400;
  Eigen::MatrixXd a(kSamples, 3);
  Eigen::VectorXd b(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    const double r = r_max * (i + 1) / kSamples;
    const double s = r * r;
    a(i, 0) = r * s;
    a(i, 1) = r * s * s;
    a(i, 2) = r * s * s * s;
    b(i) = r * (RadialFactor(lens, s) - 1.0);
  }
  const Eigen::Vector3d x = a.colPivHouseholderQr().solve(b);
  out.k1 = x(0);
  out.k2 = x(1);
  out.k3 = x(2);
  if (max_error_px != nullptr) {
    const double focal = std::max(out.fx, out.fy);
    double worst = 0.0;
    for (int i = 0; i < kSamples; ++i) worst = std::max(worst, std::abs((a.row(i) * x)(0) - b(i)));
    *max_error_px = worst * focal;
  }
  return out;
}

absl::StatusOr<std::unique_ptr<RecordingReader>> OpenRecording(const std::string& path,
                                                               RecordingFormat format,
                                                               const RecordingOptions& options) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file or folder"));
  }
  switch (format) {
    case RecordingFormat::kAzureMkv:
      return OpenAzureMkv(path, options);
    case RecordingFormat::kTum:
      return OpenTumFolder(path, options);
    case RecordingFormat::kOni:
      return OpenOni(path, options);
    case RecordingFormat::kDepthFolder:
      return OpenDepthFolder(path, options);
  }
  return absl::InvalidArgumentError("unknown recording format");
}

absl::StatusOr<CameraIntrinsics> IntrinsicsFromNumbers(const std::vector<double>& values,
                                                       const std::string& origin) {
  if (values.size() != 4 && values.size() != 9) {
    return absl::InvalidArgumentError(absl::StrCat(
        origin, ": expected \"fx fy cx cy [d0 d1 d2 d3 d4]\", got ", values.size(), " numbers"));
  }
  for (double v : values) {
    if (!std::isfinite(v)) {
      return absl::InvalidArgumentError(absl::StrCat(origin, ": a lens value is not finite"));
    }
  }
  CameraIntrinsics k;
  k.fx = values[0];
  k.fy = values[1];
  k.cx = values[2];
  k.cy = values[3];
  if (values.size() == 9) {
    k.k1 = values[4];
    k.k2 = values[5];
    k.p1 = values[6];
    k.p2 = values[7];
    k.k3 = values[8];
  }
  return k;
}

absl::StatusOr<CameraIntrinsics> ReadIntrinsicsFile(const std::string& path) {
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path, 1 << 20));
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '{') {
    const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
    const auto it = j.is_object() ? j.find("intrinsics") : j.end();
    if (j.is_discarded() || !j.is_object() || it == j.end() || !it->is_array()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": a JSON lens file needs an \"intrinsics\" array"));
    }
    std::vector<double> values;
    for (const nlohmann::json& v : *it) {
      if (!v.is_number() || values.size() >= 9) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": \"intrinsics\" is not an array of 4 or 9 numbers"));
      }
      values.push_back(v.get<double>());
    }
    return IntrinsicsFromNumbers(values, path);
  }
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line[0] == '#') continue;
    std::vector<double> values;
    for (absl::string_view field :
         absl::StrSplit(line, absl::ByAnyChar(" \t,"), absl::SkipEmpty())) {
      double v = 0;
      if (!absl::SimpleAtod(field, &v) || !std::isfinite(v)) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": \"", std::string(field), "\" is not a number"));
      }
      values.push_back(v);
    }
    return IntrinsicsFromNumbers(values, path);
  }
  return absl::InvalidArgumentError(absl::StrCat(path, ": no calibration line"));
}

DepthImageMm DepthToMillimetres(const Image<uint16_t, 1>& raw, double units_per_m) {
  DepthImageMm depth(raw.width, raw.height);
  const double to_mm = 1000.0 / units_per_m;
  for (size_t p = 0; p < raw.data.size(); ++p) {
    depth.data[p] = static_cast<uint16_t>(std::min(std::round(raw.data[p] * to_mm), 65535.0));
  }
  return depth;
}

absl::StatusOr<std::pair<int, int>> PngSize(const std::string& bytes) {
  // PNG (ISO/IEC 15948) 5.2 and 11.2.2: an 8-byte signature, then the IHDR
  // chunk (length 13, "IHDR", width and height as big-endian uint32).
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() < 24 || std::memcmp(bytes.data(), kSignature, 8) != 0 ||
      bytes.compare(12, 4, "IHDR") != 0) {
    return absl::DataLossError("not a PNG file (no signature and IHDR)");
  }
  auto be32 = [&bytes](size_t at) {
    return (uint32_t{static_cast<uint8_t>(bytes[at])} << 24) |
           (uint32_t{static_cast<uint8_t>(bytes[at + 1])} << 16) |
           (uint32_t{static_cast<uint8_t>(bytes[at + 2])} << 8) |
           uint32_t{static_cast<uint8_t>(bytes[at + 3])};
  };
  const uint32_t width = be32(16), height = be32(20);
  if (width == 0 || height == 0 || width > (1u << 30) || height > (1u << 30)) {
    return absl::DataLossError(absl::StrCat("PNG declares an image of ", width, "x", height));
  }
  return std::make_pair(static_cast<int>(width), static_cast<int>(height));
}

namespace {

absl::StatusOr<cv::Mat> DecodeBounded(const std::string& bytes, uint64_t max_pixels, int flags) {
  std::pair<int, int> size;
  if (auto s = PngSize(bytes); s.ok()) {
    size = *s;
  } else {
    return s.status();
  }
  const uint64_t pixels = static_cast<uint64_t>(size.first) * static_cast<uint64_t>(size.second);
  if (pixels > std::min(max_pixels, kMaxDecodedImagePixels)) {
    return absl::DataLossError(
        absl::StrCat("PNG declares ", size.first, "x", size.second, " pixels, more than the ",
                     std::min(max_pixels, kMaxDecodedImagePixels), " allowed"));
  }
  cv::Mat decoded;
  try {
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
    decoded = cv::imdecode(buffer, flags);
  } catch (const cv::Exception& e) {
    return absl::DataLossError(absl::StrCat("PNG does not decode: ", e.what()));
  }
  if (decoded.empty()) return absl::DataLossError("PNG does not decode (truncated or corrupt)");
  return decoded;
}

}  // namespace

absl::StatusOr<Image<uint16_t, 1>> DecodePng16(const std::string& bytes, uint64_t max_pixels) {
  absl::StatusOr<cv::Mat> decoded =
      DecodeBounded(bytes, max_pixels, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  if (!decoded.ok()) return decoded.status();
  cv::Mat mat = *decoded;
  if (mat.type() == CV_8UC1) mat.convertTo(mat, CV_16U);
  if (mat.type() != CV_16UC1) return absl::DataLossError("PNG is not a one-channel depth image");
  Image<uint16_t, 1> out(mat.cols, mat.rows);
  for (int y = 0; y < mat.rows; ++y) {
    std::memcpy(&out.at(0, y), mat.ptr<uint16_t>(y), sizeof(uint16_t) * mat.cols);
  }
  return out;
}

absl::StatusOr<RgbImage> DecodePngRgb(const std::string& bytes, uint64_t max_pixels) {
  absl::StatusOr<cv::Mat> decoded = DecodeBounded(bytes, max_pixels, cv::IMREAD_COLOR);
  if (!decoded.ok()) return decoded.status();
  if (decoded->type() != CV_8UC3) return absl::DataLossError("PNG is not an RGB image");
  RgbImage out(decoded->cols, decoded->rows);
  cv::Mat rgb(out.height, out.width, CV_8UC3, out.data.data());
  cv::cvtColor(*decoded, rgb, cv::COLOR_BGR2RGB);
  return out;
}

absl::StatusOr<std::string> EncodePng16(const DepthImageMm& depth) {
  if (depth.empty() || depth.data.size() != depth.num_pixels()) {
    return absl::InvalidArgumentError("empty or inconsistent depth image");
  }
  const cv::Mat mat(depth.height, depth.width, CV_16UC1, const_cast<uint16_t*>(depth.data.data()));
  std::vector<uchar> png;
  if (!cv::imencode(".png", mat, png)) return absl::InternalError("PNG encoding failed");
  return std::string(png.begin(), png.end());
}

absl::StatusOr<std::pair<int, int>> JpegSize(const std::string& bytes) {
  tjhandle handle = tjInitDecompress();
  if (handle == nullptr) return absl::InternalError("libturbojpeg failed to initialise");
  int width = 0, height = 0, subsampling = 0, colorspace = 0;
  const int rc = tjDecompressHeader3(handle, reinterpret_cast<const unsigned char*>(bytes.data()),
                                     static_cast<unsigned long>(bytes.size()), &width, &height,
                                     &subsampling, &colorspace);
  tjDestroy(handle);
  if (rc != 0 || width <= 0 || height <= 0) {
    return absl::DataLossError("not a JPEG image (its header does not parse)");
  }
  return std::make_pair(width, height);
}

}  // namespace reenact::recordings
