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
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"

namespace reenact::recon {
namespace {

// The take's frames regrouped into FrameSets (by frame index), as the
// capture daemon sends them.
std::vector<v1::FrameSet> FrameSetsOf(const TakeReader& take) {
  std::map<int64_t, v1::FrameSet> sets;
  for (const auto& [id, calibration] : take.sensors()) {
    auto depths = take.ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    auto masks = take.ReadAll<v1::ActorMask>(SensorTopic(id, "mask"));
    auto skeletons = take.ReadAll<v1::Skeleton>(SensorTopic(id, "skeleton"));
    EXPECT_TRUE(depths.ok() && masks.ok() && skeletons.ok());
    if (!depths.ok() || !masks.ok() || !skeletons.ok()) return {};
    std::map<int64_t, v1::Frame> frames;
    for (const v1::DepthImage& d : *depths) {
      v1::Frame& f = frames[d.frame_index()];
      f.set_sensor_id(id);
      f.set_frame_index(d.frame_index());
      f.set_host_stamp_ns(d.host_stamp_ns());
      *f.mutable_depth() = d;
    }
    for (const v1::ActorMask& m : *masks) *frames[m.frame_index()].mutable_mask() = m;
    for (const v1::Skeleton& s : *skeletons) *frames[s.frame_index()].add_skeletons() = s;
    for (auto& [index, frame] : frames) {
      v1::FrameSet& set = sets[index];
      set.set_sequence(static_cast<uint64_t>(index) + 1);
      set.set_stamp_ns(frame.host_stamp_ns());
      *set.add_frames() = std::move(frame);
    }
  }
  std::vector<v1::FrameSet> out;
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
  std::vector<v1::SensorCalibration> sensors;
  for (const auto& [id, calibration] : (*take)->sensors()) sensors.push_back(calibration);
  const std::vector<v1::FrameSet> sets = FrameSetsOf(**take);
  ASSERT_EQ(static_cast<int>(sets.size()), summary->frames);
  auto truth = (*take)->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  ASSERT_TRUE(truth.ok());

  auto follower = LiveBodyFollower::Create((*take)->info(), sensors,
                                           {{"live", "true"}, {"shape_spacing", "2"}});
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
      EXPECT_EQ(update->frame->frame_index(), index);
      ASSERT_EQ(update->frame->joints_in_world_m_size(), body::kNumKinectV2Joints);
      if (pass == 0 || settled_at < 0) continue;
      const v1::GroundTruthJoints& g = (*truth)[k];
      for (int i = 0; i < g.joint_names_size(); ++i) {
        auto id = body::KinectV2JointFromName(g.joint_names(i));
        if (!id) continue;
        joint_sum_mm += 1000.0 * (FromProto(update->frame->joints_in_world_m(body::Index(*id))) -
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
  v1::TakeInfo info;
  EXPECT_EQ(LiveBodyFollower::Create(info, {}, {{"shape_spacing", "0"}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LiveBodyFollower::Create(info, {}, {{"unknown", "1"}}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::recon
