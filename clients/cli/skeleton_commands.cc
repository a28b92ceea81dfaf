// `reenact take skeletons`: the skeletons of a take measured against a
// synthetic take's ground truth, per sensor and fused over the sensors
// (common/tracking/skeleton_fusion.h).
//
// The take and the truth may be one file (a synthetic take) or a stored take
// and the synthetic take its daemon streamed. Skeletons match ground truth by
// frame_index; a skeleton goes to the world by world_from_depth of the
// truth take's sensor of the same id (the world of the ground truth, which a
// daemon that anchored the take on the printed board replaced), or of the
// take's own sensor when the truth take has none of that id. The truth is
// interpolated to the skeleton's exposure (device stamp + that sensor's
// clock offset) when it lies within a frame of the matched one: synthetic
// sensors expose up to 0.3 frames after the ground-truth instant.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/depth_codec.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/skeleton_errors.h"
#include "common/tracking/skeleton_fusion.h"
#include "common/tracking/tracking_proto.h"

namespace reenact::cli {
namespace {

constexpr int kNumJoints = body::kNumKinectV2Joints;
constexpr double kPckThresholdM = 0.10;

using Joints = std::array<Eigen::Vector3d, kNumJoints>;
using SkeletonJoints = std::array<tracking::TrackedJoint, kNumJoints>;

struct TruthFrame {
  int64_t stamp_ns = 0;
  Joints position_in_world_m;
};
using Truth = std::map<int64_t, TruthFrame>;  // By frame_index.

// One sensor of the take: where its skeletons go in the truth's world, and
// its skeletons by frame_index (several bodies per frame possible).
struct SensorInput {
  std::string id;
  Rigid3d world_from_depth;
  int64_t clock_offset_ns = 0;
  bool calibration_from_truth = false;
  std::map<int64_t, std::vector<v1::Skeleton>> skeletons;
};

// A skeleton in the truth's world.
struct WorldSkeleton {
  Joints position_m;
  std::array<tracking::JointState, kNumJoints> state{};
};

// Errors of one source (a sensor, or the fusion) over the frames it was
// measured in: over its tracked and inferred joints together (a joint not
// tracked is a PCK miss), and over each state alone.
struct ErrorTally {
  tracking::SkeletonErrorAccumulator all{kPckThresholdM}, tracked{kPckThresholdM},
      inferred{kPckThresholdM};
  int swapped_frames = 0;  // Sensors: frames the fusion swapped its left and right.

  void Add(const WorldSkeleton& estimate, const Joints& truth_m) {
    std::array<bool, kNumJoints> any{}, is_tracked{}, is_inferred{};
    for (int j = 0; j < kNumJoints; ++j) {
      is_tracked[j] = estimate.state[j] == tracking::JointState::kTracked;
      is_inferred[j] = estimate.state[j] == tracking::JointState::kInferred;
      any[j] = is_tracked[j] || is_inferred[j];
    }
    all.Add(estimate.position_m, any, truth_m);
    tracked.Add(estimate.position_m, is_tracked, truth_m);
    inferred.Add(estimate.position_m, is_inferred, truth_m);
  }
};

int64_t Measured(const tracking::SkeletonErrors& e) {
  int64_t count = 0;
  for (int64_t c : e.joint_count) count += c;
  return count;
}

nlohmann::json Mm(double value_mm, int64_t count) {
  return count > 0 ? nlohmann::json(value_mm) : nlohmann::json();
}

nlohmann::json TallyJson(const ErrorTally& t) {
  const tracking::SkeletonErrors all = t.all.Result(), tracked = t.tracked.Result(),
                                 inferred = t.inferred.Result();
  nlohmann::json joints = nlohmann::json::object();
  for (int j = 0; j < kNumJoints; ++j) {
    joints[std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)))] =
        Mm(all.joint_mean_mm[j], all.joint_count[j]);
  }
  return {{"frames", all.frames},
          {"mpjpe_mm", Mm(all.mpjpe_mm, Measured(all))},
          {"mpjpe_tracked_mm", Mm(tracked.mpjpe_mm, Measured(tracked))},
          {"mpjpe_inferred_mm", Mm(inferred.mpjpe_mm, Measured(inferred))},
          {"pck_10cm_percent", all.joints > 0 ? nlohmann::json(100.0 * all.pck) : nlohmann::json()},
          {"joints_tracked", Measured(tracked)},
          {"joints_inferred", Measured(inferred)},
          {"joints_not_tracked", all.joints - Measured(all)},
          {"joint_mean_mm", joints}};
}

