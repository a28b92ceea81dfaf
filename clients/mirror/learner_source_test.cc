#include "clients/mirror/learner_source.h"

#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "clients/mirror/live_learner_source.h"
#include "clients/mirror/mirror_cli.h"
#include "clients/mirror/testing/fake_daemon.h"
#include "clients/mirror/testing/synthetic_learners.h"
#include "clients/sdk/takes_client.h"
#include "common/base/status_macros.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"

namespace reenact::mirror {
namespace {

using testing::LearnerTake;
using testing::TestDir;

std::vector<LearnerFrame> ReadAll(LearnerSource& source) {
  std::vector<LearnerFrame> frames;
  while (true) {
    absl::StatusOr<std::optional<LearnerFrame>> next = source.Next();
    EXPECT_TRUE(next.ok()) << next.status();
    if (!next.ok() || !next->has_value()) break;
    frames.push_back(**next);
  }
  return frames;
}

// Ground-truth joints per frame, in world.
std::vector<std::map<std::string, Eigen::Vector3d>> TruthJoints(const TakeReader& take) {
  std::vector<std::map<std::string, Eigen::Vector3d>> frames;
  auto joints = take.ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic);
  EXPECT_TRUE(joints.ok());
  if (!joints.ok()) return frames;
  for (const auto& j : *joints) {
    std::map<std::string, Eigen::Vector3d> by_name;
    for (int i = 0; i < j.joint_names_size(); ++i) {
      by_name[j.joint_names(i)] = FromProto(j.positions_in_world_m(i));
    }
    frames.push_back(by_name);
  }
  return frames;
}

TEST(TakeLearner, PlaysColourAndSkeletonInTheColourCameraFrame) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  auto source = OpenTakeLearner(path);
  ASSERT_TRUE(source.ok()) << source.status();
  const LearnerSensor& sensor = (*source)->sensor();
  EXPECT_EQ(sensor.sensor_id, "k0");
  EXPECT_FALSE(sensor.live);
  // The rig's sensors look 5 degrees down: up tilts toward the camera.
  const double tilt_deg =
      std::acos(sensor.up_in_color.dot(Eigen::Vector3d(0, -1, 0))) * 180.0 / M_PI;
  const std::vector<LearnerFrame> frames = ReadAll(**source);
  auto take = TakeReader::Open(path);
  ASSERT_TRUE(take.ok());
  const auto truth = TruthJoints(**take);
  ASSERT_EQ(frames.size(), truth.size());
  const v1::SensorCalibration& calibration = (*take)->sensors().at("k0");
  const Rigid3d color_from_world = *FromProto(calibration.color_from_depth()) *
                                   FromProto(calibration.world_from_depth())->Inverse();
  double sum_mm = 0.0, worst_gap_ms = 0.0, mean_gap_ms = 0.0;
  int joints = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(frames[f].color.has_value()) << f;
    EXPECT_EQ(frames[f].color->width, testing::kColorWidth);
    ASSERT_TRUE(frames[f].skeleton_in_color.has_value()) << f;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      const std::string name(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)));
      ASSERT_TRUE(frames[f].skeleton_in_color->valid[j]);
      sum_mm += (frames[f].skeleton_in_color->position_m[j] - color_from_world * truth[f].at(name))
                    .norm() *
                1e3;
      ++joints;
    }
    if (f > 0) {
      const double gap_ms = (frames[f].stamp_ns - frames[f - 1].stamp_ns) * 1e-6;
      EXPECT_GE(gap_ms, 0.0);
      worst_gap_ms = std::max(worst_gap_ms, std::abs(gap_ms - 1000.0 / 30.0));
      mean_gap_ms += gap_ms / (frames.size() - 1);
    }
  }
  std::cout << frames.size() << " learner frames: up tilted " << tilt_deg
            << " deg from level; joints " << sum_mm / joints
            << " mm from the truth in the colour frame; frame gap " << mean_gap_ms
            << " ms (worst off 33.3 ms by " << worst_gap_ms << " ms)\n";
  EXPECT_NEAR(tilt_deg, 5.0, 0.5);   // deg: the rig's pitch
  EXPECT_LT(sum_mm / joints, 40.0);  // mm: 1 cm jitter, 3 cm where inferred
  EXPECT_LT(worst_gap_ms, 1.0);      // ms: exposure stamps, no transfer jitter
}

