// Recorded depth sequences with a reference skeleton per frame, laid out as
// ../shared/data/rgbd-seq is: a folder per sequence with frames/NNNN.png
// (16-bit depth, millimetres, 0 = no data; the person only, background
// removed) and meta.json (the intrinsics, the joint names, per frame the
// depth file and the joints in the camera frame, OpenCV axes, metres; and
// the dataset, action, subject and trial). `reenact tracker eval --real` and
// `reenact grade --real` read them through here.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "clients/mirror/grading.h"
#include "common/body/joint_set.h"
#include "common/tracking/body_tracker.h"

namespace reenact::cli {

struct RefFrame {
  int index = 0;  // In meta.json.
  std::string depth_path;
  std::optional<std::array<double, 4>> intrinsics;  // When the frame has its own.
  // The reference (the sensor SDK's) joints in Kinect v2 order; Kinect v1
  // names map onto their Kinect v2 equivalents (no neck, hand tips, thumbs).
  std::array<std::optional<Eigen::Vector3d>, body::kNumKinectV2Joints> joints;
};

struct RefSequence {
  std::string name;
  std::string folder;
  std::optional<std::array<double, 4>> intrinsics;
  std::vector<RefFrame> frames;
  // From meta.json when present: "dataset", "action_id", "action",
  // "subject", "trial", "fps_nominal" (30 when absent).
  std::string dataset;
  int action_id = 0;
  std::string action;
  int subject = 0;
  int trial = 0;
  double fps = 30.0;
};

// Kinect v2 joint index of a Kinect v2 or v1 joint name.
std::optional<int> RefJointIndex(const std::string& name);

// Reads one sequence's meta.json. NotFound without it; InvalidArgument or
// DataLoss for one that is too large (256 MiB), not JSON, or malformed.
absl::StatusOr<RefSequence> ReadRefSequence(const std::filesystem::path& folder);

// The sequences under `dir`: `dir` itself when it holds meta.json, else its
// sub-folders that do (sorted by name), kept when their name contains one
// of `filters` (all when empty).
std::vector<std::filesystem::path> RefSequenceFolders(const std::filesystem::path& dir,
                                                      const std::vector<std::string>& filters);

// The person a tracker found in one frame of a sequence (nullopt: nobody),
// and how long tracking took.
struct TrackedRefFrame {
  std::optional<tracking::TrackedPerson> person;
  double track_ms = 0.0;
};

// Tracks every frame of `seq` in order with `tracker` (Reset first; with
// `history` false, before every frame). The folder's own background removal
// marks the person unless `own_segmentation`. The person with the most
// pixels is the one the sequence is about. Errors name the frame's file.
absl::StatusOr<std::vector<TrackedRefFrame>> TrackRefSequence(tracking::BodyTracker& tracker,
                                                              const RefSequence& seq, bool history,
                                                              bool own_segmentation);

// The sequence's stored reference skeletons as grading frames, timed at its
// frame rate; every valid joint counts as seen (the file has no states).
std::vector<mirror::GradeFrame> SdkGradeFrames(const RefSequence& seq);

// Tracked frames as grading frames: TRACKED joints are seen, INFERRED ones
// valid but not seen, NOT_TRACKED and non-finite ones left out.
std::vector<mirror::GradeFrame> TrackedGradeFrames(const RefSequence& seq,
                                                   const std::vector<TrackedRefFrame>& tracked);

}  // namespace reenact::cli
