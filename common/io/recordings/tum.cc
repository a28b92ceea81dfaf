// TUM RGB-D benchmark folders (J. Sturm et al., "A Benchmark for the
// Evaluation of RGB-D SLAM Systems", IROS 2012; the dataset's "File Formats"
// page):
//   rgb.txt, depth.txt   one "timestamp filename" line per image, timestamps
//                        in seconds, '#' starts a comment line
//   depth/*.png          16-bit one-channel PNG, 5000 units per metre
//                        (millimetres = value / 5, rounded; another scale
//                        with RecordingOptions.depth_units_per_m), 0 = no
//                        value
//   rgb/*.png            8-bit colour PNG
// Depth and colour are associated as the benchmark's associate.py does: pairs
// closer than 20 ms, the closest first, each image used once. A depth frame
// without a partner comes without colour; colour without depth is skipped.
//
// The depth images are registered to the colour camera (the benchmark
// recorded them with OpenNI's registration), so both share one camera and
// color_from_depth is the identity. Intrinsics: the benchmark's default for
// its 640x480 images, fx = fy = 525, cx = 319.5, cy = 239.5, no distortion
// (scaled when the images have another size), unless
// RecordingOptions.intrinsics_path names a calibration file: one line
// "fx fy cx cy [d0 d1 d2 d3 d4]" as the benchmark's calibration table gives
// them (d0..d4 = k1 k2 p1 p2 k3, OpenCV's order), '#' comments allowed.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/jpeg.h"
#include "common/io/recordings/recording.h"

namespace reenact::recordings {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kAssociateMaxNs = 20'000'000;  // associate.py's --max_difference 0.02.
constexpr uint64_t kMaxListBytes = 64 << 20;
constexpr uint64_t kMaxImageBytes = 256 << 20;
constexpr size_t kMaxEntries = 1'000'000;
// Candidates considered per depth image (a hostile list of equal stamps
// must not make the association quadratic).
constexpr size_t kMaxCandidatesPerDepth = 16;

struct Entry {
  int64_t stamp_ns = 0;
  std::string file;  // Relative to the folder.
};

// "1305031102.175304" -> nanoseconds, exactly (no double rounding).
bool ParseStamp(absl::string_view text, int64_t* ns) {
  const size_t dot = text.find('.');
  const absl::string_view whole = text.substr(0, dot);
  const absl::string_view fraction = dot == absl::string_view::npos ? "" : text.substr(dot + 1);
  int64_t seconds = 0;
  if (whole.empty() || whole.size() > 11 || !absl::SimpleAtoi(whole, &seconds) || seconds < 0) {
    return false;
  }
  int64_t nanos = 0;
  int digits = 0;
  for (char c : fraction) {
    if (c < '0' || c > '9') return false;
    if (digits < 9) {
      nanos = nanos * 10 + (c - '0');
      ++digits;
    }
  }
  for (; digits < 9; ++digits) nanos *= 10;
  *ns = seconds * 1'000'000'000 + nanos;
  return true;
}

bool SafeRelative(const std::string& name) {
  const fs::path p(name);
  if (p.is_absolute() || name.empty()) return false;
  for (const fs::path& part : p) {
    if (part == "..") return false;
  }
  return true;
}

absl::StatusOr<std::vector<Entry>> ReadList(const std::string& dir, const std::string& name) {
  const std::string path = (fs::path(dir) / name).string();
  absl::StatusOr<std::string> text = ReadFileToString(path, kMaxListBytes);
  if (!text.ok()) {
    return absl::Status(text.status().code(), absl::StrCat(path, ": ", text.status().message()));
  }
  std::vector<Entry> entries;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(*text, '\n')) {
    ++line_number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line[0] == '#') continue;
    std::vector<absl::string_view> fields = absl::StrSplit(line, ' ', absl::SkipEmpty());
    Entry entry;
    if (fields.size() != 2 || !ParseStamp(fields[0], &entry.stamp_ns)) {
      return absl::InvalidArgumentError(absl::StrCat(path, " line ", line_number,
                                                     ": expected \"timestamp filename\", got \"",
                                                     std::string(line.substr(0, 80)), "\""));
    }
    entry.file = std::string(fields[1]);
    if (!SafeRelative(entry.file)) {
      return absl::InvalidArgumentError(absl::StrCat(
          path, " line ", line_number, ": \"", entry.file, "\" is not a path inside the folder"));
    }
    if (!fs::exists(fs::path(dir) / entry.file)) {
      return absl::NotFoundError(
          absl::StrCat(path, " line ", line_number, ": ", entry.file, " does not exist"));
    }
    if (entries.size() >= kMaxEntries) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": more than ", kMaxEntries, " lines"));
    }
    entries.push_back(std::move(entry));
  }
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& a, const Entry& b) { return a.stamp_ns < b.stamp_ns; });
  return entries;
}

