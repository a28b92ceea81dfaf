#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/board/board_detector.h"
#include "common/board/board_image.h"
#include "common/board/board_spec.h"
#include "common/board/intrinsics_file.h"
#include "common/board/testing/board_scenes.h"
#include "common/testing/test_data.h"

namespace reenact::board {
namespace {

using testing::BoardScene;
using testing::PoseErrorStats;

// --- Spec -----------------------------------------------------------------

TEST(ParseBoardSpec, DefaultRoundTrip) {
  auto spec = ParseBoardSpec(kDefaultBoardSpecText);
  ASSERT_TRUE(spec.ok()) << spec.status();
  const BoardSpec defaults;
  EXPECT_EQ(spec->dictionary, defaults.dictionary);
  EXPECT_EQ(spec->columns, defaults.columns);
  EXPECT_EQ(spec->rows, defaults.rows);
  EXPECT_DOUBLE_EQ(spec->marker_side_m, defaults.marker_side_m);
  EXPECT_DOUBLE_EQ(spec->marker_gap_m, defaults.marker_gap_m);
  EXPECT_EQ(FormatBoardSpec(*spec), kDefaultBoardSpecText);
  EXPECT_EQ(FormatBoardSpec(defaults), kDefaultBoardSpecText);
  // The default grid fits A3 landscape (420 x 297 mm) with 20 mm borders.
  EXPECT_LE(defaults.width_m() + 0.04, 0.420);
  EXPECT_LE(defaults.depth_m() + 0.04, 0.297);
}

TEST(ParseBoardSpec, OtherBoardsRoundTrip) {
  auto spec = ParseBoardSpec("ArUco:dict_5x5_100:4X3:80.5:20:10");
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->dictionary, "DICT_5X5_100");
  EXPECT_EQ(spec->columns, 4);
  EXPECT_EQ(spec->rows, 3);
  EXPECT_DOUBLE_EQ(spec->marker_side_m, 0.0805);
  EXPECT_DOUBLE_EQ(spec->marker_gap_m, 0.020);
  EXPECT_EQ(spec->first_marker_id, 10);
  EXPECT_EQ(FormatBoardSpec(*spec), "aruco:DICT_5X5_100:4x3:80.5:20:10");
  auto again = ParseBoardSpec(FormatBoardSpec(*spec));
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(FormatBoardSpec(*again), FormatBoardSpec(*spec));
  EXPECT_EQ(DictionaryMarkerBits("DICT_APRILTAG_36h11"), 6);
  EXPECT_EQ(DictionaryMarkerBits("nope"), 0);
}

TEST(ParseBoardSpec, RejectsBadText) {
  for (const char* text :
       {"", "aruco", "aruco:DICT_4X4_50:3x2:110", "charuco:DICT_4X4_50:3x2:110:22",
        "aruco:DICT_FOO:3x2:110:22", "aruco:DICT_4X4_50:3y2:110:22", "aruco:DICT_4X4_50:3x:110:22",
        "aruco:DICT_4X4_50:3x2:-110:22", "aruco:DICT_4X4_50:3x2:110:-1",
        "aruco:DICT_4X4_50:3x2:abc:22", "aruco:DICT_4X4_50:10x10:110:22",
        "aruco:DICT_4X4_50:3x2:110:22:45", "aruco:DICT_4X4_50:3x2:110:22:1:2",
        "aruco:DICT_4X4_50:0x2:110:22", "aruco:DICT_4X4_50:3x2:nan:22",
        // An id that would wrap round to a negative last id in 32 bits.
        "aruco:DICT_4X4_50:3x2:110:22:2147483647", "aruco:DICT_4X4_50:3x2:110:22:2147483648",
        "aruco:DICT_4X4_50:3x2:110:22:-1"}) {
    auto spec = ParseBoardSpec(text);
    EXPECT_TRUE(absl::IsInvalidArgument(spec.status())) << "\"" << text << "\" " << spec.status();
  }
}

// --- Frame convention ------------------------------------------------------

TEST(BoardMarkers, LayoutFollowsTheBoardFrame) {
  const BoardSpec spec;
  const std::vector<BoardMarker> markers = BoardMarkers(spec);
  ASSERT_EQ(markers.size(), 6u);
  // Marker 0 is top-left as printed: min X, min Z; its corners go clockwise
  // as printed (+X, then +Z, then -X).
  EXPECT_TRUE(markers[0].corners_in_board[0].isApprox(
      Eigen::Vector3d(-0.5 * spec.width_m(), 0, -0.5 * spec.depth_m())));
  EXPECT_TRUE(markers[0].corners_in_board[1].isApprox(
      Eigen::Vector3d(-0.5 * spec.width_m() + 0.11, 0, -0.5 * spec.depth_m())));
  EXPECT_TRUE(markers[5].corners_in_board[2].isApprox(
      Eigen::Vector3d(0.5 * spec.width_m(), 0, 0.5 * spec.depth_m())));
  EXPECT_EQ(markers[4].row, 1);
  EXPECT_EQ(markers[4].column, 1);
  EXPECT_EQ(markers[4].id, 4);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const BoardMarker& marker : markers) {
    for (const Eigen::Vector3d& corner : marker.corners_in_board) centroid += corner / 24.0;
  }
  EXPECT_LT(centroid.norm(), 1e-12);
}