TEST(TakeLearner, MissingFileAndUnknownSensorAreNotFound) {
  EXPECT_EQ(OpenTakeLearner(TestDir() + "/no_such_take.mcap").status().code(),
            absl::StatusCode::kNotFound);
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  const absl::Status unknown = OpenTakeLearner(path, "k7").status();
  EXPECT_EQ(unknown.code(), absl::StatusCode::kNotFound);
  EXPECT_NE(unknown.message().find("k0"), std::string::npos) << unknown;  // Lists the sensors.
}

// What CopyTake changes.
enum class Damage { kNoSkeletons, kNanJoints, kNoColour };

// Copies the colour and skeleton channels of `path`'s sensor k0 to `out`,
// damaged as asked.
void CopyTake(const std::string& path, const std::string& out, Damage damage) {
  auto take = TakeReader::Open(path);
  ASSERT_TRUE(take.ok()) << take.status();
  auto writer = TakeWriter::Open(out, (*take)->info());
  ASSERT_TRUE(writer.ok()) << writer.status();
  ASSERT_TRUE((*writer)->AddSensor((*take)->sensors().at("k0")).ok());
  if (damage != Damage::kNoColour) {
    ASSERT_TRUE((*take)
                    ->ForEach<v1::ColorImage>(
                        SensorTopic("k0", "color"),
                        [&](const v1::ColorImage& image) { return (*writer)->WriteColor(image); })
                    .ok());
  }
  if (damage != Damage::kNoSkeletons) {
    ASSERT_TRUE((*take)
                    ->ForEach<v1::Skeleton>(SensorTopic("k0", "skeleton"),
                                            [&](v1::Skeleton skeleton) {
                                              for (auto& joint : *skeleton.mutable_joints()) {
                                                if (damage != Damage::kNanJoints) break;
                                                joint.mutable_position_in_depth_m()->set_x(
                                                    std::numeric_limits<double>::quiet_NaN());
                                              }
                                              return (*writer)->WriteSkeleton(skeleton);
                                            })
                    .ok());
  }
  ASSERT_TRUE((*writer)->Close().ok());
}

TEST(TakeLearner, TakeWithoutSkeletonsOrDepthIsFailedPrecondition) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  const std::string out = TestDir() + "/no_skeletons.mcap";
  CopyTake(path, out, Damage::kNoSkeletons);
  const absl::Status status = OpenTakeLearner(out).status();
  std::cout << status << "\n";
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
}

// Two people in the frame: the learner is the one with more joints, and the
// count says two; a body with no usable joint is nobody.
TEST(ChooseLearnerSkeleton, CountsThePeopleInViewAndPicksTheMostTracked) {
  auto body = [](int joints, double x_m, v1::TrackingState state) {
    v1::Skeleton s;
    for (int j = 0; j < joints; ++j) {
      v1::Joint* joint = s.add_joints();
      joint->set_name(std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j))));
      joint->mutable_position_in_depth_m()->set_x(x_m);
      joint->mutable_position_in_depth_m()->set_y(0.1 * j);
      joint->mutable_position_in_depth_m()->set_z(2.5);
      joint->set_tracking_state(state);
    }
    return s;
  };
  const v1::Skeleton near = body(25, -0.5, v1::TRACKING_STATE_TRACKED);
  const v1::Skeleton partial = body(12, 0.8, v1::TRACKING_STATE_INFERRED);
  const v1::Skeleton nobody = body(25, 0.0, v1::TRACKING_STATE_NOT_TRACKED);
  const std::optional<LearnerSkeleton> chosen =
      ChooseLearnerSkeleton({&partial, &near, &nobody}, Rigid3d());
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(chosen->people, 2);
  EXPECT_NEAR(chosen->pose.position_m[0].x(), -0.5, 1e-12);
  EXPECT_TRUE(chosen->seen[0]);
  const std::optional<LearnerSkeleton> one = ChooseLearnerSkeleton({&partial}, Rigid3d());
  ASSERT_TRUE(one.has_value());
  EXPECT_EQ(one->people, 1);
  EXPECT_FALSE(one->seen[0]);
  EXPECT_FALSE(ChooseLearnerSkeleton({&nobody}, Rigid3d()).has_value());
}