class TumReader : public RecordingReader {
 public:
  static absl::StatusOr<std::unique_ptr<RecordingReader>> Open(const std::string& dir,
                                                               const RecordingOptions& options) {
    std::unique_ptr<TumReader> reader(new TumReader(dir, options));
    RETURN_IF_ERROR(reader->Init());
    return std::unique_ptr<RecordingReader>(std::move(reader));
  }

  const RecordingInfo& info() const override { return info_; }

  absl::StatusOr<std::optional<RecordedFrame>> Next() override {
    if (next_ >= depth_.size()) return std::optional<RecordedFrame>();
    const size_t i = next_++;
    RecordedFrame frame;
    frame.index = static_cast<int64_t>(i);
    frame.stamp_ns = depth_[i].stamp_ns;
    ASSIGN_OR_RETURN(frame.depth_mm, ReadDepth(depth_[i].file));
    if (frame.depth_mm.width != info_.depth_lens.pinhole.width ||
        frame.depth_mm.height != info_.depth_lens.pinhole.height) {
      return absl::DataLossError(
          absl::StrCat(Path(depth_[i].file), ": ", frame.depth_mm.width, "x", frame.depth_mm.height,
                       " px; the first depth image is ", info_.depth_lens.pinhole.width, "x",
                       info_.depth_lens.pinhole.height));
    }
    if (partner_[i] >= 0) {
      const Entry& color = rgb_[partner_[i]];
      ASSIGN_OR_RETURN(RgbImage rgb, ReadColor(color.file));
      if (rgb.width != info_.color_lens.pinhole.width ||
          rgb.height != info_.color_lens.pinhole.height) {
        return absl::DataLossError(absl::StrCat(
            Path(color.file), ": ", rgb.width, "x", rgb.height, " px; the first colour image is ",
            info_.color_lens.pinhole.width, "x", info_.color_lens.pinhole.height));
      }
      frame.color_width = rgb.width;
      frame.color_height = rgb.height;
      frame.color_stamp_ns = color.stamp_ns;
      frame.color_rgb = std::move(rgb);
    }
    return std::optional<RecordedFrame>(std::move(frame));
  }

 private:
  TumReader(std::string dir, const RecordingOptions& options)
      : dir_(std::move(dir)), options_(options) {}

  std::string Path(const std::string& file) const { return (fs::path(dir_) / file).string(); }

  absl::StatusOr<std::string> ReadImageFile(const std::string& file) const {
    absl::StatusOr<std::string> bytes = ReadFileToString(Path(file), kMaxImageBytes);
    if (!bytes.ok()) {
      return absl::DataLossError(absl::StrCat(Path(file), ": ", bytes.status().message()));
    }
    return bytes;
  }

  absl::StatusOr<DepthImageMm> ReadDepth(const std::string& file) const {
    ASSIGN_OR_RETURN(const std::string bytes, ReadImageFile(file));
    absl::StatusOr<Image<uint16_t, 1>> raw = DecodePng16(bytes, options_.max_pixels);
    if (!raw.ok())
      return absl::DataLossError(absl::StrCat(Path(file), ": ", raw.status().message()));
    // 5000 units per metre unless the options say otherwise.
    return DepthToMillimetres(*raw,
                              options_.depth_units_per_m > 0 ? options_.depth_units_per_m : 5000.0);
  }

  absl::StatusOr<RgbImage> ReadColor(const std::string& file) const {
    ASSIGN_OR_RETURN(const std::string bytes, ReadImageFile(file));
    if (bytes.size() > 2 && static_cast<uint8_t>(bytes[0]) == 0xff &&
        static_cast<uint8_t>(bytes[1]) == 0xd8) {
      absl::StatusOr<RgbImage> jpeg = DecodeJpeg(bytes);
      if (!jpeg.ok()) {
        return absl::DataLossError(absl::StrCat(Path(file), ": ", jpeg.status().message()));
      }
      return jpeg;
    }
    absl::StatusOr<RgbImage> rgb = DecodePngRgb(bytes, options_.max_pixels);
    if (!rgb.ok())
      return absl::DataLossError(absl::StrCat(Path(file), ": ", rgb.status().message()));
    return rgb;
  }

  absl::Status Init() {
    info_.format = RecordingFormat::kTum;
    info_.source = dir_;
    info_.model = "tum_rgbd";
    const double units = options_.depth_units_per_m;
    if (units != 0 && !(units >= 1 && units <= 1e6)) {
      return absl::InvalidArgumentError("depth units per metre must be in [1, 10^6]");
    }
    ASSIGN_OR_RETURN(depth_, ReadList(dir_, "depth.txt"));
    if (depth_.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(dir_, "/depth.txt lists no image"));
    }
    if (fs::exists(fs::path(dir_) / "rgb.txt")) {
      ASSIGN_OR_RETURN(rgb_, ReadList(dir_, "rgb.txt"));
    }
    Associate();
    info_.frame_count = static_cast<int64_t>(depth_.size());
    if (depth_.size() > 1) {
      const double span_s = (depth_.back().stamp_ns - depth_.front().stamp_ns) * 1e-9;
      if (span_s > 0) info_.nominal_fps = std::round((depth_.size() - 1) / span_s * 10) / 10;
    }
    if (info_.nominal_fps <= 0 || info_.nominal_fps > 1000) info_.nominal_fps = 30;