TEST(BoardMarkers, MatchOpenCvGridBoard) {
  const Eigen::Matrix3d board_from_cv = BoardFromOpenCvBoardRotation();
  EXPECT_NEAR(board_from_cv.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(board_from_cv.isApprox(
      Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix()));
  // OpenCV's z points into the printed face: world down.
  EXPECT_TRUE((board_from_cv * Eigen::Vector3d::UnitZ()).isApprox(-Eigen::Vector3d::UnitY()));
  const BoardSpec spec;
  const cv::Ptr<cv::aruco::GridBoard> grid =
      cv::aruco::GridBoard::create(spec.columns, spec.rows, static_cast<float>(spec.marker_side_m),
                                   static_cast<float>(spec.marker_gap_m),
                                   cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50));
  const Eigen::Isometry3d board_from_grid = BoardFromOpenCvGridBoard(spec);
  const std::vector<BoardMarker> markers = BoardMarkers(spec);
  ASSERT_EQ(grid->objPoints.size(), markers.size());
  for (size_t m = 0; m < markers.size(); ++m) {
    EXPECT_EQ(grid->ids[m], markers[m].id);
    for (int k = 0; k < 4; ++k) {
      const cv::Point3f& p = grid->objPoints[m][k];
      const Eigen::Vector3d mapped = board_from_grid * Eigen::Vector3d(p.x, p.y, p.z);
      EXPECT_LT((mapped - markers[m].corners_in_board[k]).norm(), 1e-6) << m << " " << k;
    }
  }
}

// --- Images ----------------------------------------------------------------

