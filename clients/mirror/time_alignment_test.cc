#include "clients/mirror/time_alignment.h"

#include <cmath>
#include <iostream>
#include <numbers>

#include <gtest/gtest.h>

#include "clients/mirror/pose_comparison.h"
#include "clients/mirror/testing/mocap_learners.h"

namespace reenact::mirror {
namespace {

using body::SkeletonPose;

// Mean error of `pairs` (frames without a comparable part left out).
double MeanErrorDeg(const std::vector<SkeletonPose>& learner,
                    const std::vector<SkeletonPose>& teacher, const std::vector<FramePair>& pairs) {
  double sum = 0.0;
  int count = 0;
  for (const FramePair& pair : pairs) {
    const PoseComparison c = ComparePoses(learner[pair.learner_frame], teacher[pair.teacher_frame]);
    if (!c.mean_error_deg) continue;
    sum += *c.mean_error_deg;
    ++count;
  }
  return count > 0 ? sum / count : 0.0;
}

// The teacher frame a warped learner shows at learner frame i: slow first,
// then fast (a monotone warp that strays up to 10% of the length off the
// diagonal).
int WarpedTeacherFrame(int i, int num_learner, int num_teacher) {
  const double u = static_cast<double>(i) / (num_learner - 1);
  const double warped = u - 0.1 * std::sin(2.0 * std::numbers::pi * u);
  return static_cast<int>(std::lround(warped * (num_teacher - 1)));
}

TEST(AlignByDtw, RecoversAKnownTimeWarpBetterThanOneToOne) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = testing::LoadCmuTeacher(4);  // 30 fps.
  ASSERT_GT(teacher.size(), 100u);
  const int num_teacher = static_cast<int>(teacher.size());
  const int num_learner = num_teacher * 5 / 4;  // Played slower overall, unevenly.
  std::vector<SkeletonPose> learner;
  std::vector<int> truth;
  for (int i = 0; i < num_learner; ++i) {
    truth.push_back(WarpedTeacherFrame(i, num_learner, num_teacher));
    learner.push_back(
        TransformPose(testing::SensorInFrontOf(teacher[truth.back()]), teacher[truth.back()]));
  }
  const Alignment one_to_one = AlignOneToOne(num_learner, num_teacher);
  const double one_to_one_deg = MeanErrorDeg(learner, teacher, one_to_one.pairs);
  for (int band : {0, 40}) {
    absl::StatusOr<Alignment> dtw = AlignByDtw(learner, teacher, {.band_frames = band});
    ASSERT_TRUE(dtw.ok()) << dtw.status();
    double index_error_sum = 0.0;
    for (const FramePair& pair : dtw->pairs) {
      index_error_sum += std::abs(pair.teacher_frame - truth[pair.learner_frame]);
    }
    const double mean_index_error = index_error_sum / dtw->pairs.size();
    const double dtw_deg = MeanErrorDeg(learner, teacher, dtw->pairs);
    std::cout << "time warp, " << num_learner << " learner / " << num_teacher
              << " teacher frames, band " << band << ": one to one " << one_to_one_deg
              << " deg, DTW " << dtw_deg << " deg (path mean " << dtw->mean_distance_deg
              << "), DTW off the true warp by " << mean_index_error << " frames on average\n";
    RecordProperty("one_to_one_deg", std::to_string(one_to_one_deg));
    RecordProperty("dtw_deg_band_" + std::to_string(band), std::to_string(dtw_deg));
    EXPECT_LT(dtw_deg, one_to_one_deg);
    EXPECT_LT(dtw_deg, 1.0);
    EXPECT_LT(mean_index_error, 1.0);
    EXPECT_EQ(dtw->pairs.front(), (FramePair{0, 0}));
    EXPECT_EQ(dtw->pairs.back(), (FramePair{num_learner - 1, num_teacher - 1}));
  }
  EXPECT_GT(one_to_one_deg, 5.0);
}

TEST(AlignByDtw, RejectsBadInput) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = testing::LoadCmuTeacher(4, 2);
  const std::vector<SkeletonPose> learner = testing::LoadCmuTeacher(1, 100);
  EXPECT_FALSE(AlignByDtw({}, teacher).ok());
  EXPECT_FALSE(AlignByDtw(learner, teacher, {.band_frames = -1}).ok());
  // 100 learner frames onto 2 teacher frames cannot stay within 1 frame of
  // the diagonal.
  EXPECT_FALSE(AlignByDtw(learner, teacher, {.band_frames = 1}).ok());
  EXPECT_FALSE(AlignByDtw(learner, teacher, {.max_cells = 10}).ok());
  // Frames without skeletons still align (at missing_cost_deg).
  absl::StatusOr<Alignment> blank =
      AlignByDtw(std::vector<SkeletonPose>(3), std::vector<SkeletonPose>(4));
  ASSERT_TRUE(blank.ok());
  EXPECT_DOUBLE_EQ(blank->mean_distance_deg, 90.0);
}

TEST(AlignOneToOne, PairsIndexWithIndex) {
  const Alignment alignment = AlignOneToOne(5, 3);
  ASSERT_EQ(alignment.pairs.size(), 3u);
  EXPECT_EQ(alignment.pairs[2], (FramePair{2, 2}));
  EXPECT_TRUE(AlignOneToOne(-1, 3).pairs.empty());
}

}  // namespace
}  // namespace reenact::mirror
