#include "common/board/board_spec.h"

#include <cmath>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"

namespace reenact::board {
namespace {

// OpenCV's predefined ArUco dictionaries: data bits per side and marker count.
struct DictionaryInfo {
  const char* name;
  int bits;
  int size;
};

constexpr DictionaryInfo kDictionaries[] = {
    {"DICT_4X4_50", 4, 50},           {"DICT_4X4_100", 4, 100},
    {"DICT_4X4_250", 4, 250},         {"DICT_4X4_1000", 4, 1000},
    {"DICT_5X5_50", 5, 50},           {"DICT_5X5_100", 5, 100},
    {"DICT_5X5_250", 5, 250},         {"DICT_5X5_1000", 5, 1000},
    {"DICT_6X6_50", 6, 50},           {"DICT_6X6_100", 6, 100},
    {"DICT_6X6_250", 6, 250},         {"DICT_6X6_1000", 6, 1000},
    {"DICT_7X7_50", 7, 50},           {"DICT_7X7_100", 7, 100},
    {"DICT_7X7_250", 7, 250},         {"DICT_7X7_1000", 7, 1000},
    {"DICT_ARUCO_ORIGINAL", 5, 1024}, {"DICT_APRILTAG_16h5", 4, 30},
    {"DICT_APRILTAG_25h9", 5, 35},    {"DICT_APRILTAG_36h10", 6, 2320},
    {"DICT_APRILTAG_36h11", 6, 587},
};

const DictionaryInfo* FindDictionary(absl::string_view name) {
  for (const DictionaryInfo& info : kDictionaries) {
    if (absl::EqualsIgnoreCase(info.name, name)) return &info;
  }
  return nullptr;
}

bool ParseMillimetres(absl::string_view text, double* metres) {
  double mm = 0.0;
  if (!absl::SimpleAtod(text, &mm) || !std::isfinite(mm)) return false;
  *metres = mm * 1e-3;
  return true;
}

absl::Status BadSpec(absl::string_view text, absl::string_view why) {
  return absl::InvalidArgumentError(
      absl::StrCat("board spec \"", text, "\": ", why,
                   " (expected aruco:DICT_NAME:COLSxROWS:MARKER_MM:GAP_MM[:FIRST_ID], e.g. ",
                   kDefaultBoardSpecText, ")"));
}

}  // namespace

absl::Status BoardSpec::Validate() const {
  const DictionaryInfo* info = FindDictionary(dictionary);
  if (info == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown ArUco dictionary \"", dictionary, "\""));
  }
  if (columns < 1 || rows < 1 || columns > 100 || rows > 100) {
    return absl::InvalidArgumentError(
        absl::StrCat("board of ", columns, "x", rows, " markers: counts must be in 1..100"));
  }
  if (!(marker_side_m > 0.0 && marker_side_m <= 10.0) ||
      !(marker_gap_m >= 0.0 && marker_gap_m <= 10.0)) {
    return absl::InvalidArgumentError(absl::StrCat("marker side ", marker_side_m, " m and gap ",
                                                   marker_gap_m,
                                                   " m: need 0 < side <= 10 and 0 <= gap <= 10"));
  }
  // In 64 bits: an id near INT_MAX must not wrap round to a small one.
  const int64_t last_id = int64_t{first_marker_id} + num_markers() - 1;
  if (first_marker_id < 0 || last_id >= info->size) {
    return absl::InvalidArgumentError(absl::StrCat("markers ", first_marker_id, "..", last_id,
                                                   " do not fit ", info->name, " (", info->size,
                                                   " markers)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<BoardSpec> ParseBoardSpec(absl::string_view text) {
  const std::vector<absl::string_view> parts = absl::StrSplit(text, ':');
  if (parts.size() < 5 || parts.size() > 6) return BadSpec(text, "wrong number of fields");
  if (!absl::EqualsIgnoreCase(parts[0], "aruco")) return BadSpec(text, "unknown board kind");
  BoardSpec spec;
  const DictionaryInfo* info = FindDictionary(parts[1]);
  if (info == nullptr) return BadSpec(text, "unknown dictionary");
  spec.dictionary = info->name;
  const std::vector<absl::string_view> grid = absl::StrSplit(absl::AsciiStrToLower(parts[2]), 'x');
  if (grid.size() != 2 || !absl::SimpleAtoi(grid[0], &spec.columns) ||
      !absl::SimpleAtoi(grid[1], &spec.rows)) {
    return BadSpec(text, "grid is not COLSxROWS");
  }
  if (!ParseMillimetres(parts[3], &spec.marker_side_m)) return BadSpec(text, "bad marker side");
  if (!ParseMillimetres(parts[4], &spec.marker_gap_m)) return BadSpec(text, "bad marker gap");
  if (parts.size() == 6 && !absl::SimpleAtoi(parts[5], &spec.first_marker_id)) {
    return BadSpec(text, "bad first marker id");
  }
  if (absl::Status status = spec.Validate(); !status.ok()) {
    return BadSpec(text, status.message());
  }
  return spec;
}

std::string FormatBoardSpec(const BoardSpec& spec) {
  std::string text = absl::StrFormat("aruco:%s:%dx%d:%g:%g", spec.dictionary, spec.columns,
                                     spec.rows, spec.marker_side_m * 1e3, spec.marker_gap_m * 1e3);
  if (spec.first_marker_id != 0) absl::StrAppend(&text, ":", spec.first_marker_id);
  return text;
}

int DictionaryMarkerBits(absl::string_view dictionary) {
  const DictionaryInfo* info = FindDictionary(dictionary);
  return info == nullptr ? 0 : info->bits;
}

std::vector<BoardMarker> BoardMarkers(const BoardSpec& spec) {
  const double pitch_m = spec.marker_side_m + spec.marker_gap_m;
  const double left_x = -0.5 * spec.width_m();
  const double top_z = -0.5 * spec.depth_m();
  const double side = spec.marker_side_m;
  std::vector<BoardMarker> markers;
  markers.reserve(spec.num_markers());
  for (int row = 0; row < spec.rows; ++row) {
    for (int column = 0; column < spec.columns; ++column) {
      BoardMarker marker;
      marker.id = spec.first_marker_id + row * spec.columns + column;
      marker.row = row;
      marker.column = column;
      const double x0 = left_x + column * pitch_m;
      const double z0 = top_z + row * pitch_m;
      // Top of the page is -Z, so "top-left as printed" is (min X, min Z).
      marker.corners_in_board = {Eigen::Vector3d(x0, 0.0, z0), Eigen::Vector3d(x0 + side, 0.0, z0),
                                 Eigen::Vector3d(x0 + side, 0.0, z0 + side),
                                 Eigen::Vector3d(x0, 0.0, z0 + side)};
      markers.push_back(marker);
    }
  }
  return markers;
}

Eigen::Matrix3d BoardFromOpenCvBoardRotation() {
  Eigen::Matrix3d board_from_cv;
  // Columns: the images of OpenCV's x, y and z axes in the board frame.
  board_from_cv << 1.0, 0.0, 0.0,  //
      0.0, 0.0, -1.0,              //
      0.0, 1.0, 0.0;
  return board_from_cv;
}

Eigen::Isometry3d BoardFromOpenCvGridBoard(const BoardSpec& spec) {
  Eigen::Isometry3d board_from_cv = Eigen::Isometry3d::Identity();
  board_from_cv.linear() = BoardFromOpenCvBoardRotation();
  // OpenCV's origin is the top-left corner of the grid: min X, min Z.
  board_from_cv.translation() = Eigen::Vector3d(-0.5 * spec.width_m(), 0.0, -0.5 * spec.depth_m());
  return board_from_cv;
}

}  // namespace reenact::board