TEST(RenderBoardForPrint, MetricSizeAndPngResolution) {
  const BoardSpec spec;
  auto print = RenderBoardForPrint(spec);
  ASSERT_TRUE(print.ok()) << print.status();
  EXPECT_EQ(print->dpi, 300);
  EXPECT_NEAR(print->width_m, spec.width_m() + 0.04, 0.0001);
  EXPECT_NEAR(print->height_m, spec.depth_m() + 0.04, 0.0001);
  const double px_per_m = 300 / 0.0254;
  const auto pixel = [&](double x_m, double z_m) {
    const int i = static_cast<int>(0.5 * print->image.width + x_m * px_per_m);
    const int j = static_cast<int>(0.5 * print->image.height + z_m * px_per_m);
    return print->image.at(i, j, 0);
  };
  const std::vector<BoardMarker> markers = BoardMarkers(spec);
  const Eigen::Vector3d& top_left = markers[0].corners_in_board[0];
  EXPECT_EQ(pixel(top_left.x() + 0.003, top_left.z() + 0.003), 0);    // Black border.
  EXPECT_EQ(pixel(top_left.x() - 0.003, top_left.z() + 0.003), 255);  // Paper.
  EXPECT_EQ(pixel(top_left.x() + 0.115, top_left.z() + 0.050), 255);  // Gap.
  auto png = EncodePrintPng(*print);
  ASSERT_TRUE(png.ok()) << png.status();
  const size_t phys = png->find("pHYs");
  ASSERT_NE(phys, std::string::npos);
  const auto byte = [&](size_t i) {
    return static_cast<uint32_t>(static_cast<uint8_t>((*png)[i]));
  };
  const uint32_t ppm =
      byte(phys + 4) << 24 | byte(phys + 5) << 16 | byte(phys + 6) << 8 | byte(phys + 7);
  EXPECT_EQ(ppm, 11811u);  // 300 dpi.
  const cv::Mat decoded =
      cv::imdecode(std::vector<uint8_t>(png->begin(), png->end()), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(decoded.cols, print->image.width);
  EXPECT_EQ(decoded.rows, print->image.height);
  EXPECT_EQ(decoded.channels(), 1);
}

TEST(RenderBoardForPrint, PrintedPageIsDetected) {
  // The page seen straight on by a camera whose pixels are the page's dots at
  // 1 m: fx = 100 dpi / 0.0254 m per inch; the pose must put the board 1 m
  // ahead, facing the camera.
  const BoardSpec spec;
  PrintOptions options;
  options.dpi = 100;
  auto print = RenderBoardForPrint(spec, options);
  ASSERT_TRUE(print.ok()) << print.status();
  CameraIntrinsics intrinsics;
  intrinsics.width = print->image.width;
  intrinsics.height = print->image.height;
  intrinsics.fx = intrinsics.fy = 100 / 0.0254;
  intrinsics.cx = 0.5 * intrinsics.width - 0.5;
  intrinsics.cy = 0.5 * intrinsics.height - 0.5;
  auto found = DetectBoard(print->image, intrinsics, spec);
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ(found->num_markers, 6);
  EXPECT_LT(found->reprojection_rms_px, 0.5);
  EXPECT_LT((found->camera_from_board.translation() - Eigen::Vector3d(0, 0, 1)).norm(), 0.005);
  // The board's +Y (out of the face) points back at the camera (-z).
  EXPECT_GT(-(found->camera_from_board.linear() * Eigen::Vector3d::UnitY()).z(), 0.999);
}

TEST(RenderBoardTexture, ExtentAndOrientation) {
  const BoardSpec spec;
  auto texture = RenderBoardTexture(spec);
  ASSERT_TRUE(texture.ok()) << texture.status();
  EXPECT_NEAR(texture->width_m, spec.width_m() + 0.04, 0.0005);
  EXPECT_NEAR(texture->depth_m, spec.depth_m() + 0.04, 0.0005);
  EXPECT_NEAR(texture->image_srgb.width / texture->width_m, 4000.0, 1e-6);
  // Top-left marker's border near the top-left of the image; paper in the corner.
  const int border_texels = static_cast<int>(0.02 * 4000.0);
  EXPECT_EQ(texture->image_srgb.at(border_texels + 8, border_texels + 8, 0), 0);
  EXPECT_EQ(texture->image_srgb.at(4, 4, 0), 255);
  // Antialiased edges hold intermediate values only at marker edges.
  TextureOptions bad;
  bad.supersampling = 0;
  EXPECT_TRUE(absl::IsInvalidArgument(RenderBoardTexture(spec, bad).status()));
}

// --- Detection on rendered views --------------------------------------------

TEST(DetectBoard, HandheldViewsWithinOneDegreeAndTenMillimetres) {
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  auto scene = BoardScene::Create(spec, intrinsics.width, intrinsics.height);
  ASSERT_NE(scene, nullptr);
  const std::vector<Eigen::Isometry3d> path = testing::HandheldPath(30);
  PoseErrorStats stats;
  double worst_rms_px = 0.0;
  for (size_t i = 0; i < path.size(); ++i) {
    const RgbImage image = scene->Render(render::RenderCameraFromIntrinsics(intrinsics, path[i]),
                                         2.0, static_cast<unsigned>(i));
    auto found = DetectBoard(image, intrinsics, spec);
    ASSERT_TRUE(found.ok()) << "frame " << i << ": " << found.status();
    const testing::PoseError error = testing::ComparePose(found->camera_from_board, path[i]);
    EXPECT_LT(error.rotation_deg, 1.0) << "frame " << i;
    EXPECT_LT(error.position_mm, 10.0) << "frame " << i;
    EXPECT_GE(found->num_markers, 5) << "frame " << i;
    stats.Add(error);
    worst_rms_px = std::max(worst_rms_px, found->reprojection_rms_px);
  }
  std::printf(
      "still frames: %d views at 1.0-2.0 m, 1280x720: rotation error mean %.3f deg, worst %.3f "
      "deg; position error mean %.2f mm, worst %.2f mm; worst reprojection RMS %.3f px\n",
      stats.count, stats.mean.rotation_deg, stats.worst.rotation_deg, stats.mean.position_mm,
      stats.worst.position_mm, worst_rms_px);
}

TEST(DetectBoard, KinectViewsAtTwoToThreeMetres) {
  // A capture sensor aimed at the hips (0.8 m up) of an actor standing over
  // the board's centre, from 1.0-1.5 m high and 2-3 m away: the board lies low
  // in the image, seen at 18-37 degrees of elevation (markers down to ~13 px
  // tall). Rendered at 3x and box-filtered, like a sensor's pixels.
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = KinectV2ColorIntrinsics();
  auto scene = BoardScene::Create(spec, intrinsics.width, intrinsics.height, 3);
  ASSERT_NE(scene, nullptr);
  PoseErrorStats stats;
  int fewest_markers = spec.num_markers();
  unsigned seed = 100;
  for (double distance_m : {2.0, 2.5, 3.0}) {
    for (double height_m : {1.0, 1.5}) {
      for (double azimuth_deg : {-30.0, 20.0}) {
        const double a = azimuth_deg / testing::kDegPerRad;
        const Eigen::Vector3d eye(distance_m * std::sin(a), height_m, distance_m * std::cos(a));
        const Eigen::Isometry3d world_from_camera =
            testing::LookAt(eye, Eigen::Vector3d(0.0, 0.8, 0.0), 0.0);
        const RgbImage image = scene->Render(
            render::RenderCameraFromIntrinsics(intrinsics, world_from_camera), 2.0, ++seed);
        auto found = DetectBoard(image, intrinsics, spec);
        ASSERT_TRUE(found.ok()) << distance_m << " m, " << height_m << " m: " << found.status();
        const testing::PoseError error =
            testing::ComparePose(found->camera_from_board, world_from_camera);
        EXPECT_LT(error.rotation_deg, 1.0) << distance_m << " m, " << height_m << " m";
        EXPECT_LT(error.position_mm, 10.0) << distance_m << " m, " << height_m << " m";
        stats.Add(error);
        fewest_markers = std::min(fewest_markers, found->num_markers);
      }
    }
  }
  EXPECT_GE(fewest_markers, 4);
  std::printf(
      "Kinect v2 colour views at 2-3 m: rotation error mean %.3f deg, worst %.3f deg; "
      "position error mean %.2f mm, worst %.2f mm; fewest markers %d\n",
      stats.mean.rotation_deg, stats.worst.rotation_deg, stats.mean.position_mm,
      stats.worst.position_mm, fewest_markers);
}

// Applies `intrinsics`' distortion to a pinhole image of the same camera:
// each distorted pixel takes the colour of the pinhole pixel its ray hits.
RgbImage Distort(const RgbImage& pinhole, const CameraIntrinsics& intrinsics) {
  cv::Mat map_x(pinhole.height, pinhole.width, CV_32FC1);
  cv::Mat map_y(pinhole.height, pinhole.width, CV_32FC1);
  for (int v = 0; v < pinhole.height; ++v) {
    for (int u = 0; u < pinhole.width; ++u) {
      const Eigen::Vector2d distorted((u - intrinsics.cx) / intrinsics.fx,
                                      (v - intrinsics.cy) / intrinsics.fy);
      const auto normalized = intrinsics.Undistort(distorted);
      map_x.at<float>(v, u) = normalized ? intrinsics.fx * normalized->x() + intrinsics.cx : -1e4f;
      map_y.at<float>(v, u) = normalized ? intrinsics.fy * normalized->y() + intrinsics.cy : -1e4f;
    }
  }
  const cv::Mat source(pinhole.height, pinhole.width, CV_8UC3,
                       const_cast<uint8_t*>(pinhole.data.data()));
  RgbImage out(pinhole.width, pinhole.height);
  cv::Mat target(out.height, out.width, CV_8UC3, out.data.data());
  cv::remap(source, target, map_x, map_y, cv::INTER_LINEAR);
  return out;
}

TEST(DetectBoard, UsesLensDistortion) {
  // A wide webcam-like lens; the views are turned so the board sits toward
  // the image's sides, where the distortion is several pixels.
  const BoardSpec spec;
  CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  intrinsics.k1 = -0.2;
  intrinsics.k2 = 0.06;
  intrinsics.p1 = 0.001;
  intrinsics.p2 = -0.0008;
  auto scene = BoardScene::Create(spec, intrinsics.width, intrinsics.height);
  ASSERT_NE(scene, nullptr);
  std::vector<Eigen::Isometry3d> path = testing::HandheldPath(6);
  for (size_t i = 0; i < path.size(); ++i) {
    const double yaw_rad = (i % 2 == 0 ? 16.0 : -16.0) / testing::kDegPerRad;
    path[i] = path[i] * Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(7.0 / testing::kDegPerRad, Eigen::Vector3d::UnitX());
  }
  PoseErrorStats with_model, without_model;
  CameraIntrinsics pinhole = intrinsics;
  pinhole.k1 = pinhole.k2 = pinhole.p1 = pinhole.p2 = 0.0;
  DetectorOptions lenient;  // Lets the wrong model produce a pose to compare.
  lenient.max_reprojection_rms_px = 50.0;
  lenient.outlier_threshold_px = 50.0;
  for (size_t i = 0; i < path.size(); ++i) {
    const RgbImage image =
        Distort(scene->Render(render::RenderCameraFromIntrinsics(intrinsics, path[i]), 1.0,
                              static_cast<unsigned>(i)),
                intrinsics);
    auto found = DetectBoard(image, intrinsics, spec);
    ASSERT_TRUE(found.ok()) << "frame " << i << ": " << found.status();
    with_model.Add(testing::ComparePose(found->camera_from_board, path[i]));
    auto naive = DetectBoard(image, pinhole, spec, lenient);
    ASSERT_TRUE(naive.ok()) << "frame " << i << ": " << naive.status();
    without_model.Add(testing::ComparePose(naive->camera_from_board, path[i]));
  }
  std::printf(
      "distorted views (k1 -0.2, k2 0.06): worst %.3f deg, %.2f mm with the lens model; %.3f deg, "
      "%.2f mm ignoring it\n",
      with_model.worst.rotation_deg, with_model.worst.position_mm, without_model.worst.rotation_deg,
      without_model.worst.position_mm);
  EXPECT_LT(with_model.worst.rotation_deg, 1.0);
  EXPECT_LT(with_model.worst.position_mm, 10.0);
  EXPECT_GT(without_model.worst.position_mm, 3.0 * with_model.worst.position_mm);
}

TEST(DetectBoard, BoardOutOfViewIsNotFound) {
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  auto scene = BoardScene::Create(spec, intrinsics.width, intrinsics.height);
  ASSERT_NE(scene, nullptr);
  // Looking at the floor 2 m to the side of the board.
  const Eigen::Isometry3d away =
      testing::LookAt(Eigen::Vector3d(2.5, 1.5, 1.0), Eigen::Vector3d(2.5, 0.0, -0.5), 0.0);
  const RgbImage image =
      scene->Render(render::RenderCameraFromIntrinsics(intrinsics, away), 2.0, 7);
  auto found = DetectBoard(image, intrinsics, spec);
  EXPECT_TRUE(absl::IsNotFound(found.status())) << found.status();
}

TEST(DetectBoard, GarbageAndBadInput) {
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  RgbImage noise(intrinsics.width, intrinsics.height);
  std::mt19937 random(3);
  for (uint8_t& value : noise.data) value = static_cast<uint8_t>(random());
  auto found = DetectBoard(noise, intrinsics, spec);
  EXPECT_TRUE(absl::IsNotFound(found.status())) << found.status();
  RgbImage blocks(intrinsics.width, intrinsics.height);
  for (int y = 0; y < blocks.height; ++y) {
    for (int x = 0; x < blocks.width; ++x) {
      const uint8_t value = ((x / 23 + y / 17) % 2 == 0) ? 250 : 5;
      for (int c = 0; c < 3; ++c) blocks.at(x, y, c) = value;
    }
  }
  EXPECT_FALSE(DetectBoard(blocks, intrinsics, spec).ok());
  for (const auto& [width, height] : {std::pair{1, 1}, std::pair{3, 3}, std::pair{7, 5}}) {
    CameraIntrinsics tiny = intrinsics;
    tiny.width = width;
    tiny.height = height;
    EXPECT_TRUE(absl::IsNotFound(DetectBoard(RgbImage(width, height, 128), tiny, spec).status()))
        << width << "x" << height;
  }
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(RgbImage(), intrinsics, spec).status()));
  RgbImage truncated = noise;
  truncated.data.resize(100);
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(truncated, intrinsics, spec).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(RgbImage(640, 360), intrinsics, spec).status()));
  BoardSpec bad_spec;
  bad_spec.dictionary = "DICT_NONE";
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(noise, intrinsics, bad_spec).status()));
  CameraIntrinsics bad_intrinsics = intrinsics;
  bad_intrinsics.fx = 0.0;
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(noise, bad_intrinsics, spec).status()));
  DetectorOptions bad_options;
  bad_options.min_markers = 0;
  EXPECT_TRUE(absl::IsInvalidArgument(DetectBoard(noise, intrinsics, spec, bad_options).status()));
}