TEST(TakeLearner, NanJointsLeaveNobodyTracked) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  const std::string nan_take = TestDir() + "/nan_skeletons.mcap";
  CopyTake(path, nan_take, Damage::kNanJoints);
  auto source = OpenTakeLearner(nan_take);
  ASSERT_TRUE(source.ok()) << source.status();
  const std::vector<LearnerFrame> frames = ReadAll(**source);
  ASSERT_FALSE(frames.empty());
  for (const LearnerFrame& frame : frames) {
    EXPECT_FALSE(frame.skeleton_in_color.has_value());
    EXPECT_TRUE(frame.color.has_value());
  }
  // The app runs on, waiting for a learner it never sees.
  const std::string teacher = testing::TeacherReen();
  ASSERT_FALSE(teacher.empty());
  std::ostringstream out, err;
  const int code = RunMirror({"--teacher-file", teacher, "--learner-take", nan_take, "--render-to",
                              TestDir() + "/nan_frames", "--json"},
                             out, err);
  std::cout << err.str();
  ASSERT_EQ(code, 0);
  const nlohmann::json j = nlohmann::json::parse(out.str());
  EXPECT_EQ(j["repetitions_done"], 0);
  EXPECT_EQ(j["state"], "waiting_for_learner");
  EXPECT_EQ(j["frames"].get<size_t>(), frames.size());
  EXPECT_EQ(j["frames_with_learner"], 0);
}

TEST(TakeLearner, SkeletonOnlyTakeIsDrawnOnADarkBackground) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  const std::string take = TestDir() + "/skeleton_only.mcap";
  CopyTake(path, take, Damage::kNoColour);
  auto source = OpenTakeLearner(take);
  ASSERT_TRUE(source.ok()) << source.status();
  const std::vector<LearnerFrame> frames = ReadAll(**source);
  ASSERT_EQ(frames.size(), 30u);
  for (const LearnerFrame& frame : frames) {
    EXPECT_FALSE(frame.color.has_value());
    EXPECT_TRUE(frame.skeleton_in_color.has_value());
  }
  const std::string teacher = testing::TeacherReen();
  ASSERT_FALSE(teacher.empty());
  const std::string dir = TestDir() + "/skeleton_only";
  std::ostringstream out, err;
  ASSERT_EQ(RunMirror({"--teacher-file", teacher, "--learner-take", take, "--render-to", dir,
                       "--hold-s", "0.1", "--msaa", "0", "--no-hud"},
                      out, err),
            0)
      << err.str();
  const cv::Mat image = cv::imread(dir + "/frame_00010.png");
  ASSERT_FALSE(image.empty());
  // The mirror panel: the dark background (24, 24, 30) and the joints' dots.
  const cv::Mat mirror = image(cv::Rect(0, 0, image.cols / 2, image.rows));
  int dark = 0, bright = 0;
  for (int y = 0; y < mirror.rows; ++y) {
    for (int x = 0; x < mirror.cols; ++x) {
      const cv::Vec3b px = mirror.at<cv::Vec3b>(y, x);
      if (px[2] == 24 && px[1] == 24 && px[0] == 30) ++dark;
      if (px[1] > 120) ++bright;  // Green-ish dots and bones.
    }
  }
  const double dark_share = static_cast<double>(dark) / (mirror.rows * mirror.cols);
  std::cout << "skeleton-only learner: " << 100 * dark_share << " % of the mirror dark, " << bright
            << " bright skeleton pixels\n";
  EXPECT_GT(dark_share, 0.8);
  EXPECT_GT(bright, 500);
}