// ------------------------------------------------------------------ reading

absl::StatusOr<Truth> ReadTruth(const TakeReader& take, const std::string& path) {
  Truth truth;
  RETURN_IF_ERROR(take.ForEach<v1::GroundTruthJoints>(
      kGroundTruthJointsTopic, [&](const v1::GroundTruthJoints& m) -> absl::Status {
        TruthFrame frame{m.stamp_ns(), {}};
        std::array<bool, kNumJoints> seen{};
        for (int i = 0; i < m.positions_in_world_m_size() && i < m.joint_names_size(); ++i) {
          const auto joint = body::KinectV2JointFromName(m.joint_names(i));
          if (!joint) continue;
          frame.position_in_world_m[body::Index(*joint)] = FromProto(m.positions_in_world_m(i));
          seen[body::Index(*joint)] = true;
        }
        if (std::all_of(seen.begin(), seen.end(), [](bool b) { return b; })) {
          truth[m.frame_index()] = frame;
        }
        return absl::OkStatus();
      }));
  if (truth.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, ": no ground truth joints (", std::string(kGroundTruthJointsTopic),
                     " with all 25 Kinect v2 joints); --truth must name a synthetic take"));
  }
  return truth;
}

// The calibration that maps the sensor into the truth's world.
absl::Status SetCalibration(const TakeReader& take, const TakeReader& truth, SensorInput* sensor) {
  auto in_truth = truth.sensors().find(sensor->id);
  const bool from_truth = in_truth != truth.sensors().end();
  const v1::SensorCalibration& calibration =
      from_truth ? in_truth->second : take.sensors().at(sensor->id);
  absl::StatusOr<Rigid3d> world_from_depth = FromProto(calibration.world_from_depth());
  if (!world_from_depth.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "sensor ", sensor->id, ": world_from_depth: ", world_from_depth.status().message()));
  }
  sensor->world_from_depth = *world_from_depth;
  sensor->clock_offset_ns = calibration.clock_offset_ns();
  sensor->calibration_from_truth = from_truth;
  return absl::OkStatus();
}

absl::StatusOr<std::vector<SensorInput>> ReadSensors(const TakeReader& take,
                                                     const TakeReader& truth,
                                                     const std::string& path) {
  std::vector<SensorInput> sensors;
  for (const auto& [id, calibration] : take.sensors()) {
    SensorInput sensor;
    sensor.id = id;
    RETURN_IF_ERROR(
        take.ForEach<v1::Skeleton>(SensorTopic(id, "skeleton"), [&sensor](const v1::Skeleton& m) {
          sensor.skeletons[m.frame_index()].push_back(m);
          return absl::OkStatus();
        }));
    if (sensor.skeletons.empty()) continue;
    RETURN_IF_ERROR(SetCalibration(take, truth, &sensor));
    sensors.push_back(std::move(sensor));
  }
  if (sensors.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, ": no skeleton channel (no Skeleton messages on /sensor/<id>/skeleton of any of its ",
        take.sensors().size(), " sensors)"));
  }
  return sensors;
}

// --track: the sensors' skeletons tracked afresh from the take's depth (and
// its actor masks, where it has them), frame by frame in stream order, as
// reenactd's tracker would; the skeletons the take stores are ignored.
absl::StatusOr<std::vector<SensorInput>> TrackSensors(const TakeReader& take,
                                                      const TakeReader& truth,
                                                      const tracking::BodyTrackerOptions& options,
                                                      const std::string& path) {
  std::vector<SensorInput> sensors;
  for (const auto& [id, calibration] : take.sensors()) {
    absl::StatusOr<std::map<int64_t, std::vector<v1::Skeleton>>> tracked =
        tracking::TrackTakeSensor(take, id, options);
    if (!tracked.ok()) {
      return absl::Status(tracked.status().code(),
                          absl::StrCat(path, ": ", tracked.status().message()));
    }
    SensorInput sensor;
    sensor.id = id;
    sensor.skeletons = *std::move(tracked);
    if (sensor.skeletons.empty()) continue;
    RETURN_IF_ERROR(SetCalibration(take, truth, &sensor));
    sensors.push_back(std::move(sensor));
  }
  if (sensors.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, ": the tracker found nobody in the depth of any of its ",
                     take.sensors().size(), " sensors"));
  }
  return sensors;
}

