#include "common/tracking/training_data.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>

#include <gtest/gtest.h>

#include "common/body/procedural_body.h"
#include "common/testing/test_data.h"
#include "common/tracking/body_part_forest.h"
#include "common/tracking/forest_training.h"

namespace reenact::tracking {
namespace {

TrainingDataOptions SmallOptions(int images) {
  TrainingDataOptions o;
  o.motion_paths = {testing::TestDataPath("mocap/cmu-train/02_01.bvh")};
  o.shapes_per_body = 2;
  o.num_images = images;
  o.frame_stride = 10;
  o.arm_pose_fraction = 0.0;  // The clip's own poses.
  return o;
}

TEST(VertexParts, HeadAndFeetOfTheProceduralBody) {
  auto model = body::BuildProceduralBody();
  ASSERT_TRUE(model.ok()) << model.status();
  const std::vector<uint8_t> parts = VertexParts(*model);
  ASSERT_EQ(parts.size(), static_cast<size_t>(model->num_vertices()));
  Eigen::Index top = 0, bottom = 0;
  model->template_vertices_m.row(1).maxCoeff(&top);
  model->template_vertices_m.row(1).minCoeff(&bottom);
  EXPECT_EQ(parts[static_cast<size_t>(top)], body::Index(body::KinectV2Joint::kHead));
  const int foot = parts[static_cast<size_t>(bottom)];
  EXPECT_TRUE(foot == body::Index(body::KinectV2Joint::kAnkleLeft) ||
              foot == body::Index(body::KinectV2Joint::kAnkleRight) ||
              foot == body::Index(body::KinectV2Joint::kFootLeft) ||
              foot == body::Index(body::KinectV2Joint::kFootRight))
      << foot;
  std::map<int, int> count;
  for (uint8_t p : parts) ++count[p];
  EXPECT_GE(count.size(), 15u);  // Most joints move some of the body.
}

TEST(SynthesizeTrainingImages, PersonDepthMatchesItsJoints) {
  const std::string motion = testing::TestDataPath("mocap/cmu-train/02_01.bvh");
  REENACT_REQUIRE_TEST_FILE(motion);
  auto images = SynthesizeTrainingImages(SmallOptions(12), /*keep_full_frames=*/true);
  ASSERT_TRUE(images.ok()) << images.status();
  ASSERT_GE(images->size(), 10u);
  for (const TrainingImage& image : *images) {
    // The person's depth lies within 0.45 m of the SpineBase's depth
    // (a torso is about 0.3 m deep, limbs reach further), but for the
    // silhouette's flying pixels (the noise model mixes person and
    // background there, as real time-of-flight sensors do: about 10 % of a
    // person's pixels at these distances); and the joints project into the
    // crop.
    const double spine_z = image.joints_in_camera_m[0].z();
    int on_person = 0, near = 0;
    for (size_t i = 0; i < image.part.size(); ++i) {
      if (image.part[i] == kNoPart) continue;
      ++on_person;
      near += std::abs(image.depth_m.data[i] - spine_z) < 0.45 ? 1 : 0;
    }
    ASSERT_GT(on_person, 500);
    EXPECT_GT(static_cast<double>(near) / on_person, 0.85);
    const Eigen::Vector3d& p =
        image.joints_in_camera_m[body::Index(body::KinectV2Joint::kSpineMid)];
    const double u = image.intrinsics.fx * p.x() / p.z() + image.intrinsics.cx;
    EXPECT_GT(u, -5.0);
    EXPECT_LT(u, image.intrinsics.width + 5.0);
    // The full frame's mask covers the same pixels as the crop's parts.
    int masked = 0;
    for (uint8_t m : image.full_mask.data) masked += m;
    EXPECT_EQ(masked, on_person);
  }
}

// The arms posed at random come before the body (guards, crossed arms) and
// keep their bone lengths; the motion's own arms mostly hang at the sides.
TEST(SynthesizeTrainingImages, ArmsPosedAtRandomComeBeforeTheBody) {
  REENACT_REQUIRE_TEST_FILE(testing::TestDataPath("mocap/cmu-train/02_01.bvh"));
  using J = body::KinectV2Joint;
  // Per image: the wrists' mean distance before the chest (along the
  // torso's forward axis), metres, and the largest change of a forearm's
  // length against the motion's own arms.
  const auto measure = [](const std::vector<TrainingImage>& images) {
    double forward_sum = 0.0;
    int n = 0;
    for (const TrainingImage& image : images) {
      const auto& p = image.joints_in_camera_m;
      const auto at = [&](J j) { return p[body::Index(j)]; };
      const Eigen::Vector3d left = (at(J::kShoulderLeft) - at(J::kShoulderRight)).normalized();
      const Eigen::Vector3d up = (at(J::kSpineShoulder) - at(J::kSpineBase)).normalized();
      const Eigen::Vector3d forward = left.cross(up).normalized();
      for (J wrist : {J::kWristLeft, J::kWristRight}) {
        forward_sum += (at(wrist) - at(J::kSpineMid)).dot(forward);
        ++n;
      }
    }
    return n > 0 ? forward_sum / n : std::nan("");
  };
  const auto forearm = [](const TrainingImage& image) {
    const auto& p = image.joints_in_camera_m;
    return (p[body::Index(J::kWristLeft)] - p[body::Index(J::kElbowLeft)]).norm();
  };
  TrainingDataOptions as_they_are = SmallOptions(40);
  as_they_are.arm_pose_fraction = 0.0;
  TrainingDataOptions posed = as_they_are;
  posed.arm_pose_fraction = 1.0;
  auto plain = SynthesizeTrainingImages(as_they_are);
  auto augmented = SynthesizeTrainingImages(posed);
  ASSERT_TRUE(plain.ok() && augmented.ok());
  ASSERT_GE(plain->size(), 30u);
  ASSERT_GE(augmented->size(), 30u);
  const double plain_forward_m = measure(*plain);
  const double augmented_forward_m = measure(*augmented);
  std::cout << "wrists before the SpineMid: " << 100 * plain_forward_m << " cm as the motion has "
            << "them, " << 100 * augmented_forward_m << " cm posed at random\n";
  EXPECT_GT(augmented_forward_m, plain_forward_m + 0.1);  // m
  // Bones keep their lengths: the forearm of one actor is one length.
  double shortest = 1e9, longest = 0.0;
  for (const TrainingImage& image : *augmented) {
    shortest = std::min(shortest, forearm(image));
    longest = std::max(longest, forearm(image));
  }
  double plain_shortest = 1e9, plain_longest = 0.0;
  for (const TrainingImage& image : *plain) {
    plain_shortest = std::min(plain_shortest, forearm(image));
    plain_longest = std::max(plain_longest, forearm(image));
  }
  EXPECT_NEAR(shortest, plain_shortest, 0.01);  // m
  EXPECT_NEAR(longest, plain_longest, 0.01);    // m
  TrainingDataOptions bad = as_they_are;
  bad.arm_pose_fraction = 1.5;
  EXPECT_EQ(bad.Validate().code(), absl::StatusCode::kInvalidArgument);
}

TEST(ApplyStructuredLightNoise, DepthComesInDisparitySteps) {
  // A slanted plane from 1.5 to 3.5 m: the distinct depths reported near 2 m
  // and 3 m are z^2 / (8 * 580 * 0.075) apart: 11.5 mm and 25.9 mm.
  FloatImage ideal(400, 50);
  for (int y = 0; y < 50; ++y) {
    for (int x = 0; x < 400; ++x) ideal.at(x, y) = 1.5f + 2.0f * x / 400.0f;
  }
  const DepthImageMm noisy = ApplyStructuredLightNoise(ideal, 7);
  for (double z : {2.0, 3.0}) {
    std::vector<int> values;
    for (uint16_t v : noisy.data) {
      if (std::abs(v - z * 1000) < 80) values.push_back(v);
    }
    std::sort(values.begin(), values.end());
    values.erase(std::unique(values.begin(), values.end()), values.end());
    ASSERT_GE(values.size(), 5u);
    const double step = static_cast<double>(values.back() - values.front()) / (values.size() - 1);
    EXPECT_NEAR(step, z * z * 1000 / (8 * 580 * 0.075), 0.15 * z * z * 1000 / 348.0) << z;
  }
}

TEST(TrainForest, LearnsPartsBetterThanChance) {
  REENACT_REQUIRE_TEST_FILE(testing::TestDataPath("mocap/cmu-train/02_01.bvh"));
  auto train = SynthesizeTrainingImages(SmallOptions(60));
  ASSERT_TRUE(train.ok()) << train.status();
  ForestTrainingOptions o;
  o.num_trees = 1, o.max_depth = 12, o.pixels_per_image = 300, o.features_per_node = 50;
  ForestTrainingSummary summary;
  auto forest = TrainForest(*train, o, "test", &summary);
  ASSERT_TRUE(forest.ok()) << forest.status();
  EXPECT_LE(summary.max_depth, 12);
  EXPECT_GT(summary.leaves, 100);
  // Part accuracy on other images of the same kind (seed 2).
  TrainingDataOptions test_options = SmallOptions(20);
  test_options.seed = 2;
  auto test = SynthesizeTrainingImages(test_options);
  ASSERT_TRUE(test.ok());
  int64_t right = 0, total = 0;
  for (const TrainingImage& image : *test) {
    const DepthProbe probe{image.depth_m.data.data(), image.depth_m.width, image.depth_m.height,
                           static_cast<float>(image.intrinsics.fx),
                           static_cast<float>(image.intrinsics.fy)};
    for (int y = 0; y < image.depth_m.height; y += 3) {
      for (int x = 0; x < image.depth_m.width; x += 3) {
        const uint8_t truth = image.part[static_cast<size_t>(y) * image.depth_m.width + x];
        if (truth == kNoPart) continue;
        const ForestLeaf& leaf =
            DescendTree(forest->trees()[0], probe, x, y, image.depth_m.at(x, y));
        const auto best =
            std::max_element(leaf.part_probability.begin(), leaf.part_probability.end());
        right += (best - leaf.part_probability.begin()) == truth ? 1 : 0;
        ++total;
      }
    }
  }
  const double accuracy = static_cast<double>(right) / total;
  std::cout << "[ figure ] part accuracy of a small forest on unseen images: " << accuracy << " ("
            << total << " pixels)\n";
  EXPECT_GT(accuracy, 0.35);  // Chance is below 0.1 over 20-odd parts.
}

}  // namespace
}  // namespace reenact::tracking
