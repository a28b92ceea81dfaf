#include "common/tracking/person_segmentation.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/testing/test_data.h"
#include "common/tracking/training_data.h"

namespace reenact::tracking {
namespace {

CameraIntrinsics Intrinsics(int w, int h, double f, double cx, double cy) {
  CameraIntrinsics k;
  k.width = w, k.height = h, k.fx = f, k.fy = f, k.cx = cx, k.cy = cy;
  return k;
}

TEST(SegmentPeople, FindsTheFivePeopleAndTheFloorOfARealKinectFrame) {
  const std::string path =
      testing::TestDataPath("rgbd/pcl-five-people/derived/five_people_depth_mm.png");
  REENACT_REQUIRE_TEST_FILE(path);
  const cv::Mat image = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(image.type(), CV_16UC1);
  DepthImageMm depth(image.cols, image.rows);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) depth.at(x, y) = image.at<uint16_t>(y, x);
  }
  auto result = SegmentPeople(depth, Intrinsics(640, 480, 525.0, 319.5, 239.5));
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_EQ(result->people.size(), 5u);
  // The published ground plane of the frame (data README): normal
  // (-0.0104, 0.9970, 0.0766) with y down in the camera, d = -1.266; ours
  // points up (-y), so it is the negated plane, within 5 degrees and 5 cm.
  ASSERT_TRUE(result->floor_plane.has_value());
  const Eigen::Vector3d published(-0.0103586, 0.997011, 0.0765573);
  const Eigen::Vector3d ours = -result->floor_plane->head<3>();
  const double angle_deg = std::acos(std::min(1.0, ours.normalized().dot(published))) * 180 / M_PI;
  std::printf("floor: %.2f deg from the published plane, d %.3f m vs %.3f m\n", angle_deg,
              -(*result->floor_plane)(3), -1.26614);
  EXPECT_LT(angle_deg, 5.0);
  EXPECT_NEAR(-(*result->floor_plane)(3), -1.26614, 0.05);
  // Largest first, labelled 1..5, each a standing person's size.
  for (size_t i = 0; i < result->people.size(); ++i) {
    const PersonSegment& p = result->people[i];
    if (i > 0) {
      EXPECT_LE(p.num_pixels, result->people[i - 1].num_pixels);
    }
    EXPECT_GE(p.label, 1);
    EXPECT_LE(p.label, 5);
    EXPECT_GT(p.num_pixels, 2000);
    EXPECT_GT(p.centroid_in_camera_m.z(), 1.5);
    EXPECT_LT(p.centroid_in_camera_m.z(), 3.0);
    const double height_m = (p.max_y - p.min_y) * p.centroid_in_camera_m.z() / 525.0;
    EXPECT_GT(height_m, 1.2) << "person " << p.label;
    EXPECT_LT(height_m, 2.1) << "person " << p.label;
  }
}

// On synthesised frames (a held-out motion, Kinect v2 noise, room with floor
// and wall) the segmentation covers the true person mask with IoU >= 0.85.
TEST(SegmentPeople, CoversTheTruePersonOfSynthesisedFrames) {
  const std::string motion = testing::TestDataPath("mocap/cmu/131_01.bvh");
  REENACT_REQUIRE_TEST_FILE(motion);
  TrainingDataOptions o = SequenceOptions(motion, 8, 1.8, 3.5, 17);
  auto images = SynthesizeTrainingImages(o, /*keep_full_frames=*/true);
  ASSERT_TRUE(images.ok()) << images.status();
  double iou_sum = 0.0;
  for (const TrainingImage& image : *images) {
    auto result = SegmentPeople(image.full_depth_mm, image.full_intrinsics);
    ASSERT_TRUE(result.ok()) << result.status();
    ASSERT_GE(result->people.size(), 1u);
    const int label = result->people.front().label;
    int both = 0, either = 0;
    for (size_t i = 0; i < image.full_mask.data.size(); ++i) {
      const bool truth = image.full_mask.data[i] != 0 && image.full_depth_mm.data[i] != 0;
      const bool ours = result->labels.data[i] == label;
      both += truth && ours;
      either += truth || ours;
    }
    ASSERT_GT(either, 0);
    iou_sum += static_cast<double>(both) / either;
  }
  const double iou = iou_sum / images->size();
  std::printf("mean IoU of the largest segment with the true person: %.3f\n", iou);
  EXPECT_GT(iou, 0.85);
}

