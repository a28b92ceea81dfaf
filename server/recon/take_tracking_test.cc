// Takes without skeletons through RunMethod: tracked from their depth by the
// first job, the skeletons kept beside the take for the next one; a take
// with nobody in it is refused.
#include "server/recon/take_tracking.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/match.h"
#include "common/io/recordings/recording.h"
#include "common/io/recordings/recording_import.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/synth/synthesizer.h"
#include "common/testing/test_data.h"
#include "server/recon/methods.h"
#include "server/recon/testing/short_take.h"

namespace reenact::recon {
namespace {

namespace fs = std::filesystem;

// One run of rigid-cylinders on `take`: its result and its log lines.
struct MethodRun {
  absl::StatusOr<MethodResult> result = absl::UnknownError("not run");
  std::vector<std::string> log;
  double seconds = 0;
};

MethodRun RunCylinders(const std::string& take, const std::string& out) {
  MethodInput input;
  input.take_path = take;
  input.method = "rigid-cylinders";
  input.options = {{"texture_size_px", "128"}, {"threads", "2"}};
  MethodRun run;
  const auto start = std::chrono::steady_clock::now();
  run.result =
      RunMethod(input, out, {}, [&run](const std::string& line) { run.log.push_back(line); });
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return run;
}

// The log's "track: " line, or "".
std::string TrackLine(const MethodRun& run) {
  for (const std::string& line : run.log) {
    if (absl::StartsWith(line, "track: ")) return line;
  }
  return "";
}

// A 2-sensor synthetic take with no skeleton stream (what the capture
// daemon stores without its tracker, and every imported recording), made
// once per test process.
struct NoSkeletonTake {
  std::string path;
  std::string skip;
  absl::Status error;
};

const NoSkeletonTake& GetNoSkeletonTake() {
  static const NoSkeletonTake* made = [] {
    auto* t = new NoSkeletonTake;
    // The recon tests' shared take, shorter and without sensor skeletons.
    synth::SynthOptions options = recon::testing::SharedTakeOptions();
    options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kNone;
    options.seconds = 1.0;
    t->path = reenact::testing::MakeTempDir("recon_take_tracking") + "/take.mcap";
    absl::StatusOr<synth::SynthSummary> summary = synth::SynthesizeTake(options, t->path);
    if (!summary.ok()) {
      if (summary.status().code() == absl::StatusCode::kUnavailable) {
        t->skip = std::string(summary.status().message());
      } else {
        t->error = summary.status();
      }
    }
    return t;
  }();
  return *made;
}

#define REQUIRE_NO_SKELETON_TAKE()                                                   \
  do {                                                                               \
    if (!GetNoSkeletonTake().skip.empty()) GTEST_SKIP() << GetNoSkeletonTake().skip; \
    ASSERT_TRUE(GetNoSkeletonTake().error.ok()) << GetNoSkeletonTake().error;        \
  } while (false)

TEST(TakeTracking, TakeWithoutSkeletonsIsTrackedOnceAndReconstructed) {
  REQUIRE_NO_SKELETON_TAKE();
  // A copy of its own: the skeletons kept beside it are this test's.
  const std::string dir = reenact::testing::MakeTempDir("recon_take_tracking_run");
  const std::string take = dir + "/take.mcap";
  fs::copy_file(GetNoSkeletonTake().path, take, fs::copy_options::overwrite_existing);
  const std::string stored = TrackedSkeletonsPath(take);
  ASSERT_FALSE(fs::exists(stored));
  {
    // Without tracking nothing has a skeleton: what every job failed on.
    auto plain = TakeFrames::Load(take);
    ASSERT_TRUE(plain.ok()) << plain.status();
    EXPECT_EQ((*plain)->num_valid_instants(), 0);
  }

  // First job: tracks, keeps the skeletons, succeeds.
  const MethodRun first = RunCylinders(take, dir + "/first.reen");
  ASSERT_TRUE(first.result.ok()) << first.result.status();
  const std::string first_line = TrackLine(first);
  std::cout << "first run: " << first.seconds << " s; " << first_line << "\n";
  EXPECT_TRUE(absl::StrContains(first_line, "instants tracked from depth (2 sensors)"))
      << first_line;
  EXPECT_FALSE(absl::StrContains(first_line, "reused")) << first_line;
  EXPECT_GT(first.result->frames, 0);
  ASSERT_TRUE(fs::exists(stored));
  const auto stored_bytes = fs::file_size(stored);
  EXPECT_GT(stored_bytes, 1000u);

  // Second job: the kept skeletons, no tracking.
  const MethodRun second = RunCylinders(take, dir + "/second.reen");
  ASSERT_TRUE(second.result.ok()) << second.result.status();
  const std::string second_line = TrackLine(second);
  std::cout << "second run: " << second.seconds << " s; " << second_line << "\n";
  EXPECT_TRUE(absl::StrContains(second_line, "stored skeletons reused")) << second_line;
  EXPECT_EQ(second.result->frames, first.result->frames);

  // The tracked skeletons against the synthetic take's true joints, over
  // the joints the fusion kept.
  auto loaded = LoadTakeForMethod(take);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  auto reader = TakeReader::Open(take);
  ASSERT_TRUE(reader.ok()) << reader.status();
  auto truth = ReadGroundTruth(**reader, {});
  ASSERT_TRUE(truth.ok()) << truth.status();
  double sum_m = 0;
  int joints = 0;
  double base_sum_m = 0;  // The spine base: where the person is.
  int bases = 0;
  const TakeFrames& frames = **loaded;
  for (const Instant& instant : frames.instants()) {
    if (!instant.valid) continue;
    int64_t frame_index = -1;
    for (const SensorView& view : instant.views) {
      if (view.present) frame_index = view.frame_index;
    }
    const auto true_joints = truth->joints.find(frame_index);
    if (true_joints == truth->joints.end()) continue;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      if (!IsJointValid(instant.joints_in_world_m[j])) continue;
      sum_m += (instant.joints_in_world_m[j] - true_joints->second[j]).norm();
      if (j == body::Index(body::KinectV2Joint::kSpineBase)) {
        base_sum_m += (instant.joints_in_world_m[j] - true_joints->second[j]).norm();
        ++bases;
      }
      ++joints;
    }
  }
  ASSERT_GT(joints, 0);
  ASSERT_GT(bases, 0);
  const double mpjpe_mm = 1000.0 * sum_m / joints;
  const double base_mm = 1000.0 * base_sum_m / bases;
  std::cout << "tracked: " << frames.num_valid_instants() << " of " << frames.num_instants()
            << " instants, " << joints << " joints, MPJPE " << mpjpe_mm << " mm, spine base "
            << base_mm << " mm\n";
  EXPECT_GE(frames.num_valid_instants(), frames.num_instants() / 2);
  // The shipped network measured 215 mm here (spine base 11 mm): a short
  // take at 15 fps whose limbs it reads far worse than a Kinect's real
  // recordings (models/tracker/README.md). The bounds hold it to that.
  EXPECT_LT(base_mm, 60.0);
  EXPECT_LT(mpjpe_mm, 300.0);
}

TEST(TakeTracking, CorruptOrStaleStoredSkeletonsAreTrackedAgain) {
  REQUIRE_NO_SKELETON_TAKE();
  const std::string dir = reenact::testing::MakeTempDir("recon_take_tracking_corrupt");
  const std::string take = dir + "/take.mcap";
  fs::copy_file(GetNoSkeletonTake().path, take, fs::copy_options::overwrite_existing);
  const std::string stored = TrackedSkeletonsPath(take);
  std::vector<std::string> log;
  const auto to_log = [&log](const std::string& line) { log.push_back(line); };

  // Bytes that are no file of skeletons.
  std::ofstream(stored, std::ios::binary) << "not skeletons";
  auto first = LoadTakeForMethod(take, {}, {}, {}, to_log);
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_GE(log.size(), 2u);
  EXPECT_TRUE(absl::StrContains(log[0], "ignoring the stored skeletons")) << log[0];
  EXPECT_TRUE(absl::StrContains(log[0], "corrupt")) << log[0];
  EXPECT_FALSE(absl::StrContains(log.back(), "reused")) << log.back();
  const int valid = (*first)->num_valid_instants();
  EXPECT_GT(valid, 0);

  // One flipped byte in a whole file: its checksum.
  std::string bytes;
  {
    std::ifstream in(stored, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 100u);
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x5a;
  std::ofstream(stored, std::ios::binary | std::ios::trunc) << flipped;
  log.clear();
  ASSERT_TRUE(LoadTakeForMethod(take, {}, {}, {}, to_log).ok());
  EXPECT_TRUE(absl::StrContains(log.front(), "checksum")) << log.front();

  // Whole but made from another take (the take's bytes changed, as when a
  // take is deleted and uploaded again under its id).
  { std::ofstream(take, std::ios::binary | std::ios::app) << "x"; }
  log.clear();
  auto grown = LoadTakeForMethod(take, {}, {}, {}, to_log);
  ASSERT_TRUE(grown.ok()) << grown.status();
  EXPECT_TRUE(absl::StrContains(log.front(), "stale")) << log.front();
  EXPECT_EQ((*grown)->num_valid_instants(), valid);  // The tracker is deterministic.
  log.clear();
  ASSERT_TRUE(LoadTakeForMethod(take, {}, {}, {}, to_log).ok());
  ASSERT_EQ(log.size(), 1u);
  EXPECT_TRUE(absl::StrContains(log[0], "stored skeletons reused")) << log[0];
}

TEST(TakeTracking, CancelledWhileTracking) {
  REQUIRE_NO_SKELETON_TAKE();
  const std::string dir = reenact::testing::MakeTempDir("recon_take_tracking_cancel");
  const std::string take = dir + "/take.mcap";
  fs::copy_file(GetNoSkeletonTake().path, take, fs::copy_options::overwrite_existing);
  int frames = 0;
  auto cancelled = LoadTakeForMethod(take, {}, {}, [&frames](const Progress& p) {
    EXPECT_EQ(p.stage, "track");
    return ++frames < 3;
  });
  EXPECT_EQ(cancelled.status().code(), absl::StatusCode::kCancelled) << cancelled.status();
  EXPECT_EQ(frames, 3);
  EXPECT_FALSE(fs::exists(TrackedSkeletonsPath(take)));
}

// The real Azure Kinect recording of a desk (nobody in it), imported as
// `reenact import` does: the job fails with a clear message.
TEST(TakeTracking, ImportedRecordingWithoutAPersonIsRefused) {
  const std::string mkv = reenact::testing::TestDataPath("rgbd/azure-kinect-mkv/recording.mkv");
  if (!fs::exists(mkv)) {
    GTEST_SKIP() << "\n*** SKIPPED: the real Azure Kinect recording " << mkv << " is missing ***";
  }
  const std::string dir = reenact::testing::MakeTempDir("recon_take_tracking_mkv");
  const std::string take = dir + "/take.mcap";
  auto reader = recordings::OpenRecording(mkv, recordings::RecordingFormat::kAzureMkv);
  ASSERT_TRUE(reader.ok()) << reader.status();
  auto imported = recordings::ImportRecording(**reader, take);
  ASSERT_TRUE(imported.ok()) << imported.status();
  std::cout << "imported " << imported->frames << " frames\n";

  const MethodRun run = RunCylinders(take, dir + "/r.reen");
  std::cout << run.seconds << " s; " << TrackLine(run) << "\n" << run.result.status() << "\n";
  ASSERT_FALSE(run.result.ok());
  EXPECT_EQ(run.result.status().code(), absl::StatusCode::kInvalidArgument) << run.result.status();
  EXPECT_TRUE(absl::StrContains(run.result.status().message(), "no person in this take"))
      << run.result.status();
  EXPECT_FALSE(fs::exists(dir + "/r.reen"));
  // Nobody found is kept too: the next job fails at once, the same way.
  EXPECT_TRUE(fs::exists(TrackedSkeletonsPath(take)));
  const MethodRun again = RunCylinders(take, dir + "/r.reen");
  std::cout << again.seconds << " s; " << TrackLine(again) << "\n";
  ASSERT_FALSE(again.result.ok());
  EXPECT_TRUE(absl::StrContains(again.result.status().message(), "no person in this take"));
  EXPECT_TRUE(absl::StrContains(TrackLine(again), "stored skeletons reused")) << TrackLine(again);
}

// A depth frame that does not decode is DataLoss naming the frame.
TEST(TakeTracking, UndecodableDepthIsDataLoss) {
  REQUIRE_NO_SKELETON_TAKE();
  // A take whose every depth frame says "rvl" but holds other bytes: the
  // synthetic take rewritten through the take writer.
  const std::string dir = reenact::testing::MakeTempDir("recon_take_tracking_bad_depth");
  const std::string take = dir + "/take.mcap";
  auto in = TakeReader::Open(GetNoSkeletonTake().path);
  ASSERT_TRUE(in.ok()) << in.status();
  auto writer = TakeWriter::Open(take, (*in)->info());
  ASSERT_TRUE(writer.ok()) << writer.status();
  for (const auto& [id, calibration] : (*in)->sensors()) {
    ASSERT_TRUE((*writer)->AddSensor(calibration).ok());
    auto depth = (*in)->ReadAll<v1::DepthImage>(SensorTopic(id, "depth"));
    ASSERT_TRUE(depth.ok()) << depth.status();
    for (v1::DepthImage& d : *depth) {
      d.set_data("not depth");
      ASSERT_TRUE((*writer)->WriteDepth(d).ok());
    }
  }
  ASSERT_TRUE((*writer)->Close().ok());
  auto loaded = LoadTakeForMethod(take);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss) << loaded.status();
  EXPECT_TRUE(absl::StrContains(loaded.status().message(), "frame ")) << loaded.status();
}

}  // namespace
}  // namespace reenact::recon
