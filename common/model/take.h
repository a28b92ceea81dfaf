// A take as plain values: what the take file (take.proto, sensor.proto) and
// the ingest's FrameSets (frame.proto) carry, with the images still encoded
// (depth RVL, mask RLE, colour JPEG: the codecs in common/io decode them).
// common/io/take_convert.h converts from the messages and reads a take file
// into a RecordedTake; server/recon's TakeFrames groups its frames into
// instants.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/model/sensor_calibration.h"

namespace reenact {

// What a take says about itself.
struct TakeInfo {
  std::string name;  // e.g. "kata-01".
  int64_t created_unix_ns = 0;
  std::string generator;      // e.g. "reenactd 0.1.0", "reenact-synth".
  std::string motion_source;  // Synthetic takes: the motion, e.g. a BVH file.
  std::string body_model;     // Synthetic takes: the body model.
  int sensor_count = 0;
  double fps = 0.0;  // Nominal; 0: unknown.
  int64_t start_stamp_ns = 0;
  std::string notes;
  bool synthetic = false;  // Rendered by the synthetic pipeline, with ground truth.
};

// How a sensor's body tracker saw a joint. kUnspecified counts as tracked
// (trackers that do not say).
enum class JointTrackingState { kUnspecified, kNotTracked, kInferred, kTracked };

struct SkeletonJoint {
  std::string name;  // body::KinectV2Joint name, e.g. "ElbowLeft".
  Eigen::Vector3d position_in_depth_m = Eigen::Vector3d::Zero();
  JointTrackingState state = JointTrackingState::kUnspecified;
  float confidence = 0.0f;  // 0..1; 0: the tracker gives none.
};

// One body a sensor's tracker found in one frame.
struct Skeleton {
  int body_index = 0;  // The body's value in the frame's actor mask.
  std::vector<SkeletonJoint> joints;
};

// One encoded image of a frame.
struct EncodedImage {
  std::string encoding;  // e.g. "rvl" (depth), "rle" (mask), "jpeg" (colour).
  std::string data;
  int64_t host_stamp_ns = 0;  // Take timeline (host clock).
};

// One sensor's frame: its images (each may be absent) and skeletons.
struct SensorFrame {
  std::string sensor_id;
  int64_t frame_index = -1;  // The sensor's own count.
  std::optional<EncodedImage> depth;
  std::optional<EncodedImage> mask;
  std::optional<EncodedImage> color;
  std::vector<Skeleton> skeletons;
};

// The frames of several sensors at one instant, as the ingest groups them.
struct FrameSet {
  uint64_t sequence = 0;  // 1, 2, 3, ... within a take.
  int64_t stamp_ns = 0;   // Take timeline.
  int64_t skew_ns = 0;    // Latest minus earliest frame stamp.
  std::vector<SensorFrame> frames;
};

// What a take file records of one FrameSet the server stored: which frame of
// which sensor belonged to it.
struct FrameSetRecord {
  uint64_t sequence = 0;
  int64_t stamp_ns = 0;
  int64_t skew_ns = 0;
  std::vector<std::string> sensor_ids;
  // Parallel to sensor_ids; empty in takes written before the file kept
  // them (readers then match frames by stamp).
  std::vector<int64_t> frame_indices;
};

// A whole recorded take: every sensor's frames (one per sensor and
// frame_index, in no particular order) and, for takes the server ingested,
// the FrameSets it stored.
struct RecordedTake {
  TakeInfo info;
  std::vector<SensorCalibration> sensors;
  std::vector<SensorFrame> frames;
  std::vector<FrameSetRecord> frame_sets;
};

}  // namespace reenact