// A person seen side-on by a Kinect v1 (structured-light noise) with a
// hand raised before the face: the arm lies 0.1-0.3 m in front of the head
// and chest, so the head and the arm come out as pieces apart from the
// body, and join it (step 4). Worst frame's IoU with the true person mask.
TEST(SegmentPeople, PiecesCutOffByTheArmsJoinThePerson) {
  const std::string motion = testing::TestDataPath("mocap/cmu/01_01.bvh");
  REENACT_REQUIRE_TEST_FILE(motion);
  TrainingDataOptions o = SequenceOptions(motion, 20, 2.0, 2.5, 31);
  o.camera = Intrinsics(640, 480, 594.2, 339.3, 242.7);  // A Kinect v1 depth camera.
  o.structured_light_fraction = 1.0;
  auto images = SynthesizeTrainingImages(o, /*keep_full_frames=*/true);
  ASSERT_TRUE(images.ok()) << images.status();
  PersonSegmentationOptions apart;
  apart.attach_step_m = 0.0;
  double worst = 1.0, worst_apart = 1.0;
  for (const TrainingImage& image : *images) {
    double iou[2] = {0.0, 0.0};
    for (const bool attach : {true, false}) {
      auto result = SegmentPeople(image.full_depth_mm, image.full_intrinsics,
                                  attach ? PersonSegmentationOptions{} : apart);
      ASSERT_TRUE(result.ok()) << result.status();
      ASSERT_EQ(result->people.size(), 1u);
      int both = 0, either = 0;
      for (size_t i = 0; i < image.full_mask.data.size(); ++i) {
        const bool truth = image.full_mask.data[i] != 0 && image.full_depth_mm.data[i] != 0;
        const bool ours = result->labels.data[i] == result->people.front().label;
        both += truth && ours;
        either += truth || ours;
      }
      ASSERT_GT(either, 0);
      iou[attach ? 0 : 1] = static_cast<double>(both) / either;
    }
    worst = std::min(worst, iou[0]);
    worst_apart = std::min(worst_apart, iou[1]);
  }
  std::printf("worst IoU with the true person: %.3f (pieces left apart: %.3f)\n", worst,
              worst_apart);
  EXPECT_GT(worst, 0.85);
}

TEST(SegmentPeople, NobodyAndBadInput) {
  const CameraIntrinsics k = Intrinsics(64, 48, 50.0, 32.0, 24.0);
  auto empty = SegmentPeople(DepthImageMm(64, 48, 0), k);
  ASSERT_TRUE(empty.ok()) << empty.status();
  EXPECT_TRUE(empty->people.empty());
  auto wall = SegmentPeople(DepthImageMm(64, 48, 3000), k);
  ASSERT_TRUE(wall.ok()) << wall.status();
  EXPECT_TRUE(wall->people.empty());
  EXPECT_EQ(SegmentPeople(DepthImageMm(10, 10, 1000), k).status().code(),
            absl::StatusCode::kInvalidArgument);
  CameraIntrinsics nan_k = k;
  nan_k.cy = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(SegmentPeople(DepthImageMm(64, 48, 1000), nan_k).status().code(),
            absl::StatusCode::kInvalidArgument);
  PersonSegmentationOptions bad;
  bad.min_points = -1;
  EXPECT_EQ(SegmentPeople(DepthImageMm(64, 48, 1000), k, bad).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::tracking