// The joints of a Skeleton message by name; a joint of unspecified state
// counts as not tracked. A joint without confidence (a device's) gets 1.
SkeletonJoints FromSkeleton(const v1::Skeleton& skeleton) {
  SkeletonJoints joints;
  for (const v1::Joint& m : skeleton.joints()) {
    const auto joint = body::KinectV2JointFromName(m.name());
    if (!joint) continue;
    tracking::TrackedJoint& out = joints[body::Index(*joint)];
    out.position_in_camera_m = FromProto(m.position_in_depth_m());
    out.confidence = m.confidence() > 0.0f ? m.confidence() : 1.0;
    out.state = m.tracking_state() == v1::TRACKING_STATE_TRACKED ? tracking::JointState::kTracked
                : m.tracking_state() == v1::TRACKING_STATE_INFERRED
                    ? tracking::JointState::kInferred
                    : tracking::JointState::kNotTracked;
  }
  return joints;
}

// --------------------------------------------------------------- evaluation

// The truth at `exposure_ns`, interpolated between the matched frame and its
// neighbour when the exposure lies between them; the matched frame's
// otherwise.
Joints TruthAt(const Truth& truth, Truth::const_iterator frame, int64_t exposure_ns) {
  auto other = exposure_ns >= frame->second.stamp_ns
                   ? std::next(frame)
                   : (frame == truth.begin() ? truth.end() : std::prev(frame));
  if (other == truth.end() || other->second.stamp_ns == frame->second.stamp_ns) {
    return frame->second.position_in_world_m;
  }
  const double s = static_cast<double>(exposure_ns - frame->second.stamp_ns) /
                   static_cast<double>(other->second.stamp_ns - frame->second.stamp_ns);
  if (!(s >= 0.0 && s <= 1.0)) return frame->second.position_in_world_m;
  Joints joints;
  for (int j = 0; j < kNumJoints; ++j) {
    joints[j] =
        (1 - s) * frame->second.position_in_world_m[j] + s * other->second.position_in_world_m[j];
  }
  return joints;
}

WorldSkeleton ToWorld(const SkeletonJoints& joints, const Rigid3d& world_from_depth) {
  WorldSkeleton w;
  for (int j = 0; j < kNumJoints; ++j) {
    w.position_m[j] = world_from_depth * joints[j].position_in_camera_m;
    w.state[j] = joints[j].state;
  }
  return w;
}

// Mean error of the skeleton's estimated joints, metres (infinite when none).
double MeanError(const WorldSkeleton& w, const Joints& truth_m) {
  double sum = 0.0;
  int count = 0;
  for (int j = 0; j < kNumJoints; ++j) {
    if (w.state[j] == tracking::JointState::kNotTracked || !w.position_m[j].allFinite()) continue;
    sum += (w.position_m[j] - truth_m[j]).norm();
    ++count;
  }
  return count > 0 ? sum / count : std::numeric_limits<double>::infinity();
}

// One sensor's skeleton at one frame: of several bodies, the one closest to
// the truth (the person the ground truth describes).
struct Pick {
  SkeletonJoints joints;
  WorldSkeleton world;
  Joints truth_m;
  int64_t exposure_ns = 0;
};

Pick PickSkeleton(const SensorInput& sensor, const std::vector<v1::Skeleton>& bodies,
                  const Truth& truth, Truth::const_iterator frame) {
  std::optional<Pick> best;
  double best_error = 0.0;
  for (const v1::Skeleton& body : bodies) {
    Pick pick{FromSkeleton(body), {}, {}, body.device_stamp_ns() + sensor.clock_offset_ns};
    pick.world = ToWorld(pick.joints, sensor.world_from_depth);
    pick.truth_m = TruthAt(truth, frame, pick.exposure_ns);
    const double error = MeanError(pick.world, pick.truth_m);
    if (!best || error < best_error) best = pick, best_error = error;
  }
  return *best;
}

struct Evaluation {
  std::vector<ErrorTally> sensors;  // Parallel to the SensorInputs.
  ErrorTally fused;
  int frames_without_truth = 0;
};

