#include "common/io/take_convert.h"

#include <cstring>
#include <filesystem>
#include <map>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/proto_convert.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"

namespace reenact {

TakeInfo TakeInfoFromProto(const v1::TakeInfo& m) {
  TakeInfo info;
  info.name = m.name();
  info.created_unix_ns = m.created_unix_ns();
  info.generator = m.generator();
  info.motion_source = m.motion_source();
  info.body_model = m.body_model();
  info.sensor_count = m.sensor_count();
  info.fps = m.fps();
  info.start_stamp_ns = m.start_stamp_ns();
  info.notes = m.notes();
  info.synthetic = m.synthetic();
  return info;
}

v1::TakeInfo TakeInfoToProto(const TakeInfo& info) {
  v1::TakeInfo m;
  m.set_name(info.name);
  m.set_created_unix_ns(info.created_unix_ns);
  m.set_generator(info.generator);
  m.set_motion_source(info.motion_source);
  m.set_body_model(info.body_model);
  m.set_sensor_count(info.sensor_count);
  m.set_fps(info.fps);
  m.set_start_stamp_ns(info.start_stamp_ns);
  m.set_notes(info.notes);
  m.set_synthetic(info.synthetic);
  return m;
}

namespace {

JointTrackingState StateFromProto(v1::TrackingState state) {
  switch (state) {
    case v1::TRACKING_STATE_NOT_TRACKED:
      return JointTrackingState::kNotTracked;
    case v1::TRACKING_STATE_INFERRED:
      return JointTrackingState::kInferred;
    case v1::TRACKING_STATE_TRACKED:
      return JointTrackingState::kTracked;
    default:
      return JointTrackingState::kUnspecified;
  }
}

// The bytes of `image` moved into an EncodedImage.
template <typename Image>
EncodedImage TakeImage(Image* image) {
  EncodedImage out;
  out.encoding = image->encoding();
  out.data = std::move(*image->mutable_data());
  out.host_stamp_ns = image->host_stamp_ns();
  return out;
}

}  // namespace

Skeleton SkeletonFromProto(const v1::Skeleton& m) {
  Skeleton skeleton;
  skeleton.body_index = m.body_index();
  skeleton.joints.reserve(m.joints_size());
  for (const v1::Joint& j : m.joints()) {
    SkeletonJoint joint;
    joint.name = j.name();
    joint.position_in_depth_m = FromProto(j.position_in_depth_m());
    joint.state = StateFromProto(j.tracking_state());
    joint.confidence = j.confidence();
    skeleton.joints.push_back(std::move(joint));
  }
  return skeleton;
}

SensorFrame SensorFrameFromProto(v1::Frame&& m) {
  SensorFrame frame;
  frame.sensor_id = m.sensor_id();
  frame.frame_index = m.has_depth() ? m.depth().frame_index() : m.frame_index();
  if (m.has_depth()) frame.depth = TakeImage(m.mutable_depth());
  if (m.has_mask()) frame.mask = TakeImage(m.mutable_mask());
  if (m.has_color()) frame.color = TakeImage(m.mutable_color());
  frame.skeletons.reserve(m.skeletons_size());
  for (const v1::Skeleton& s : m.skeletons()) frame.skeletons.push_back(SkeletonFromProto(s));
  return frame;
}

FrameSet FrameSetFromProto(const v1::FrameSet& m) {
  FrameSet set;
  set.sequence = m.sequence();
  set.stamp_ns = m.stamp_ns();
  set.skew_ns = m.skew_ns();
  set.frames.reserve(m.frames_size());
  for (const v1::Frame& frame : m.frames()) {
    set.frames.push_back(SensorFrameFromProto(v1::Frame(frame)));
  }
  return set;
}

FrameSetRecord FrameSetRecordFromProto(const v1::FrameSetRecord& m) {
  FrameSetRecord record;
  record.sequence = m.sequence();
  record.stamp_ns = m.stamp_ns();
  record.skew_ns = m.skew_ns();
  record.sensor_ids.assign(m.sensor_ids().begin(), m.sensor_ids().end());
  record.frame_indices.assign(m.frame_indices().begin(), m.frame_indices().end());
  return record;
}

namespace {

enum class Stream { kDepth, kMask, kColor, kSkeleton };

struct TopicRoute {
  int sensor = -1;
  Stream stream = Stream::kDepth;
};

// The schema a stream's messages must have.
const char* ExpectedType(Stream stream) {
  switch (stream) {
    case Stream::kDepth:
      return "reenact.v1.DepthImage";
    case Stream::kMask:
      return "reenact.v1.ActorMask";
    case Stream::kColor:
      return "reenact.v1.ColorImage";
    case Stream::kSkeleton:
      return "reenact.v1.Skeleton";
  }
  return "";
}

// Reads a take file's messages into a RecordedTake.
class RecordedTakeReader {
 public:
  RecordedTakeReader(const TakeReader& reader, const RecordedTakeOptions& options,
                     const ProgressCallback& progress)
      : reader_(reader), options_(options), progress_(progress) {}