TEST(BoardTracker, ForgetsThePoseWhenTheBoardLeavesTheView) {
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  auto scene = BoardScene::Create(spec, intrinsics.width, intrinsics.height);
  ASSERT_NE(scene, nullptr);
  auto tracker = BoardTracker::Create(spec, intrinsics);
  ASSERT_TRUE(tracker.ok()) << tracker.status();
  const std::vector<Eigen::Isometry3d> path = testing::HandheldPath(30);
  const Eigen::Isometry3d away =
      testing::LookAt(Eigen::Vector3d(2.5, 1.5, 1.0), Eigen::Vector3d(2.5, 0.0, -0.5), 0.0);
  const auto track = [&](const Eigen::Isometry3d& world_from_camera) {
    return tracker->Track(
        scene->Render(render::RenderCameraFromIntrinsics(intrinsics, world_from_camera), 2.0, 11));
  };
  ASSERT_TRUE(track(path[10]).ok());
  auto second = track(path[11]);
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_LT(testing::ComparePose(second->camera_from_board, path[11]).position_mm, 10.0);
  ASSERT_TRUE(tracker->last_camera_from_board().has_value());
  EXPECT_TRUE(absl::IsNotFound(track(away).status()));
  EXPECT_FALSE(tracker->last_camera_from_board().has_value());
  auto again = track(path[12]);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_LT(testing::ComparePose(again->camera_from_board, path[12]).position_mm, 10.0);
  EXPECT_TRUE(absl::IsInvalidArgument(tracker->Track(RgbImage(4, 4)).status()));
  EXPECT_TRUE(tracker->last_camera_from_board().has_value());  // Bad input keeps the pose.
  CameraIntrinsics bad = intrinsics;
  bad.fy = -1.0;
  EXPECT_TRUE(absl::IsInvalidArgument(BoardTracker::Create(spec, bad).status()));
}