// Fuses the picked skeletons of one instant and tallies the result against
// the truth at their mean exposure.
absl::Status TallyFused(const std::vector<SensorInput>& inputs, const std::vector<int>& which,
                        const std::vector<Pick>& picks, const Truth& truth,
                        Truth::const_iterator frame, tracking::SequentialSkeletonFusion* fusion,
                        Evaluation* evaluation) {
  if (picks.empty()) return absl::OkStatus();
  std::vector<tracking::SensorSkeleton> views;
  double exposure_sum_ns = 0;
  for (size_t k = 0; k < picks.size(); ++k) {
    views.push_back({inputs[which[k]].id, inputs[which[k]].world_from_depth, picks[k].joints});
    exposure_sum_ns += static_cast<double>(picks[k].exposure_ns - frame->second.stamp_ns);
  }
  ASSIGN_OR_RETURN(tracking::SkeletonFusionSummary summary,
                   fusion->Fuse(views, frame->second.stamp_ns));
  WorldSkeleton fused;
  for (int j = 0; j < kNumJoints; ++j) {
    fused.position_m[j] = summary.skeleton.joints[j].position_in_world_m;
    fused.state[j] = summary.skeleton.joints[j].state;
  }
  const int64_t mean_exposure_ns =
      frame->second.stamp_ns + std::llround(exposure_sum_ns / static_cast<double>(picks.size()));
  evaluation->fused.Add(fused, TruthAt(truth, frame, mean_exposure_ns));
  for (size_t k = 0; k < picks.size(); ++k) {
    evaluation->sensors[which[k]].swapped_frames += summary.sensors[k].swapped_left_right;
  }
  return absl::OkStatus();
}

absl::Status EvaluateFrame(const std::vector<SensorInput>& inputs, const Truth& truth,
                           int64_t frame_index, tracking::SequentialSkeletonFusion* fusion,
                           Evaluation* evaluation) {
  const auto frame = truth.find(frame_index);
  if (frame == truth.end()) {
    ++evaluation->frames_without_truth;
    return absl::OkStatus();
  }
  std::vector<Pick> picks;
  std::vector<int> which;
  for (size_t s = 0; s < inputs.size(); ++s) {
    const auto bodies = inputs[s].skeletons.find(frame_index);
    if (bodies == inputs[s].skeletons.end() || bodies->second.empty()) continue;
    picks.push_back(PickSkeleton(inputs[s], bodies->second, truth, frame));
    which.push_back(static_cast<int>(s));
    evaluation->sensors[s].Add(picks.back().world, picks.back().truth_m);
  }
  return TallyFused(inputs, which, picks, truth, frame, fusion, evaluation);
}

absl::StatusOr<Evaluation> Evaluate(const std::vector<SensorInput>& inputs, const Truth& truth) {
  Evaluation evaluation;
  evaluation.sensors.resize(inputs.size());
  std::set<int64_t> frames;
  for (const SensorInput& sensor : inputs) {
    for (const auto& [f, bodies] : sensor.skeletons) frames.insert(f);
  }
  tracking::SequentialSkeletonFusion fusion;
  for (int64_t f : frames) RETURN_IF_ERROR(EvaluateFrame(inputs, truth, f, &fusion, &evaluation));
  if (evaluation.fused.all.Result().frames == 0) {
    return absl::FailedPreconditionError(
        "no skeleton frame of the take has a ground-truth frame of the same frame_index");
  }
  return evaluation;
}

// ------------------------------------------------------------------- output

nlohmann::json EvaluationJson(const std::string& take_path, const std::string& truth_path,
                              const std::vector<SensorInput>& inputs, const Truth& truth,
                              const Evaluation& e) {
  nlohmann::json j = {{"take", take_path},
                      {"truth", truth_path},
                      {"truth_frames", truth.size()},
                      {"frames_without_truth", e.frames_without_truth},
                      {"pck_threshold_m", kPckThresholdM},
                      {"sensors", nlohmann::json::array()}};
  for (size_t s = 0; s < inputs.size(); ++s) {
    nlohmann::json sensor = TallyJson(e.sensors[s]);
    sensor["id"] = inputs[s].id;
    sensor["calibration"] = inputs[s].calibration_from_truth ? "truth" : "take";
    sensor["fusion_swapped_frames"] = e.sensors[s].swapped_frames;
    j["sensors"].push_back(sensor);
  }
  j["fused"] = TallyJson(e.fused);
  return j;
}

std::string Cell(const nlohmann::json& value, int width, int precision = 1) {
  std::ostringstream s;
  s << std::setw(width) << std::fixed << std::setprecision(precision);
  if (value.is_number()) {
    s << value.get<double>();
  } else {
    s << "-";
  }
  return s.str();
}

