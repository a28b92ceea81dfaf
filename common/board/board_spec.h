// The printed ArUco grid board that defines the world frame of a take and of
// the AR viewer (thesis 3.4.2, Eq. 3.12: the viewer overlays part b of frame n
// with T*_b = C* C_n^-1 T_b,n; C_n, the capture sensor's pose, and C*, the
// viewer camera's pose, are both measured against this one board, so the
// teacher appears where they stood).
//
// Board frame (= world frame when the board lies face up on the floor):
//   origin  the centre of the marker grid, on the printed face;
//   +X      along the columns: left to right on the printed page;
//   +Y      the normal out of the printed face (world up);
//   +Z      = X x Y: down the printed page, from the top row to the bottom row;
//   the printed face lies in y = 0; units are metres.
// Marker ids run row by row from the top-left marker as printed:
// id = first_marker_id + row * columns + column.
//
// Default board (BoardSpec{}, "aruco:DICT_4X4_50:3x2:110:22"): 3 x 2 markers of
// 110 mm with 22 mm gaps, a 374 x 242 mm grid that fits A3 landscape
// (420 x 297 mm) with a white border of 20 mm or more (a printer clipping the
// outer few millimetres of white does no harm). Few, large markers and the
// 4x4-bit dictionary give the largest cells for the paper (18.3 mm), which is
// what matters for a Kinect-class sensor 2-3 m away: 1920x1080 with
// fx ~ 1080 px sees the floor board at 18-37 degrees of elevation, ~40 x 13 px
// per marker at 3 m, ~2 px per cell across (board_test's Kinect views: all
// found, pose within 2.5 mm). A phone or webcam at 0.5-2 m still sees whole
// markers when only part of the board is in view.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace reenact::board {

// The textual form of the default board.
inline constexpr char kDefaultBoardSpecText[] = "aruco:DICT_4X4_50:3x2:110:22";

// An ArUco grid board: `columns` x `rows` square markers of one predefined
// OpenCV dictionary, spaced by a constant gap.
struct BoardSpec {
  // Predefined OpenCV ArUco dictionary, by its OpenCV name: DICT_4X4_50 ...
  // DICT_7X7_1000, DICT_ARUCO_ORIGINAL, DICT_APRILTAG_16h5/25h9/36h10/36h11.
  std::string dictionary = "DICT_4X4_50";
  int columns = 3;               // Markers along the board's +X.
  int rows = 2;                  // Markers along the board's +Z.
  double marker_side_m = 0.110;  // Side of one marker's black square, metres.
  double marker_gap_m = 0.022;   // White space between neighbouring markers, metres.
  int first_marker_id = 0;       // Id of the top-left marker (see the file comment).

  // InvalidArgument for an unknown dictionary, non-positive counts or sizes, a
  // negative gap, or ids beyond the dictionary.
  absl::Status Validate() const;

  int num_markers() const { return columns * rows; }
  // Extent of the marker grid (outer edges of the outer markers), metres.
  double width_m() const { return columns * marker_side_m + (columns - 1) * marker_gap_m; }
  double depth_m() const { return rows * marker_side_m + (rows - 1) * marker_gap_m; }
};

// Parses "aruco:DICT_NAME:COLSxROWS:MARKER_MM:GAP_MM[:FIRST_ID]", e.g.
// kDefaultBoardSpecText; sizes in millimetres (decimals allowed), the
// dictionary name case-insensitive. InvalidArgument naming the bad part.
absl::StatusOr<BoardSpec> ParseBoardSpec(absl::string_view text);

// The textual form ParseBoardSpec reads; FIRST_ID only when it is not 0.
std::string FormatBoardSpec(const BoardSpec& spec);

// Number of data bits along one side of a marker of `dictionary` (4 for
// DICT_4X4_*), or 0 when the name is unknown.
int DictionaryMarkerBits(absl::string_view dictionary);

// One marker of the board: its id and its corners in the board frame, metres,
// in the order OpenCV's detector reports them: the printed marker's top-left,
// top-right, bottom-right, bottom-left (clockwise as printed).
struct BoardMarker {
  int id = 0;
  int row = 0;
  int column = 0;
  std::array<Eigen::Vector3d, 4> corners_in_board;
};

// Every marker of a valid `spec`, in id order.
std::vector<BoardMarker> BoardMarkers(const BoardSpec& spec);

// The rotation from the axes of OpenCV's cv::aruco::GridBoard (OpenCV 4.6 as
// built in Debian 12: x right and y down the printed page, so z = x cross y
// points into the printed face) to the board frame: board_from_cv maps
// x -> +X, y -> +Z, z -> -Y, a rotation of +90 degrees about X. (Older OpenCV
// releases put the origin at the bottom-left, y up the page and z out of the
// face; from those axes the rotation is -90 degrees about X. board_test checks
// the installed layout.)
Eigen::Matrix3d BoardFromOpenCvBoardRotation();

// The full transform from the frame of a cv::aruco::GridBoard of the same
// layout (origin at the top-left corner of the grid as printed, axes as
// above) to the board frame.
Eigen::Isometry3d BoardFromOpenCvGridBoard(const BoardSpec& spec);

}  // namespace reenact::board