// --- Intrinsics files ---------------------------------------------------------

TEST(IntrinsicsFile, ParsesExplicitValuesAndDistortion) {
  auto intrinsics = ParseIntrinsicsJson(
      R"({"width": 1280, "height": 720, "fx": 1000, "fy": 1001, "cx": 640.5, "cy": 359.5,
          "distortion": [-0.1, 0.02, 0.001, -0.002, 0.003]})");
  ASSERT_TRUE(intrinsics.ok()) << intrinsics.status();
  EXPECT_EQ(intrinsics->width, 1280);
  EXPECT_DOUBLE_EQ(intrinsics->fy, 1001.0);
  EXPECT_DOUBLE_EQ(intrinsics->k1, -0.1);
  EXPECT_DOUBLE_EQ(intrinsics->p1, 0.001);
  EXPECT_DOUBLE_EQ(intrinsics->p2, -0.002);
  EXPECT_DOUBLE_EQ(intrinsics->k3, 0.003);
  auto again = ParseIntrinsicsJson(FormatIntrinsicsJson(*intrinsics));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_DOUBLE_EQ(again->k3, 0.003);
  EXPECT_DOUBLE_EQ(again->cx, 640.5);
}

TEST(IntrinsicsFile, FieldOfViewDefault) {
  auto from_fov = IntrinsicsFromFieldOfView(1280, 720, 65.0);
  ASSERT_TRUE(from_fov.ok());
  EXPECT_NEAR(from_fov->fx, 640.0 / std::tan(32.5 * std::numbers::pi / 180.0), 1e-9);
  EXPECT_DOUBLE_EQ(from_fov->cx, 639.5);
  EXPECT_DOUBLE_EQ(from_fov->cy, 359.5);
  auto parsed = ParseIntrinsicsJson(R"({"width": 1280, "height": 720, "horizontal_fov_deg": 65})");
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_DOUBLE_EQ(parsed->fx, from_fov->fx);
  EXPECT_TRUE(absl::IsInvalidArgument(IntrinsicsFromFieldOfView(1280, 720, 180.0).status()));
}