TEST(LiveLearner, ReceivesTheDaemonsFramesLikeTheTakeSource) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  testing::FakeDaemonServer daemon(path);
  DaemonFeedOptions options;
  options.connection.address = daemon.address();
  auto feed = NewDaemonFrameFeed(options);
  ASSERT_TRUE(feed.ok()) << feed.status();
  auto live = OpenLiveLearner(*std::move(feed));
  ASSERT_TRUE(live.ok()) << live.status();
  EXPECT_TRUE((*live)->sensor().live);
  EXPECT_EQ((*live)->sensor().sensor_id, "k0");
  // The queue drops the oldest frames when the reader falls behind.
  std::vector<LearnerFrame> received;
  while (true) {
    auto next = (*live)->Next();
    ASSERT_TRUE(next.ok()) << next.status();
    if (!next->has_value()) break;
    received.push_back(**next);
  }
  const v1::StreamFramesRequest& request = daemon.service.last_request();
  ASSERT_EQ(request.sensor_ids_size(), 1);
  EXPECT_EQ(request.sensor_ids(0), "k0");
  ASSERT_EQ(request.color_sensor_ids_size(), 1);
  EXPECT_EQ(request.color_max_width_px(), 960);
  auto recorded = OpenTakeLearner(path);
  ASSERT_TRUE(recorded.ok());
  std::map<int64_t, LearnerFrame> by_stamp;
  for (LearnerFrame& frame : ReadAll(**recorded)) by_stamp[frame.stamp_ns] = frame;
  ASSERT_FALSE(received.empty());
  int compared = 0;
  for (const LearnerFrame& frame : received) {
    auto match = by_stamp.find(frame.stamp_ns);
    ASSERT_NE(match, by_stamp.end());
    ASSERT_TRUE(frame.skeleton_in_color && match->second.skeleton_in_color);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      EXPECT_NEAR(
          (frame.skeleton_in_color->position_m[j] - match->second.skeleton_in_color->position_m[j])
              .norm(),
          0.0, 1e-12);
    }
    ASSERT_TRUE(frame.color.has_value());
    EXPECT_EQ(frame.color->width, testing::kColorWidth);
    ++compared;
  }
  std::cout << "live daemon feed: " << compared << " frames received (" << (*live)->frames_dropped()
            << " dropped), identical to the take source\n";
  EXPECT_EQ(compared + (*live)->frames_dropped(), static_cast<int64_t>(by_stamp.size()));
}

TEST(LiveLearner, StreamCancelEndsAStreamThatSendsNothing) {
  const std::string path = LearnerTake(1.0, 0.0);
  ASSERT_FALSE(path.empty());
  testing::FakeDaemonServer daemon(path, /*pace_fps=*/0.02);  // A set, then 50 s of nothing.
  const client::CaptureClient client({.address = daemon.address()});
  client::StreamCancel cancel;
  std::thread canceller;
  int sets = 0;
  const auto start = std::chrono::steady_clock::now();
  const absl::Status status = client.StreamFrames(
      v1::StreamFramesRequest(),
      [&](const v1::LiveFrameSet&) {
        if (++sets == 1) {
          canceller = std::thread([&cancel] {
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
            cancel.Cancel();
          });
        }
        return true;  // The callback never stops it: only the cancel can.
      },
      &cancel);
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (canceller.joinable()) canceller.join();
  EXPECT_TRUE(status.ok()) << status;
  EXPECT_EQ(sets, 1);
  std::cout << "cancelled a silent stream after " << waited_s << " s\n";
  EXPECT_LT(waited_s, 25.0);  // Well before the daemon's next set at 50 s.
  // Already cancelled: the next call returns at once, receiving nothing.
  sets = 0;
  EXPECT_TRUE(client
                  .StreamFrames(
                      v1::StreamFramesRequest(),
                      [&](const v1::LiveFrameSet&) { return ++sets > 0; }, &cancel)
                  .ok());
  EXPECT_EQ(sets, 0);
}

TEST(LiveLearner, AbsentDaemonIsUnavailableNamingIt) {
  DaemonFeedOptions options;
  options.connection.address = "127.0.0.1:1";
  auto feed = NewDaemonFrameFeed(options);
  ASSERT_TRUE(feed.ok()) << feed.status();
  const absl::Status status = OpenLiveLearner(*std::move(feed)).status();
  std::cout << status << "\n";
  EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("127.0.0.1:1"), std::string::npos);
}

}  // namespace
}  // namespace reenact::mirror