  absl::StatusOr<RecordedTake> Read() {
    RecordedTake take;
    take.info = TakeInfoFromProto(reader_.info());
    for (const auto& [id, calibration] : reader_.sensors()) {
      absl::StatusOr<SensorCalibration> plain = SensorCalibrationFromProto(calibration);
      if (!plain.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(path(), ": sensor ", id, ": ", plain.status().message()));
      }
      const int s = static_cast<int>(take.sensors.size());
      routes_[SensorTopic(id, "depth")] = {s, Stream::kDepth};
      routes_[SensorTopic(id, "mask")] = {s, Stream::kMask};
      routes_[SensorTopic(id, "color")] = {s, Stream::kColor};
      routes_[SensorTopic(id, "skeleton")] = {s, Stream::kSkeleton};
      take.sensors.push_back(*std::move(plain));
    }
    frames_.resize(take.sensors.size());
    RETURN_IF_ERROR(ReadMessages(&take.frame_sets));
    for (size_t s = 0; s < frames_.size(); ++s) {
      for (auto& [index, frame] : frames_[s]) {
        frame.sensor_id = take.sensors[s].sensor_id;
        frame.frame_index = index;
        take.frames.push_back(std::move(frame));
      }
    }
    return take;
  }

 private:
  const std::string& path() const { return reader_.mcap().path(); }

  absl::Status CheckSchema(const McapChannel& channel, const std::string& expected) const {
    const auto& schemas = reader_.mcap().schemas();
    auto it = schemas.find(channel.schema_id);
    if (it == schemas.end() || it->second.name != expected) {
      return absl::InvalidArgumentError(
          absl::StrCat(path(), ": channel ", channel.topic, " does not hold ", expected));
    }
    return absl::OkStatus();
  }

  template <typename Message>
  absl::Status Parse(const McapChannel& channel, const McapMessage& message, Message* out) const {
    if (!out->ParseFromString(message.data)) {
      return absl::DataLossError(absl::StrCat(path(), ": message on ", channel.topic,
                                              " at log time ", message.log_time_ns,
                                              " ns does not parse"));
    }
    return absl::OkStatus();
  }

  absl::Status ReadMessages(std::vector<FrameSetRecord>* records) {
    const uint64_t total = reader_.mcap().statistics().message_count;
    uint64_t done = 0;
    std::map<uint16_t, bool> checked;  // Channel id -> schema checked.
    return reader_.mcap().ForEachMessage(
        [&](const McapChannel& channel, const McapMessage& message) -> absl::Status {
          if ((++done % 32 == 0 || done == total) && progress_) {
            Progress p{"load", total > 0 ? static_cast<double>(done) / total : 0.0,
                       static_cast<int64_t>(done), static_cast<int64_t>(total)};
            if (!progress_(p)) return absl::CancelledError("cancelled while loading the take");
          }
          if (channel.topic == kIngestFrameSetTopic) {
            if (!checked[channel.id]) {
              RETURN_IF_ERROR(CheckSchema(channel, "reenact.v1.FrameSetRecord"));
              checked[channel.id] = true;
            }
            v1::FrameSetRecord record;
            RETURN_IF_ERROR(Parse(channel, message, &record));
            records->push_back(FrameSetRecordFromProto(record));
            return absl::OkStatus();
          }
          auto route = routes_.find(channel.topic);
          if (route == routes_.end()) return absl::OkStatus();
          if (!checked[channel.id]) {
            RETURN_IF_ERROR(CheckSchema(channel, ExpectedType(route->second.stream)));
            checked[channel.id] = true;
          }
          return Store(channel, message, route->second);
        });
  }

  absl::Status Store(const McapChannel& channel, const McapMessage& message,
                     const TopicRoute& route) {
    auto& frames = frames_[route.sensor];
    switch (route.stream) {
      case Stream::kDepth: {
        v1::DepthImage m;
        RETURN_IF_ERROR(Parse(channel, message, &m));
        frames[m.frame_index()].depth = TakeImage(&m);
        break;
      }
      case Stream::kMask: {
        v1::ActorMask m;
        RETURN_IF_ERROR(Parse(channel, message, &m));
        frames[m.frame_index()].mask = TakeImage(&m);
        break;
      }
      case Stream::kColor: {
        if (!options_.load_color) break;
        v1::ColorImage m;
        RETURN_IF_ERROR(Parse(channel, message, &m));
        frames[m.frame_index()].color = TakeImage(&m);
        break;
      }
      case Stream::kSkeleton: {
        v1::Skeleton m;
        RETURN_IF_ERROR(Parse(channel, message, &m));
        frames[m.frame_index()].skeletons.push_back(SkeletonFromProto(m));
        break;
      }
    }
    return absl::OkStatus();
  }

  const TakeReader& reader_;
  const RecordedTakeOptions options_;
  const ProgressCallback& progress_;
  std::map<std::string, TopicRoute> routes_;
  std::vector<std::map<int64_t, SensorFrame>> frames_;  // Per sensor, by frame_index.
};

}  // namespace

