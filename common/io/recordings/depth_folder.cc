// Depth-only folders: a folder of 16-bit one-channel depth PNGs, one frame
// per file, as many depth sensors' tools and datasets write them (no colour,
// no timestamps). The frames are the folder's *.png files, or those of its
// frames/ subfolder when it has one, in the order of their names; names
// that differ only in a number (1.png, 2.png, 10.png or 0001.png, ...) are
// ordered by that number. Frame k is stamped k / fps.
//
// Depth values are RecordingOptions.depth_units_per_m units per metre
// (default 1000: millimetres; 0 = no value). The lens comes from
// RecordingOptions.intrinsics_path (ReadIntrinsicsFile: "fx fy cx cy [k1 k2
// p1 p2 k3]" or a JSON file with an "intrinsics" array) or, without it, from
// the folder's own meta.json when that has an "intrinsics" array (the layout
// of ../shared/data/rgbd-seq: meta.json also gives "fps_nominal"). Anything
// else is refused with a message that asks for --intrinsics: a guessed lens
// would put every point of the take in the wrong place.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/recordings/recording.h"

namespace reenact::recordings {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kMaxImageBytes = 256 << 20;
constexpr uint64_t kMaxMetaBytes = 256 << 20;
constexpr size_t kMaxFrames = 1'000'000;

// The name split around its last run of digits: "frame_0012.png" ->
// ("frame_", 12, ".png"), so that names differing only in the number sort by
// it.
struct NameKey {
  std::string prefix;
  bool has_number = false;
  std::string digits;  // Without leading zeros ("" for 0).
  std::string rest;
  std::string name;
};

NameKey KeyOf(const std::string& name) {
  NameKey key;
  key.name = name;
  const size_t last_digit = name.find_last_of("0123456789");
  if (last_digit == std::string::npos) {
    key.prefix = name;
    return key;
  }
  size_t first_digit = last_digit;
  while (first_digit > 0 && std::isdigit(static_cast<unsigned char>(name[first_digit - 1]))) {
    --first_digit;
  }
  key.has_number = true;
  key.prefix = name.substr(0, first_digit);
  std::string digits = name.substr(first_digit, last_digit + 1 - first_digit);
  digits.erase(0, std::min(digits.find_first_not_of('0'), digits.size()));
  key.digits = digits;
  key.rest = name.substr(last_digit + 1);
  return key;
}

bool NameLess(const NameKey& a, const NameKey& b) {
  if (a.has_number && b.has_number && a.prefix == b.prefix && a.rest == b.rest) {
    if (a.digits.size() != b.digits.size()) return a.digits.size() < b.digits.size();
    if (a.digits != b.digits) return a.digits < b.digits;
  }
  return a.name < b.name;
}

bool IsPng(const fs::directory_entry& entry) {
  std::error_code ec;
  if (!entry.is_regular_file(ec)) return false;
  std::string extension = entry.path().extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".png";
}

absl::StatusOr<std::vector<std::string>> ListPngs(const fs::path& dir) {
  std::vector<NameKey> keys;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!IsPng(*it)) continue;
    if (keys.size() >= kMaxFrames) {
      return absl::InvalidArgumentError(
          absl::StrCat(dir.string(), ": more than ", kMaxFrames, " depth images"));
    }
    keys.push_back(KeyOf(it->path().filename().string()));
  }
  if (ec) return absl::NotFoundError(absl::StrCat(dir.string(), ": ", ec.message()));
  std::sort(keys.begin(), keys.end(), NameLess);
  std::vector<std::string> files;
  files.reserve(keys.size());
  for (const NameKey& key : keys) files.push_back((dir / key.name).string());
  return files;
}

// The folder's meta.json, parsed, when it has one; null otherwise.
absl::StatusOr<nlohmann::json> ReadMeta(const fs::path& dir) {
  const fs::path path = dir / "meta.json";
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return nlohmann::json();
  ASSIGN_OR_RETURN(const std::string text, ReadFileToString(path.string(), kMaxMetaBytes));
  nlohmann::json meta = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (meta.is_discarded() || !meta.is_object()) {
    return absl::InvalidArgumentError(absl::StrCat(path.string(), ": not a JSON object"));
  }
  return meta;
}

class DepthFolderReader : public RecordingReader {
 public:
  static absl::StatusOr<std::unique_ptr<RecordingReader>> Open(const std::string& dir,
                                                               const RecordingOptions& options) {
    std::unique_ptr<DepthFolderReader> reader(new DepthFolderReader(dir, options));
    RETURN_IF_ERROR(reader->Init());
    return std::unique_ptr<RecordingReader>(std::move(reader));
  }

  const RecordingInfo& info() const override { return info_; }

