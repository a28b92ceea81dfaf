#include "server/recon/take_frames.h"

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include <gtest/gtest.h>

#include "common/io/depth_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "server/recon/testing/short_take.h"

namespace reenact::recon {
namespace {

using recon::testing::GetSharedTake;

// Ground-truth joints by frame index.
std::map<int64_t, JointArray> TruthJoints(const std::string& path) {
  std::map<int64_t, JointArray> truth;
  auto reader = TakeReader::Open(path);
  EXPECT_TRUE(reader.ok()) << reader.status();
  if (!reader.ok()) return truth;
  auto all = (*reader)->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  EXPECT_TRUE(all.ok()) << all.status();
  if (!all.ok()) return truth;
  for (const v1::GroundTruthJoints& g : *all) {
    JointArray joints = MissingJoints();
    for (int i = 0; i < g.joint_names_size() && i < g.positions_in_world_m_size(); ++i) {
      if (auto j = body::KinectV2JointFromName(g.joint_names(i))) {
        joints[body::Index(*j)] = FromProto(g.positions_in_world_m(i));
      }
    }
    truth[g.frame_index()] = joints;
  }
  return truth;
}

TEST(TakeFrames, LoadsTheSyntheticTake) {
  RECON_REQUIRE_SHARED_TAKE();
  const auto& shared = GetSharedTake();
  auto take = TakeFrames::Load(shared.path);
  ASSERT_TRUE(take.ok()) << take.status();
  const TakeFrames& t = **take;
  EXPECT_EQ(t.num_sensors(), 2);
  EXPECT_EQ(t.num_instants(), shared.summary.frames);
  EXPECT_EQ(t.num_valid_instants(), shared.summary.frames);
  EXPECT_FALSE(t.grouped_by_frame_sets());
  EXPECT_NEAR(t.fps(), 15.0, 1e-9);
  EXPECT_NEAR(t.duration_s(), (shared.summary.frames - 1) / 15.0, 0.01);
  for (int i = 1; i < t.num_instants(); ++i) {
    EXPECT_GT(t.instant(i).stamp_ns, t.instant(i - 1).stamp_ns);
  }
  for (const Instant& instant : t.instants()) {
    for (const SensorView& view : instant.views) {
      EXPECT_TRUE(view.present);
      EXPECT_TRUE(view.has_skeleton);
      EXPECT_FALSE(view.color_jpeg.empty());
      EXPECT_GT(view.tracked_joint_count, 10);
    }
  }
  const TakeSensor& k0 = t.sensors()[0];
  EXPECT_EQ(k0.depth_intrinsics.width, 512);
  EXPECT_EQ(k0.color_intrinsics.width, 640);
  EXPECT_NEAR(k0.depth_scale_m_per_unit, 0.001, 1e-12);
}

// The fused skeleton (mean over the two sensors) against the ground truth:
// the synthetic sensor skeletons carry 10 mm (tracked) / 30 mm (inferred)
// Gaussian noise per axis, so one sensor's mean 3-D error is about 16 mm
// and the mean of two about 11 mm.
TEST(TakeFrames, FusedSkeletonMatchesGroundTruth) {
  RECON_REQUIRE_SHARED_TAKE();
  const auto& shared = GetSharedTake();
  auto take = TakeFrames::Load(shared.path);
  ASSERT_TRUE(take.ok()) << take.status();
  const auto truth = TruthJoints(shared.path);
  ASSERT_EQ(static_cast<int>(truth.size()), (*take)->num_instants());
  double fused_sum = 0, single_sum = 0;
  int fused_n = 0, single_n = 0;
  for (const Instant& instant : (*take)->instants()) {
    auto it = truth.find(instant.views[0].frame_index);
    ASSERT_NE(it, truth.end());
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      ASSERT_TRUE(IsJointValid(instant.joints_in_world_m[j]));
      fused_sum += (instant.joints_in_world_m[j] - it->second[j]).norm();
      ++fused_n;
      const Eigen::Vector3d& one = instant.views[0].joints_in_world_m[j];
      if (IsJointValid(one)) {
        single_sum += (one - it->second[j]).norm();
        ++single_n;
      }
    }
  }
  const double fused_mm = 1e3 * fused_sum / fused_n;
  const double single_mm = 1e3 * single_sum / single_n;
  std::printf(
      "[ figures  ] fused skeleton mean error %.1f mm over %d joints; sensor k0 alone "
      "(tracked joints) %.1f mm\n",
      fused_mm, fused_n, single_mm);
  EXPECT_LT(fused_mm, 16.0);
  EXPECT_LT(single_mm, 22.0);
}

TEST(TakeFrames, DecodesDepthMaskAndColour) {
  RECON_REQUIRE_SHARED_TAKE();
  auto take = TakeFrames::Load(GetSharedTake().path);
  ASSERT_TRUE(take.ok()) << take.status();
  const TakeFrames& t = **take;
  auto depth = t.LoadDepth(3, 1);
  ASSERT_TRUE(depth.ok()) << depth.status();
  EXPECT_EQ(depth->width, 512);
  EXPECT_EQ(depth->height, 424);
  auto mask = t.LoadActorMask(3, 1);
  ASSERT_TRUE(mask.ok()) << mask.status();
  int actor = 0, with_depth = 0;
  for (size_t i = 0; i < mask->data.size(); ++i) {
    actor += mask->data[i] ? 1 : 0;
    with_depth += depth->data[i] > 0 ? 1 : 0;
    if (mask->data[i]) {
      EXPECT_GT(depth->data[i], 0);
    }
  }
  EXPECT_GT(actor, 2000);        // A person at 2.5 m covers ~10k depth pixels.
  EXPECT_LT(actor, with_depth);  // The room is not the actor.
  auto actor_depth = t.LoadActorDepth(3, 1);
  ASSERT_TRUE(actor_depth.ok());
  int nonzero = 0;
  for (uint16_t d : actor_depth->data) nonzero += d > 0 ? 1 : 0;
  EXPECT_EQ(nonzero, actor);

  auto full = t.LoadColor(3, 0);
  ASSERT_TRUE(full.ok()) << full.status();
  EXPECT_EQ(full->width, 640);
  EXPECT_EQ(full->height, 360);
  auto half = t.LoadColor(3, 0, 2);
  ASSERT_TRUE(half.ok()) << half.status();
  EXPECT_EQ(half->width, 320);
  EXPECT_EQ(half->height, 180);
  auto k = t.ColorIntrinsicsForImage(0, *half);
  ASSERT_TRUE(k.ok());
  EXPECT_NEAR(k->fx, t.sensors()[0].color_intrinsics.fx / 2, 1e-9);

  EXPECT_EQ(t.LoadColor(3, 0, 3).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(t.LoadDepth(-1, 0).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(t.LoadDepth(0, 2).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(t.LoadDepth(t.num_instants(), 0).status().code(), absl::StatusCode::kInvalidArgument);

  std::atomic<int> views{0};
  ASSERT_TRUE(t.ParallelForViews([&](int i, int s) {
                 auto d = t.LoadDepth(i, s);
                 if (!d.ok()) return d.status();
                 ++views;
                 return absl::OkStatus();
               }).ok());
  EXPECT_EQ(views.load(), 2 * t.num_instants());
  auto failing = t.ParallelForViews(
      [](int i, int s) { return i == 2 ? absl::DataLossError("x") : absl::OkStatus(); });
  EXPECT_EQ(failing.code(), absl::StatusCode::kDataLoss);
}

TEST(TakeFrames, LoadOptions) {
  RECON_REQUIRE_SHARED_TAKE();
  TakeFramesOptions options;
  options.load_color = false;
  options.max_instants = 5;
  options.num_threads = 2;
  auto take = TakeFrames::Load(GetSharedTake().path, options);
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_EQ((*take)->num_instants(), 5);
  EXPECT_EQ((*take)->pool().num_threads(), 2);
  EXPECT_TRUE((*take)->instant(0).views[0].color_jpeg.empty());
  EXPECT_EQ((*take)->LoadColor(0, 0).status().code(), absl::StatusCode::kNotFound);
  options.max_instants = -1;
  EXPECT_EQ(TakeFrames::Load(GetSharedTake().path, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  // Cancelled through the progress callback.
  int calls = 0;
  auto cancelled = TakeFrames::Load(GetSharedTake().path, {}, [&](const Progress& p) {
    EXPECT_EQ(p.stage, "load");
    return ++calls < 2;
  });
  EXPECT_EQ(cancelled.status().code(), absl::StatusCode::kCancelled);
}

// A take as the server's ingest writes it: frame-set records after each
// set's frames; sensor k1 misses the third set. Records name their frames
// (frame_indices), whose host stamps may lie far from the set's
// clock-corrected stamp; older takes have no indices and are matched by
// stamp.
TEST(TakeFrames, GroupsByFrameSetRecords) {
  RECON_REQUIRE_SHARED_TAKE();
  for (const bool indexed : {false, true}) {
    SCOPED_TRACE(indexed ? "records with frame indices, stamps 40 ms off" : "records by stamp");
    auto source = TakeReader::Open(GetSharedTake().path);
    ASSERT_TRUE(source.ok()) << source.status();
    const std::string path = reenact::testing::MakeTempDir("recon_frame_sets") +
                             (indexed ? "/indexed.mcap" : "/take.mcap");
    auto writer = TakeWriter::Open(path, (*source)->info());
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (const auto& [id, calibration] : (*source)->sensors()) {
      ASSERT_TRUE((*writer)->AddSensor(calibration).ok());
    }
    // Frames per sensor and index.
    std::map<std::pair<std::string, int64_t>, v1::DepthImage> depth;
    std::map<std::pair<std::string, int64_t>, v1::Skeleton> skeletons;
    ASSERT_TRUE((*source)
                    ->ForEach<v1::DepthImage>(SensorTopic("k0", "depth"),
                                              [&](const v1::DepthImage& m) {
                                                depth[{"k0", m.frame_index()}] = m;
                                                return absl::OkStatus();
                                              })
                    .ok());
    ASSERT_TRUE((*source)
                    ->ForEach<v1::DepthImage>(SensorTopic("k1", "depth"),
                                              [&](const v1::DepthImage& m) {
                                                depth[{"k1", m.frame_index()}] = m;
                                                return absl::OkStatus();
                                              })
                    .ok());
    for (const char* id : {"k0", "k1"}) {
      ASSERT_TRUE((*source)
                      ->ForEach<v1::Skeleton>(SensorTopic(id, "skeleton"),
                                              [&](const v1::Skeleton& m) {
                                                skeletons[{id, m.frame_index()}] = m;
                                                return absl::OkStatus();
                                              })
                      .ok());
    }
    constexpr int kSets = 6;
    for (int f = 0; f < kSets; ++f) {
      v1::FrameSetRecord record;
      record.set_sequence(f + 1);
      int64_t stamp_sum = 0;
      int n = 0;
      for (const char* id : {"k0", "k1"}) {
        if (f == 2 && std::string(id) == "k1") {
          record.add_missing_sensor_ids(id);
          continue;
        }
        const v1::DepthImage& d = depth.at({id, f});
        ASSERT_TRUE((*writer)->WriteDepth(d).ok());
        ASSERT_TRUE((*writer)->WriteSkeleton(skeletons.at({id, f})).ok());
        record.add_sensor_ids(id);
        if (indexed) record.add_frame_indices(f);
        stamp_sum += d.host_stamp_ns() + (indexed ? 40'000'000 : 0);
        ++n;
      }
      record.set_stamp_ns(stamp_sum / n);
      ASSERT_TRUE((*writer)->WriteFrameSetRecord(record).ok());
    }
    ASSERT_TRUE((*writer)->Close().ok());

    auto take = TakeFrames::Load(path);
    ASSERT_TRUE(take.ok()) << take.status();
    EXPECT_TRUE((*take)->grouped_by_frame_sets());
    ASSERT_EQ((*take)->num_instants(), kSets);
    for (int f = 0; f < kSets; ++f) {
      const Instant& instant = (*take)->instant(f);
      EXPECT_TRUE(instant.valid);
      EXPECT_EQ(instant.views[0].frame_index, f);
      EXPECT_EQ(instant.views[1].present, f != 2);
      if (f != 2) {
        EXPECT_EQ(instant.views[1].frame_index, f);
      }
      // No mask in this take: every pixel with depth counts as the actor.
      auto mask = (*take)->LoadActorMask(f, 0);
      auto d = (*take)->LoadDepth(f, 0);
      ASSERT_TRUE(mask.ok() && d.ok());
      for (size_t i = 0; i < d->data.size(); i += 97) {
        EXPECT_EQ(mask->data[i] != 0, d->data[i] != 0);
      }
      // No colour in this take.
      EXPECT_EQ((*take)->LoadColor(f, 0).status().code(), absl::StatusCode::kNotFound);
    }
  }
}

// A two-sensor recording made in memory (no file): the instants its
// FrameSet records name, skeletons in the world frame, colour kept only
// where the sensor's colour calibration is usable.
RecordedTake SmallRecording() {
  RecordedTake take;
  take.info.name = "memory";
  take.info.fps = 10.0;
  for (const char* id : {"a", "b"}) {
    SensorCalibration& s = take.sensors.emplace_back();
    s.sensor_id = id;
    s.depth_intrinsics = {8, 6, 5.0, 5.0, 4.0, 3.0};
    s.world_from_depth.translation = Eigen::Vector3d(id[0] == 'a' ? 1.0 : -1.0, 0.0, 0.0);
  }
  take.sensors[0].color_intrinsics = {16, 12, 10.0, 10.0, 8.0, 6.0};  // b: none.
  DepthImageMm depth(8, 6, 1500);
  const std::string encoded = *EncodeDepth(depth);
  for (int s = 0; s < 2; ++s) {
    for (int f = 0; f < 3; ++f) {
      SensorFrame& frame = take.frames.emplace_back();
      frame.sensor_id = take.sensors[s].sensor_id;
      frame.frame_index = 10 * s + f;  // The sensors count differently.
      frame.depth = EncodedImage{"rvl", encoded, 1000000000LL + 100000000LL * f};
      frame.color = EncodedImage{"jpeg", "not decoded here", frame.depth->host_stamp_ns};
      Skeleton& skeleton = frame.skeletons.emplace_back();
      skeleton.body_index = 1;
      SkeletonJoint& joint = skeleton.joints.emplace_back();
      joint.name = std::string(body::KinectV2JointName(body::KinectV2Joint::kSpineBase));
      joint.position_in_depth_m = Eigen::Vector3d(s == 0 ? -1.0 : 1.0, 0.1 * f, 2.0);
      joint.state = JointTrackingState::kTracked;
    }
  }
  for (int f = 0; f < 3; ++f) {
    FrameSetRecord& record = take.frame_sets.emplace_back();
    record.sequence = static_cast<uint64_t>(3 - f);  // Out of order on purpose.
    record.stamp_ns = 1000000000LL + 100000000LL * (2 - f);
    record.sensor_ids = {"a", "b"};
    record.frame_indices = {2 - f, 10 + (2 - f)};
  }
  return take;
}

TEST(TakeFrames, GroupsARecordingMadeInMemory) {
  auto take = TakeFrames::FromRecording(SmallRecording());
  ASSERT_TRUE(take.ok()) << take.status();
  const TakeFrames& frames = **take;
  EXPECT_EQ(frames.info().name, "memory");
  EXPECT_DOUBLE_EQ(frames.fps(), 10.0);
  EXPECT_TRUE(frames.grouped_by_frame_sets());
  ASSERT_EQ(frames.num_instants(), 3);
  ASSERT_EQ(frames.num_sensors(), 2);
  for (int i = 0; i < 3; ++i) {
    const Instant& instant = frames.instant(i);
    EXPECT_EQ(instant.stamp_ns, 1000000000LL + 100000000LL * i);
    ASSERT_TRUE(instant.views[0].present && instant.views[1].present);
    EXPECT_EQ(instant.views[0].frame_index, i);
    EXPECT_EQ(instant.views[1].frame_index, 10 + i);
    EXPECT_FALSE(instant.views[0].color_jpeg.empty()) << "a's colour is calibrated";
    EXPECT_TRUE(instant.views[1].color_jpeg.empty()) << "b has no colour calibration";
    // Both sensors see the joint at (0, 0.1 i, 2) in the world.
    ASSERT_TRUE(instant.valid);
    const Eigen::Vector3d& joint = instant.joints_in_world_m[0];
    EXPECT_NEAR(joint.x(), 0.0, 1e-9);
    EXPECT_NEAR(joint.y(), 0.1 * i, 1e-9);
    EXPECT_NEAR(joint.z(), 2.0, 1e-9);
    auto depth = frames.LoadDepth(i, 1);
    ASSERT_TRUE(depth.ok()) << depth.status();
    EXPECT_EQ(depth->at(3, 2), 1500);
  }
}

TEST(TakeFrames, BadRecordingsAreInvalidArgument) {
  RecordedTake twice = SmallRecording();
  twice.sensors[1].sensor_id = "a";
  EXPECT_EQ(TakeFrames::FromRecording(std::move(twice)).status().code(),
            absl::StatusCode::kInvalidArgument);
  RecordedTake no_focal = SmallRecording();
  no_focal.sensors[0].depth_intrinsics.fx = 0.0;
  EXPECT_EQ(TakeFrames::FromRecording(std::move(no_focal)).status().code(),
            absl::StatusCode::kInvalidArgument);
  RecordedTake nan_pose = SmallRecording();
  nan_pose.sensors[1].world_from_depth.translation.x() = NAN;
  EXPECT_EQ(TakeFrames::FromRecording(std::move(nan_pose)).status().code(),
            absl::StatusCode::kInvalidArgument);
  RecordedTake no_depth = SmallRecording();
  for (SensorFrame& frame : no_depth.frames) frame.depth.reset();
  EXPECT_EQ(TakeFrames::FromRecording(std::move(no_depth)).status().code(),
            absl::StatusCode::kInvalidArgument);
  RecordedTake none = SmallRecording();
  none.sensors.clear();
  EXPECT_EQ(TakeFrames::FromRecording(std::move(none)).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(TakeFrames, BadInputIsAnErrorNotACrash) {
  const std::string dir = reenact::testing::MakeTempDir("recon_bad_takes");
  EXPECT_EQ(TakeFrames::Load(dir + "/missing.mcap").status().code(), absl::StatusCode::kNotFound);
  { std::ofstream(dir + "/garbage.mcap") << "this is not an mcap file at all"; }
  auto garbage = TakeFrames::Load(dir + "/garbage.mcap");
  EXPECT_FALSE(garbage.ok());
  EXPECT_TRUE(absl::IsInvalidArgument(garbage.status()) || absl::IsDataLoss(garbage.status()))
      << garbage.status();

  RECON_REQUIRE_SHARED_TAKE();
  // Cut the take at several lengths and flip bytes in its middle: every
  // outcome is a clean error or a (shorter) take.
  std::string bytes;
  {
    std::ifstream in(GetSharedTake().path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 100000u);
  for (double fraction : {0.0005, 0.01, 0.3, 0.77}) {
    const std::string path = dir + "/cut.mcap";
    {
      std::ofstream out(path, std::ios::binary | std::ios::trunc);
      out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() * fraction));
    }
    auto take = TakeFrames::Load(path);
    if (take.ok()) {
      EXPECT_LE((*take)->num_instants(), GetSharedTake().summary.frames);
    } else {
      EXPECT_TRUE(absl::IsInvalidArgument(take.status()) || absl::IsDataLoss(take.status()))
          << take.status();
    }
  }
  std::string flipped = bytes;
  for (size_t i = bytes.size() / 3; i < bytes.size() / 3 + 4096; i += 7) flipped[i] ^= 0x5a;
  const std::string path = dir + "/flipped.mcap";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(flipped.data(), static_cast<std::streamsize>(flipped.size()));
  }
  auto take = TakeFrames::Load(path);
  if (!take.ok()) {
    EXPECT_TRUE(absl::IsInvalidArgument(take.status()) || absl::IsDataLoss(take.status()))
        << take.status();
  }
}

}  // namespace
}  // namespace reenact::recon
