#include "common/tracking/body_part_forest.h"

#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::tracking {
namespace {

// Root splits on the depth 0.1 m to the right of the pixel against the pixel
// itself; leaf 0 (left) votes for the head 0.2 m above, leaf 1 for SpineBase.
BodyPartForest TwoLeafForest() {
  DecisionTree tree;
  ForestNode root;
  root.left = 1, root.right = 2;
  root.feature = {0.1f, 0.0f, 0.0f, 0.0f, 0.5f};
  tree.nodes = {root, ForestNode{-1, -1, 0, {}}, ForestNode{-1, -1, 1, {}}};
  for (int l = 0; l < 2; ++l) {
    ForestLeaf leaf;
    leaf.part_probability = std::vector<float>(25, 0.0f);
    leaf.part_probability[l == 0 ? 3 : 0] = 1.0f;
    leaf.votes[0] = JointVote{static_cast<uint8_t>(l == 0 ? 3 : 0), 0.8f,
                              Eigen::Vector3f(0.0f, l == 0 ? -0.2f : 0.1f, 0.05f)};
    tree.leaves.push_back(leaf);
  }
  return BodyPartForest(25, {tree}, "two leaves");
}

std::string ReadAll(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

TEST(BodyPartForest, SaveLoadKeepsStructureWithinQuantisation) {
  const std::string dir = testing::MakeTempDir("forest_roundtrip");
  const BodyPartForest forest = TwoLeafForest();
  ASSERT_TRUE(forest.Save(dir + "/f.rtf").ok());
  auto loaded = BodyPartForest::Load(dir + "/f.rtf");
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->description(), "two leaves");
  ASSERT_EQ(loaded->trees().size(), 1u);
  const DecisionTree& t = loaded->trees()[0];
  ASSERT_EQ(t.nodes.size(), 3u);
  EXPECT_NEAR(t.nodes[0].feature.u_x_m, 0.1f, 0.0005f);  // Stored in mm.
  EXPECT_FLOAT_EQ(t.nodes[0].feature.threshold_m, 0.5f);
  EXPECT_NEAR(t.leaves[0].votes[0].offset_m.y(), -0.2f, 0.0005f);
  EXPECT_NEAR(t.leaves[0].votes[0].weight, 0.8f, 1.0f / 255);
  EXPECT_NEAR(t.leaves[0].part_probability[3], 1.0f, 1e-6f);
  EXPECT_EQ(t.leaves[0].votes[1].joint, kNoJoint);
  EXPECT_EQ(loaded->max_depth(), 1);
}

TEST(BodyPartForest, DescendsByTheDepthFeature) {
  const BodyPartForest forest = TwoLeafForest();
  // A 40x10 image at 2 m; right half 1 m deeper (a step).
  std::vector<float> depth(400, 2.0f);
  for (int y = 0; y < 10; ++y) {
    for (int x = 20; x < 40; ++x) depth[static_cast<size_t>(y) * 40 + x] = 3.0f;
  }
  const DepthProbe probe{depth.data(), 40, 10, 200.0f, 200.0f};
  // 0.1 m at 2 m with f = 200 px is 10 px: from x = 5 the probe stays at 2 m
  // (f = 0 < 0.5: left); from x = 15 it reads 3 m (f = 1: right).
  EXPECT_EQ(DescendTree(forest.trees()[0], probe, 5, 5, 2.0f).votes[0].joint, 3);
  EXPECT_EQ(DescendTree(forest.trees()[0], probe, 15, 5, 2.0f).votes[0].joint, 0);
  // Off the image the probe reads the background (8 m): right.
  EXPECT_EQ(DescendTree(forest.trees()[0], probe, 35, 5, 3.0f).votes[0].joint, 0);
}

TEST(BodyPartForest, EveryTruncationIsDataLoss) {
  const std::string dir = testing::MakeTempDir("forest_truncated");
  ASSERT_TRUE(TwoLeafForest().Save(dir + "/f.rtf").ok());
  const std::string bytes = ReadAll(dir + "/f.rtf");
  for (size_t n = 0; n < bytes.size(); ++n) {
    auto parsed = BodyPartForest::Parse(bytes.substr(0, n));
    ASSERT_FALSE(parsed.ok()) << n;
    EXPECT_TRUE(absl::IsDataLoss(parsed.status())) << n << ": " << parsed.status();
  }
}

TEST(BodyPartForest, HostileCountsAndLinksAreRefused) {
  const std::string dir = testing::MakeTempDir("forest_hostile");
  ASSERT_TRUE(TwoLeafForest().Save(dir + "/f.rtf").ok());
  const std::string bytes = ReadAll(dir + "/f.rtf");
  const size_t tree_header = 8 + 4 * 4 + std::strlen("two leaves");
  // A node count of 2^32 - 16: refused before anything is sized.
  std::string huge = bytes;
  const uint32_t big = 0xfffffff0u;
  std::memcpy(&huge[tree_header], &big, 4);
  EXPECT_TRUE(absl::IsDataLoss(BodyPartForest::Parse(huge).status()));
  // The root's left child pointing back at the root (a cycle).
  std::string cycle = bytes;
  const int32_t zero = 0;
  std::memcpy(&cycle[tree_header + 8], &zero, 4);
  EXPECT_TRUE(absl::IsDataLoss(BodyPartForest::Parse(cycle).status()));
  // A vote for joint 200.
  std::string joint = bytes;
  joint[tree_header + 8 + 3 * 24 + 25] = static_cast<char>(200);
  EXPECT_TRUE(absl::IsDataLoss(BodyPartForest::Parse(joint).status()));
  EXPECT_TRUE(absl::IsDataLoss(BodyPartForest::Parse("RTFOREST").status()));
  EXPECT_TRUE(absl::IsNotFound(BodyPartForest::Load(dir + "/missing.rtf").status()));
}

}  // namespace
}  // namespace reenact::tracking