    // Sizes from the first images (their headers only).
    ASSIGN_OR_RETURN(const std::string depth_bytes, ReadImageFile(depth_.front().file));
    absl::StatusOr<std::pair<int, int>> depth_size = PngSize(depth_bytes);
    if (!depth_size.ok()) {
      return absl::DataLossError(
          absl::StrCat(Path(depth_.front().file), ": ", depth_size.status().message()));
    }
    std::pair<int, int> color_size{0, 0};
    const auto first_partner =
        std::find_if(partner_.begin(), partner_.end(), [](int p) { return p >= 0; });
    if (first_partner != partner_.end()) {
      ASSIGN_OR_RETURN(const RgbImage first, ReadColor(rgb_[*first_partner].file));
      color_size = {first.width, first.height};
      info_.has_color = true;
    }
    for (const auto& [w, h] : {*depth_size, color_size}) {
      if (static_cast<uint64_t>(w) * static_cast<uint64_t>(h) > options_.max_pixels) {
        return absl::InvalidArgumentError(
            absl::StrCat(dir_, ": images of ", w, "x", h, " px are larger than allowed"));
      }
    }

    CameraIntrinsics base;
    if (!options_.intrinsics_path.empty()) {
      ASSIGN_OR_RETURN(base, ReadIntrinsicsFile(options_.intrinsics_path));
      base.width = depth_size->first;
      base.height = depth_size->second;
      info_.calibration_note = absl::StrCat("calibration: ", options_.intrinsics_path);
    } else {
      base.width = 640;
      base.height = 480;
      base.fx = base.fy = 525.0;
      base.cx = 319.5;
      base.cy = 239.5;
      if (depth_size->first != 640 || depth_size->second != 480) {
        ASSIGN_OR_RETURN(base, ScaledIntrinsics(base, depth_size->first, depth_size->second));
      }
      info_.calibration_note =
          "calibration: TUM RGB-D default intrinsics (fx = fy = 525, cx = 319.5, cy = 239.5 at "
          "640x480, no distortion); depth registered to colour";
    }
    RETURN_IF_ERROR(base.Validate());
    info_.depth_lens.pinhole = base;
    if (info_.has_color) {
      ASSIGN_OR_RETURN(info_.color_lens.pinhole,
                       color_size.first == base.width && color_size.second == base.height
                           ? absl::StatusOr<CameraIntrinsics>(base)
                           : ScaledIntrinsics(base, color_size.first, color_size.second));
    }
    return absl::OkStatus();
  }

  // associate.py: every (depth, colour) pair closer than 20 ms, closest
  // first, each image at most once.
  void Associate() {
    partner_.assign(depth_.size(), -1);
    struct Candidate {
      int64_t gap;
      size_t depth, rgb;
    };
    std::vector<Candidate> candidates;
    size_t lo = 0;
    for (size_t d = 0; d < depth_.size(); ++d) {
      while (lo < rgb_.size() && rgb_[lo].stamp_ns < depth_[d].stamp_ns - kAssociateMaxNs) ++lo;
      for (size_t r = lo; r < rgb_.size() && r < lo + kMaxCandidatesPerDepth &&
                          rgb_[r].stamp_ns <= depth_[d].stamp_ns + kAssociateMaxNs;
           ++r) {
        candidates.push_back({std::abs(rgb_[r].stamp_ns - depth_[d].stamp_ns), d, r});
      }
    }
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.gap < b.gap; });
    std::vector<bool> rgb_used(rgb_.size(), false);
    for (const Candidate& c : candidates) {
      if (partner_[c.depth] >= 0 || rgb_used[c.rgb]) continue;
      partner_[c.depth] = static_cast<int>(c.rgb);
      rgb_used[c.rgb] = true;
    }
  }

  const std::string dir_;
  const RecordingOptions options_;
  RecordingInfo info_;
  std::vector<Entry> depth_, rgb_;
  std::vector<int> partner_;  // Index into rgb_ per depth frame, -1 for none.
  size_t next_ = 0;
};

}  // namespace

absl::StatusOr<std::unique_ptr<RecordingReader>> OpenTumFolder(const std::string& path,
                                                               const RecordingOptions& options) {
  if (!fs::is_directory(path)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": a TUM recording is a folder"));
  }
  return TumReader::Open(path, options);
}

}  // namespace reenact::recordings