void PrintRow(const std::string& name, const nlohmann::json& t, const std::string& extra,
              std::ostream& out) {
  out << "  " << std::left << std::setw(10) << name << std::right << std::setw(7)
      << t["frames"].get<int>() << Cell(t["mpjpe_mm"], 10) << Cell(t["mpjpe_tracked_mm"], 10)
      << Cell(t["pck_10cm_percent"], 12) << extra << "\n";
}

void PrintEvaluation(const nlohmann::json& j, std::ostream& out) {
  out << j["take"].get<std::string>() << " against the ground truth of "
      << j["truth"].get<std::string>() << " (" << j["truth_frames"] << " frames)\n"
      << "  source     frames  MPJPE mm  tracked mm  PCK@10cm %  swapped frames\n";
  for (const auto& s : j["sensors"]) {
    PrintRow(s["id"].get<std::string>(), s,
             "  " + std::to_string(s["fusion_swapped_frames"].get<int>()), out);
  }
  PrintRow("fused", j["fused"], "", out);
  out << "per-joint mean error, mm:\n  " << std::left << std::setw(14) << "joint" << std::right;
  for (const auto& s : j["sensors"]) out << std::setw(8) << s["id"].get<std::string>();
  out << std::setw(8) << "fused"
      << "\n";
  for (int k = 0; k < kNumJoints; ++k) {
    const std::string name(body::KinectV2JointName(static_cast<body::KinectV2Joint>(k)));
    out << "  " << std::left << std::setw(14) << name << std::right;
    for (const auto& s : j["sensors"]) out << Cell(s["joint_mean_mm"][name], 8);
    out << Cell(j["fused"]["joint_mean_mm"][name], 8) << "\n";
  }
  if (j["frames_without_truth"].get<int>() > 0) {
    out << "  " << j["frames_without_truth"] << " skeleton frames had no ground truth\n";
  }
}

absl::StatusOr<nlohmann::json> TakeSkeletons(
    const std::string& take_path, const std::string& truth_path,
    const std::optional<tracking::BodyTrackerOptions>& track) {
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> take, TakeReader::Open(take_path));
  std::unique_ptr<TakeReader> truth_reader;
  if (truth_path != take_path) {
    ASSIGN_OR_RETURN(truth_reader, TakeReader::Open(truth_path));
  }
  const TakeReader& truth_take = truth_reader ? *truth_reader : *take;
  std::vector<SensorInput> inputs;
  if (track) {
    ASSIGN_OR_RETURN(inputs, TrackSensors(*take, truth_take, *track, take_path));
  } else {
    ASSIGN_OR_RETURN(inputs, ReadSensors(*take, truth_take, take_path));
  }
  ASSIGN_OR_RETURN(Truth truth, ReadTruth(truth_take, truth_path));
  ASSIGN_OR_RETURN(Evaluation evaluation, Evaluate(inputs, truth));
  return EvaluationJson(take_path, truth_path, inputs, truth, evaluation);
}

}  // namespace

int RunTakeSkeletons(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags =
      Flags::Parse(args, {"truth", "forest", "model"}, {"json", "track", "refine", "no-refine"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto truth = flags->Required("truth");
  if (!truth.ok()) return ReportError(truth.status(), err);
  std::optional<tracking::BodyTrackerOptions> track;
  if (flags->Has("track")) {
    track.emplace();
    if (const std::optional<std::string> forest = flags->Get("forest")) {
      track->method = tracking::TrackerMethod::kForest;
      track->forest_path = *forest;
    }
    track->model_path = flags->Get("model").value_or("");
    track->refine = flags->Has("refine") && !flags->Has("no-refine");
  } else if (flags->Has("no-refine") || flags->Has("refine") || flags->Has("forest") ||
             flags->Has("model")) {
    return ReportError(
        absl::InvalidArgumentError("--refine, --no-refine, --model and --forest go with --track"),
        err);
  }
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("take skeletons needs exactly one TAKE file"),
                       err);
  }
  absl::StatusOr<nlohmann::json> result = TakeSkeletons(flags->positional()[0], *truth, track);
  if (!result.ok()) {
    ReportError(result.status(), err);
    return kExitFailure;  // Bad files, not bad usage.
  }
  if (flags->Has("json")) {
    out << result->dump(2) << "\n";
  } else {
    PrintEvaluation(*result, out);
  }
  return kExitOk;
}

}  // namespace reenact::cli