  absl::StatusOr<std::optional<RecordedFrame>> Next() override {
    if (next_ >= files_.size()) return std::optional<RecordedFrame>();
    const size_t i = next_++;
    RecordedFrame frame;
    frame.index = static_cast<int64_t>(i);
    frame.stamp_ns = static_cast<int64_t>(std::llround(i * 1e9 / info_.nominal_fps));
    absl::StatusOr<std::string> bytes = ReadFileToString(files_[i], kMaxImageBytes);
    if (!bytes.ok()) {
      return absl::DataLossError(absl::StrCat(files_[i], ": ", bytes.status().message()));
    }
    absl::StatusOr<Image<uint16_t, 1>> raw = DecodePng16(*bytes, options_.max_pixels);
    if (!raw.ok())
      return absl::DataLossError(absl::StrCat(files_[i], ": ", raw.status().message()));
    if (raw->width != info_.depth_lens.pinhole.width ||
        raw->height != info_.depth_lens.pinhole.height) {
      return absl::DataLossError(absl::StrCat(
          files_[i], ": ", raw->width, "x", raw->height, " px; the first depth image is ",
          info_.depth_lens.pinhole.width, "x", info_.depth_lens.pinhole.height));
    }
    frame.depth_mm = DepthToMillimetres(*raw, units_per_m_);
    return std::optional<RecordedFrame>(std::move(frame));
  }

 private:
  DepthFolderReader(std::string dir, const RecordingOptions& options)
      : dir_(std::move(dir)), options_(options) {}

  absl::Status Init() {
    info_.format = RecordingFormat::kDepthFolder;
    info_.source = dir_;
    info_.model = "depth_png";
    std::error_code ec;
    const fs::path frames_dir = fs::is_directory(fs::path(dir_) / "frames", ec)
                                    ? fs::path(dir_) / "frames"
                                    : fs::path(dir_);
    ASSIGN_OR_RETURN(files_, ListPngs(frames_dir));
    if (files_.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(frames_dir.string(), " holds no *.png"));
    }
    info_.frame_count = static_cast<int64_t>(files_.size());
    units_per_m_ = options_.depth_units_per_m != 0 ? options_.depth_units_per_m : 1000.0;
    if (!(units_per_m_ >= 1 && units_per_m_ <= 1e6)) {
      return absl::InvalidArgumentError("depth units per metre must be in [1, 10^6]");
    }

    ASSIGN_OR_RETURN(const nlohmann::json meta, ReadMeta(dir_));
    if (!(options_.fps >= 0 && options_.fps <= 1000)) {
      return absl::InvalidArgumentError("the frame rate must be in (0, 1000] frames/s");
    }
    info_.nominal_fps = options_.fps;
    if (info_.nominal_fps <= 0 && meta.is_object()) {
      const auto fps = meta.find("fps_nominal");
      if (fps != meta.end() && fps->is_number()) info_.nominal_fps = fps->get<double>();
    }
    if (!(info_.nominal_fps > 0)) info_.nominal_fps = 30.0;
    if (!(info_.nominal_fps <= 1000)) {
      return absl::InvalidArgumentError("the frame rate must be in (0, 1000] frames/s");
    }

    // The size from the first image's header.
    absl::StatusOr<std::string> first = ReadFileToString(files_.front(), kMaxImageBytes);
    if (!first.ok()) {
      return absl::DataLossError(absl::StrCat(files_.front(), ": ", first.status().message()));
    }
    absl::StatusOr<std::pair<int, int>> size = PngSize(*first);
    if (!size.ok()) {
      return absl::DataLossError(absl::StrCat(files_.front(), ": ", size.status().message()));
    }
    if (static_cast<uint64_t>(size->first) * static_cast<uint64_t>(size->second) >
        options_.max_pixels) {
      return absl::InvalidArgumentError(absl::StrCat(files_.front(), ": ", size->first, "x",
                                                     size->second, " px is larger than allowed"));
    }

    CameraIntrinsics lens;
    if (!options_.intrinsics_path.empty()) {
      ASSIGN_OR_RETURN(lens, ReadIntrinsicsFile(options_.intrinsics_path));
      info_.calibration_note = absl::StrCat("calibration: ", options_.intrinsics_path);
    } else if (meta.is_object() && meta.contains("intrinsics")) {
      const std::string meta_path = (fs::path(dir_) / "meta.json").string();
      std::vector<double> values;
      for (const nlohmann::json& v : meta["intrinsics"]) {
        if (!v.is_number() || values.size() >= 9) {
          return absl::InvalidArgumentError(
              absl::StrCat(meta_path, ": \"intrinsics\" is not an array of 4 or 9 numbers"));
        }
        values.push_back(v.get<double>());
      }
      ASSIGN_OR_RETURN(lens, IntrinsicsFromNumbers(values, meta_path));
      info_.calibration_note = absl::StrCat("calibration: ", meta_path);
    } else {
      return absl::InvalidArgumentError(absl::StrCat(
          dir_,
          ": a folder of depth images needs its lens: give --intrinsics FILE (\"fx fy cx cy "
          "[k1 k2 p1 p2 k3]\", or JSON with an \"intrinsics\" array)"));
    }
    lens.width = size->first;
    lens.height = size->second;
    RETURN_IF_ERROR(lens.Validate());
    info_.depth_lens.pinhole = lens;
    absl::StrAppend(&info_.calibration_note, "; depth only, ", units_per_m_, " units per metre, ",
                    info_.nominal_fps, " frames/s");
    return absl::OkStatus();
  }

  const std::string dir_;
  const RecordingOptions options_;
  RecordingInfo info_;
  std::vector<std::string> files_;
  double units_per_m_ = 1000.0;
  size_t next_ = 0;
};

}  // namespace

absl::StatusOr<std::unique_ptr<RecordingReader>> OpenDepthFolder(const std::string& path,
                                                                 const RecordingOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": a depth-png recording is a folder"));
  }
  return DepthFolderReader::Open(path, options);
}

}  // namespace reenact::recordings