TEST(IntrinsicsFile, RejectsBadFiles) {
  for (const char* text :
       {"", "[]", "{", R"({"width": 1280, "height": 720})",
        R"({"width": 1280, "height": 720, "fx": "a", "fy": 1, "cx": 1, "cy": 1})",
        R"({"width": 12.5, "height": 720, "fx": 1, "fy": 1, "cx": 1, "cy": 1})",
        R"({"width": 1280, "height": 720, "fx": -5, "fy": 1, "cx": 1, "cy": 1})",
        R"({"width": 1280, "height": 720, "fx": 1, "fy": 1, "cx": 1, "cy": 1, "k1": 0,
            "distortion": [0, 0, 0, 0]})",
        R"({"width": 1280, "height": 720, "fx": 1, "fy": 1, "cx": 1, "cy": 1,
            "distortion": [0, 0]})"}) {
    EXPECT_TRUE(absl::IsInvalidArgument(ParseIntrinsicsJson(text).status())) << text;
  }
  EXPECT_TRUE(absl::IsNotFound(LoadIntrinsicsFile("/nonexistent/camera.json").status()));
  const std::string dir = reenact::testing::MakeTempDir("intrinsics_file");
  std::ofstream(dir + "/camera.json")
      << R"({"width": 640, "height": 480, "horizontal_fov_deg": 60})";
  auto loaded = LoadIntrinsicsFile(dir + "/camera.json");
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->height, 480);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace reenact::board