absl::StatusOr<RecordedTake> ReadRecordedTake(const std::string& path,
                                              const RecordedTakeOptions& options,
                                              const ProgressCallback& progress) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return absl::NotFoundError(absl::StrCat("take not found: ", path));
  }
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  return RecordedTakeReader(*reader, options, progress).Read();
}

namespace {

absl::StatusOr<GroundTruthTopology> TopologyFromProto(const v1::GroundTruthTopology& m) {
  GroundTruthTopology topology;
  topology.model_name = m.model_name();
  topology.vertex_count = m.vertex_count();
  if (topology.vertex_count <= 0) {
    return absl::DataLossError("ground truth topology: no vertices");
  }
  const auto triangles = [&](const auto& indices, int limit, const char* what,
                             std::vector<Eigen::Vector3i>* out) -> absl::Status {
    if (indices.size() % 3 != 0) {
      return absl::DataLossError(
          absl::StrCat("ground truth topology: ", what, " indices not a multiple of 3"));
    }
    out->reserve(indices.size() / 3);
    for (int i = 0; i < indices.size(); i += 3) {
      const Eigen::Vector3i t(static_cast<int>(indices[i]), static_cast<int>(indices[i + 1]),
                              static_cast<int>(indices[i + 2]));
      if ((t.array() < 0).any() || (t.array() >= limit).any()) {
        return absl::DataLossError(
            absl::StrCat("ground truth topology: ", what, " index out of range"));
      }
      out->push_back(t);
    }
    return absl::OkStatus();
  };
  RETURN_IF_ERROR(
      triangles(m.triangle_indices(), topology.vertex_count, "triangle", &topology.triangles));
  ASSIGN_OR_RETURN(const std::vector<float> uvs, UnpackFloats(m.uvs_f32()));
  if (uvs.size() % 2 != 0) return absl::DataLossError("ground truth topology: odd uv count");
  topology.uvs.reserve(uvs.size() / 2);
  for (size_t i = 0; i + 1 < uvs.size(); i += 2) topology.uvs.emplace_back(uvs[i], uvs[i + 1]);
  if (!topology.uvs.empty()) {
    RETURN_IF_ERROR(triangles(m.uv_triangle_indices(), static_cast<int>(topology.uvs.size()),
                              "uv triangle", &topology.uv_triangles));
  }
  topology.albedo_png = m.albedo_png();
  if (m.has_direction_to_light_in_world()) {
    topology.direction_to_light_in_world = FromProto(m.direction_to_light_in_world());
  }
  topology.ambient = m.ambient();
  topology.diffuse = m.diffuse();
  return topology;
}

}  // namespace

absl::StatusOr<GroundTruth> ReadGroundTruth(const TakeReader& take,
                                            const std::set<int64_t>& mesh_frames) {
  GroundTruth truth;
  ASSIGN_OR_RETURN(auto topologies,
                   take.ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic));
  if (topologies.empty()) {
    return absl::FailedPreconditionError(
        "the take has no ground truth (/ground_truth/topology); evaluate against a synthetic take");
  }
  ASSIGN_OR_RETURN(truth.topology, TopologyFromProto(topologies.front()));
  const int vertex_count = truth.topology.vertex_count;
  if (!mesh_frames.empty()) {
    RETURN_IF_ERROR(take.ForEach<v1::GroundTruthMesh>(
        kGroundTruthMeshTopic, [&](const v1::GroundTruthMesh& mesh) -> absl::Status {
          if (!mesh_frames.count(mesh.frame_index())) return absl::OkStatus();
          const std::string& bytes = mesh.positions_in_world_m_f32();
          if (mesh.vertex_count() != vertex_count ||
              bytes.size() != static_cast<size_t>(vertex_count) * 3 * sizeof(float)) {
            return absl::DataLossError(absl::StrCat("ground truth mesh of frame ",
                                                    mesh.frame_index(), " has the wrong size"));
          }
          Eigen::Matrix3Xf positions(3, vertex_count);
          std::memcpy(positions.data(), bytes.data(), bytes.size());
          truth.meshes[mesh.frame_index()] = positions.cast<double>();
          return absl::OkStatus();
        }));
  }
  RETURN_IF_ERROR(take.ForEach<v1::GroundTruthJoints>(
      kGroundTruthJointsTopic, [&](const v1::GroundTruthJoints& joints) -> absl::Status {
        if (joints.positions_in_world_m_size() != body::kNumKinectV2Joints) {
          return absl::OkStatus();
        }
        TrueJoints& out = truth.joints[joints.frame_index()];
        for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
          out[j] = FromProto(joints.positions_in_world_m(j));
        }
        return absl::OkStatus();
      }));
  ASSIGN_OR_RETURN(truth.sensors, TakeSensorCalibrations(take));
  return truth;
}

absl::StatusOr<std::vector<SensorCalibration>> TakeSensorCalibrations(const TakeReader& take) {
  std::vector<SensorCalibration> sensors;
  sensors.reserve(take.sensors().size());
  for (const auto& [id, calibration] : take.sensors()) {
    ASSIGN_OR_RETURN(SensorCalibration sensor, SensorCalibrationFromProto(calibration));
    sensors.push_back(std::move(sensor));
  }
  return sensors;
}

}  // namespace reenact
