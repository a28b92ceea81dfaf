// Following a synthetic take FrameSet by FrameSet, as the server does while
// a take is ingested.
#include "server/recon/body/live_body.h"

#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/body/joint_set.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::recon {
namespace {

// The take's frames regrouped into FrameSets (by frame index), as the
// capture daemon sends them.
std::vector<FrameSet> FrameSetsOf(RecordedTake take) {
  std::map<int64_t, FrameSet> sets;
  for (SensorFrame& frame : take.frames) {
    if (!frame.depth) continue;
    FrameSet& set = sets[frame.frame_index];
    set.sequence = static_cast<uint64_t>(frame.frame_index) + 1;
    set.stamp_ns = frame.depth->host_stamp_ns;
    set.frames.push_back(std::move(frame));
  }
  std::vector<FrameSet> out;
  for (auto& [index, set] : sets) out.push_back(std::move(set));
  return out;
}

TEST(LiveBodyFollower, FollowsASyntheticTakeFrameSetByFrameSet) {
  const std::string dir = reenact::testing::MakeTempDir("live_body");
  synth::SynthOptions options;
  // The sensors carry the jittered true skeleton (a device SDK stand-in).
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
  options.motion = "builtin:front-kick";
  options.shape = "random:3";
  options.seconds = 2.0;
  options.fps = 15.0;
  options.color_width = 320;
  options.color_height = 180;
  const std::string path = dir + "/take.mcap";
  auto summary = synth::SynthesizeTake(options, path);
  if (!summary.ok() && summary.status().code() == absl::StatusCode::kUnavailable) {
    GTEST_SKIP() << summary.status();
  }
  ASSERT_TRUE(summary.ok()) << summary.status();
  auto take = TakeReader::Open(path);
  ASSERT_TRUE(take.ok());
  RecordedTakeOptions read;
  read.load_color = false;
  auto recorded = ReadRecordedTake(path, read);
  ASSERT_TRUE(recorded.ok()) << recorded.status();
  const TakeInfo info = recorded->info;
  const std::vector<SensorCalibration> sensors = recorded->sensors;
  const std::vector<FrameSet> sets = FrameSetsOf(*std::move(recorded));
  ASSERT_EQ(static_cast<int>(sets.size()), summary->frames);
  auto truth = (*take)->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(truth.ok());

  auto follower = LiveBodyFollower::Create(info, sensors, {{"shape_spacing", "2"}});
  ASSERT_TRUE(follower.ok()) << follower.status();
  // Two passes over the take (the second after the background shape fit
  // has finished); the joints are measured in the second.
  int meshes = 0, frames = 0, settled_at = -1;
  double joint_sum_mm = 0.0, fit_ms = 0.0;
  int joints = 0;
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t k = 0; k < sets.size(); ++k) {
      auto update = (*follower)->Push(sets[k]);
      ASSERT_TRUE(update.ok()) << update.status();
      const int index = pass * static_cast<int>(sets.size()) + static_cast<int>(k);
      if (index == 0) {
        EXPECT_TRUE(update->mesh.has_value()) << "the first FrameSet sends the mesh";
      }
      if (update->mesh) {
        ++meshes;
        if (index > 0) settled_at = index;
      }
      if (!update->frame) continue;
      ++frames;
      fit_ms += update->fit_ms;
      EXPECT_EQ(update->frame->frame_index, index);
      ASSERT_EQ(update->frame->joints_in_world_m.size(), size_t{body::kNumKinectV2Joints});
      if (pass == 0 || settled_at < 0) continue;
      const v1::GroundTruthJoints& g = (*truth)[k];
      for (int i = 0; i < g.joint_names_size(); ++i) {
        auto id = body::KinectV2JointFromName(g.joint_names(i));
        if (!id) continue;
        joint_sum_mm += 1000.0 * (update->frame->joints_in_world_m[body::Index(*id)] -
                                  FromProto(g.positions_in_world_m(i)))
                                     .norm();
        ++joints;
      }
    }
    (*follower)->WaitForShape();
  }
  EXPECT_EQ(meshes, 2) << "the mean-shape mesh, then the fitted shape's";
  EXPECT_TRUE((*follower)->shape_settled());
  EXPECT_EQ(frames, 2 * static_cast<int>(sets.size()));
  ASSERT_GT(joints, 0);
  const double mpjpe_mm = joint_sum_mm / joints;
  std::printf("live: %d FrameSets, shape settled at %d, MPJPE after it %.2f mm, %.1f ms each\n",
              frames, settled_at, mpjpe_mm, fit_ms / frames);
  EXPECT_LE(mpjpe_mm, 15.0);
}

TEST(LiveBodyFollower, BadOptionsAreInvalidArgument) {
  const TakeInfo info;
  EXPECT_EQ(LiveBodyFollower::Create(info, {}, {{"shape_spacing", "0"}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LiveBodyFollower::Create(info, {}, {{"unknown", "1"}}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::recon
