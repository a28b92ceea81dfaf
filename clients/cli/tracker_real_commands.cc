// `reenact tracker eval --real DIR`: the body tracker measured on recorded
// depth sequences with a reference skeleton per frame, laid out as
// ../shared/data/rgbd-seq is (frames/NNNN.png in mm, meta.json with the
// intrinsics, joint names and per frame the joints in the camera frame); and
// `reenact tracker synth`: the project's own synthetic depth written in that
// layout, for training the tracker's network and for measuring it.
#include <algorithm>
#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "clients/cli/commands.h"
#include "clients/cli/progress_bar.h"
#include "clients/cli/real_sequences.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/training_data.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;
using body::KinectV2Joint;

constexpr int kJoints = body::kNumKinectV2Joints;

// The 20 joints an evaluation scores: Kinect v1's skeleton in Kinect v2
// names (no neck, hand tips or thumbs).
bool Scored(int j) {
  return j != body::Index(KinectV2Joint::kNeck) && j < body::Index(KinectV2Joint::kHandTipLeft);
}

// Left and right joints of the limbs.
constexpr std::array<std::pair<KinectV2Joint, KinectV2Joint>, 8> kLimbPairs = {{
    {KinectV2Joint::kShoulderLeft, KinectV2Joint::kShoulderRight},
    {KinectV2Joint::kElbowLeft, KinectV2Joint::kElbowRight},
    {KinectV2Joint::kWristLeft, KinectV2Joint::kWristRight},
    {KinectV2Joint::kHandLeft, KinectV2Joint::kHandRight},
    {KinectV2Joint::kHipLeft, KinectV2Joint::kHipRight},
    {KinectV2Joint::kKneeLeft, KinectV2Joint::kKneeRight},
    {KinectV2Joint::kAnkleLeft, KinectV2Joint::kAnkleRight},
    {KinectV2Joint::kFootLeft, KinectV2Joint::kFootRight},
}};

// Error sums of one sequence or of all.
struct Tally {
  int frames = 0;         // With a reference.
  int frames_missed = 0;  // With a reference but no skeleton tracked.
  int frames_sided = 0;   // Where left and right could be compared.
  int frames_swapped = 0;
  int64_t joints = 0, within_10cm = 0, joints_missed = 0;
  double error_sum_m = 0;
  std::array<double, kJoints> joint_sum_m{};
  std::array<int64_t, kJoints> joint_count{};
  double track_ms = 0;

  void Add(const Tally& o) {
    frames += o.frames, frames_missed += o.frames_missed, frames_sided += o.frames_sided;
    frames_swapped += o.frames_swapped, joints += o.joints, within_10cm += o.within_10cm;
    joints_missed += o.joints_missed, error_sum_m += o.error_sum_m, track_ms += o.track_ms;
    for (int j = 0; j < kJoints; ++j) {
      joint_sum_m[j] += o.joint_sum_m[j], joint_count[j] += o.joint_count[j];
    }
  }
  double Mpjpe() const { return joints ? 1000.0 * error_sum_m / joints : 0.0; }
  // Missed joints count as beyond 10 cm.
  double Pck() const {
    const int64_t all = joints + joints_missed;
    return all ? 100.0 * within_10cm / all : 0.0;
  }
  double Swapped() const { return frames_sided ? 100.0 * frames_swapped / frames_sided : 0.0; }
};

void Score(const RefFrame& ref, const tracking::TrackedPerson* person, Tally* t) {
  bool any = false;
  for (int j = 0; j < kJoints; ++j) any |= Scored(j) && ref.joints[j].has_value();
  if (!any) return;
  ++t->frames;
  if (person == nullptr) {
    ++t->frames_missed;
    for (int j = 0; j < kJoints; ++j) t->joints_missed += Scored(j) && ref.joints[j].has_value();
    return;
  }
  for (int j = 0; j < kJoints; ++j) {
    if (!Scored(j) || !ref.joints[j]) continue;
    const tracking::TrackedJoint& joint = person->joints[j];
    if (joint.state == tracking::JointState::kNotTracked) {
      ++t->joints_missed;
      continue;
    }
    const double e = (joint.position_in_camera_m - *ref.joints[j]).norm();
    ++t->joints, t->error_sum_m += e, t->within_10cm += e < 0.1;
    t->joint_sum_m[j] += e, ++t->joint_count[j];
  }
  double same = 0, swapped = 0;
  int pairs = 0;
  for (const auto& [l, r] : kLimbPairs) {
    const int il = body::Index(l), ir = body::Index(r);
    if (!ref.joints[il] || !ref.joints[ir] ||
        person->joints[il].state == tracking::JointState::kNotTracked ||
        person->joints[ir].state == tracking::JointState::kNotTracked) {
      continue;
    }
    const Eigen::Vector3d& pl = person->joints[il].position_in_camera_m;
    const Eigen::Vector3d& pr = person->joints[ir].position_in_camera_m;
    same += (pl - *ref.joints[il]).norm() + (pr - *ref.joints[ir]).norm();
    swapped += (pl - *ref.joints[ir]).norm() + (pr - *ref.joints[il]).norm();
    ++pairs;
  }
  if (pairs > 0) {
    ++t->frames_sided;
    t->frames_swapped += swapped < same;
  }
}

nlohmann::json TallyJson(const Tally& t) {
  nlohmann::json joints = nlohmann::json::object();
  for (int j = 0; j < kJoints; ++j) {
    if (t.joint_count[j] == 0) continue;
    joints[std::string(body::KinectV2JointName(static_cast<KinectV2Joint>(j)))] =
        1000.0 * t.joint_sum_m[j] / t.joint_count[j];
  }
  return {{"frames", t.frames},
          {"frames_without_skeleton", t.frames_missed},
          {"mpjpe_mm", t.Mpjpe()},
          {"pck_10cm", t.Pck()},
          {"left_right_swapped_percent", t.Swapped()},
          {"mean_track_ms", t.frames ? t.track_ms / t.frames : 0.0},
          {"joint_mean_mm", joints}};
}

}  // namespace

int RunTrackerEvalReal(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"real", "model", "forest", "sequences", "joints-out", "stride"},
                            {"json", "quiet", "no-history", "refine", "segment"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto dir = flags->Required("real");
  if (!dir.ok()) return ReportError(dir.status(), err);
  std::error_code ec;
  if (!fs::is_directory(*dir, ec)) {
    return ReportError(absl::NotFoundError(absl::StrCat("no folder ", *dir)), err);
  }
  const std::vector<std::string> filters =
      absl::StrSplit(flags->GetOr("sequences", ""), ',', absl::SkipEmpty());
  const std::vector<fs::path> folders = RefSequenceFolders(*dir, filters);
  if (folders.empty()) {
    return ReportError(
        absl::NotFoundError(absl::StrCat("no sequence (a folder with meta.json) in ", *dir,
                                         filters.empty() ? "" : " whose name matches --sequences")),
        err);
  }
  tracking::BodyTrackerOptions options;
  if (flags->Has("forest")) {
    options.method = tracking::TrackerMethod::kForest;
    options.forest_path = *flags->Get("forest");
  }
  options.model_path = flags->GetOr("model", "");
  options.refine = flags->Has("refine");
  auto stride = flags->GetInt("stride", options.pixel_stride);
  if (!stride.ok()) return ReportError(stride.status(), err);
  options.pixel_stride = *stride;
  auto tracker = tracking::BodyTracker::Create(options);
  if (!tracker.ok()) return ReportError(tracker.status(), err);
  const bool history = !flags->Has("no-history");
  const bool own_segmentation = flags->Has("segment");
  const bool quiet = flags->Has("quiet") || flags->Has("json");

  std::ofstream joints_out;
  if (const auto path = flags->Get("joints-out")) {
    joints_out.open(*path, std::ios::trunc);
    if (!joints_out) {
      return ReportError(absl::PermissionDeniedError(absl::StrCat("cannot write ", *path)), err);
    }
  }
  Tally all;
  nlohmann::json sequences = nlohmann::json::array();
  for (const fs::path& folder : folders) {
    absl::StatusOr<RefSequence> seq = ReadRefSequence(folder);
    if (!seq.ok()) return ReportError(seq.status(), err);
    absl::StatusOr<std::vector<TrackedRefFrame>> tracked =
        TrackRefSequence(**tracker, *seq, history, own_segmentation);
    if (!tracked.ok()) return ReportError(tracked.status(), err);
    Tally tally;
    for (size_t f = 0; f < seq->frames.size(); ++f) {
      const RefFrame& frame = seq->frames[f];
      tally.track_ms += (*tracked)[f].track_ms;
      const tracking::TrackedPerson* person =
          (*tracked)[f].person ? &*(*tracked)[f].person : nullptr;
      Score(frame, person, &tally);
      if (joints_out.is_open()) {
        nlohmann::json joints = nlohmann::json::object();
        if (person != nullptr) {
          for (int j = 0; j < kJoints; ++j) {
            const tracking::TrackedJoint& joint = person->joints[j];
            if (joint.state == tracking::JointState::kNotTracked) continue;
            const Eigen::Vector3d& p = joint.position_in_camera_m;
            joints[std::string(body::KinectV2JointName(static_cast<KinectV2Joint>(j)))] = {
                {"position_m", {p.x(), p.y(), p.z()}},
                {"confidence", joint.confidence},
                {"state", std::string(tracking::JointStateName(joint.state))}};
          }
        }
        joints_out << nlohmann::json{{"sequence", seq->name},
                                     {"frame", frame.index},
                                     {"joints", joints}}
                          .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)
                   << "\n";
      }
    }
    nlohmann::json s = TallyJson(tally);
    s["sequence"] = seq->name;
    sequences.push_back(s);
    if (!quiet) {
      out << seq->name << ": " << tally.frames << " frames, MPJPE " << tally.Mpjpe()
          << " mm, PCK@10cm " << tally.Pck() << " %, left/right swapped " << tally.Swapped()
          << " %, " << (tally.frames ? tally.track_ms / tally.frames : 0.0) << " ms/frame\n";
    }
    all.Add(tally);
  }
  if (joints_out.is_open() && !joints_out.flush()) {
    return ReportError(absl::DataLossError("cannot write --joints-out"), err);
  }
  nlohmann::json result = {
      {"sequences", sequences},
      {"overall", TallyJson(all)},
      {"history", history},
      {"method", options.method == tracking::TrackerMethod::kNetwork ? "network" : "forest"}};
  result["overall"]["sequences"] = sequences.size();
  if (flags->Has("json")) {
    out << result.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    return kExitOk;
  }
  out << "overall: " << sequences.size() << " sequences, " << all.frames << " frames ("
      << all.frames_missed << " without a skeleton), MPJPE " << all.Mpjpe() << " mm, PCK@10cm "
      << all.Pck() << " %, left/right swapped in " << all.Swapped() << " % of frames, "
      << (all.frames ? all.track_ms / all.frames : 0.0) << " ms/frame"
      << (history ? "" : " (each frame alone)") << "\n";
  for (const auto& [name, mm] : result["overall"]["joint_mean_mm"].items()) {
    out << "  " << name << " " << mm.get<double>() << " mm\n";
  }
  return kExitOk;
}

int RunTrackerSynth(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags =
      Flags::Parse(args,
                   {"out", "data", "images", "seed", "shapes", "bodies", "min-distance",
                    "max-distance", "arm-poses", "structured-light", "frame-stride", "motion"},
                   {"held-out", "sequence", "json", "quiet"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_dir = flags->Required("out");
  if (!out_dir.ok()) return ReportError(out_dir.status(), err);
  tracking::TrainingDataOptions o;
  const std::string data = flags->GetOr("data", "../shared/data");
  auto images = flags->GetInt("images", 1000);
  auto seed = flags->GetInt("seed", 1);
  auto shapes = flags->GetInt("shapes", o.shapes_per_body);
  auto min_d = flags->GetDouble("min-distance", 1.0);
  auto max_d = flags->GetDouble("max-distance", 4.5);
  auto arms = flags->GetDouble("arm-poses", o.arm_pose_fraction);
  auto sl = flags->GetDouble("structured-light", o.structured_light_fraction);
  auto frame_stride = flags->GetInt("frame-stride", o.frame_stride);
  for (const absl::Status& s :
       {images.status(), seed.status(), shapes.status(), min_d.status(), max_d.status(),
        arms.status(), sl.status(), frame_stride.status()}) {
    if (!s.ok()) return ReportError(s, err);
  }
  if (flags->Has("sequence")) {
    auto motion = flags->Required("motion");
    if (!motion.ok()) return ReportError(motion.status(), err);
    o = tracking::SequenceOptions(*motion, *images, *min_d, *max_d, static_cast<uint64_t>(*seed));
  } else {
    o.num_images = *images;
    o.seed = static_cast<uint64_t>(*seed);
    o.min_distance_m = *min_d, o.max_distance_m = *max_d;
    o.arm_pose_fraction = *arms;
    o.structured_light_fraction = *sl;
    const std::string motions =
        flags->Has("held-out") ? data + "/mocap/cmu" : data + "/mocap/cmu-train";
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(motions, ec)) {
      if (entry.path().extension() == ".bvh") o.motion_paths.push_back(entry.path().string());
    }
    std::sort(o.motion_paths.begin(), o.motion_paths.end());
    o.asf_paths.assign(o.motion_paths.size(), "");
    if (o.motion_paths.empty()) {
      return ReportError(absl::NotFoundError(absl::StrCat("no BVH motions in ", motions)), err);
    }
  }
  o.frame_stride = *frame_stride;
  o.shapes_per_body = *shapes;
  const std::string makehuman = data + "/body/makehuman";
  std::string bodies = flags->GetOr("bodies", "");
  std::error_code ec;
  if (bodies.empty()) {
    bodies = fs::exists(makehuman, ec) ? "procedural,makehuman:" + makehuman : "procedural";
  }
  o.bodies = absl::StrSplit(bodies, ',', absl::SkipEmpty());
  const bool quiet = flags->Has("quiet") || flags->Has("json");
  ProgressBar bar(err, !quiet);
  const auto start = std::chrono::steady_clock::now();
  auto made = tracking::SynthesizeTrainingImages(o, o.sequence, bar.AsCallback());
  if (!made.ok()) return ReportError(made.status(), err);
  bar.Finish();
  fs::create_directories(fs::path(*out_dir) / "frames", ec);
  if (ec) {
    return ReportError(
        absl::PermissionDeniedError(absl::StrCat("cannot make ", *out_dir, ": ", ec.message())),
        err);
  }
  nlohmann::json frames = nlohmann::json::array();
  for (size_t i = 0; i < made->size(); ++i) {
    const tracking::TrainingImage& image = (*made)[i];
    // A sequence keeps its whole frames (the person alone, as a segmented
    // recording has them); shuffled images keep the person's crop.
    cv::Mat png;
    CameraIntrinsics k;
    if (o.sequence) {
      k = image.full_intrinsics;
      png = cv::Mat(k.height, k.width, CV_16UC1, cv::Scalar(0));
      for (int y = 0; y < k.height; ++y) {
        for (int x = 0; x < k.width; ++x) {
          if (image.full_mask.at(x, y)) png.at<uint16_t>(y, x) = image.full_depth_mm.at(x, y);
        }
      }
    } else {
      k = image.intrinsics;
      png = cv::Mat(k.height, k.width, CV_16UC1, cv::Scalar(0));
      for (int y = 0; y < k.height; ++y) {
        for (int x = 0; x < k.width; ++x) {
          const float z = image.depth_m.at(x, y);
          if (z > 0 && z < 7.9f) {
            png.at<uint16_t>(y, x) = static_cast<uint16_t>(std::lround(z * 1000.0f));
          }
        }
      }
    }
    char name[32];
    std::snprintf(name, sizeof(name), "frames/%06zu.png", i);
    if (!cv::imwrite((fs::path(*out_dir) / name).string(), png)) {
      return ReportError(absl::DataLossError(absl::StrCat("cannot write ", *out_dir, "/", name)),
                         err);
    }
    nlohmann::json joints = nlohmann::json::object();
    for (int j = 0; j < kJoints; ++j) {
      const Eigen::Vector3d& p = image.joints_in_camera_m[j];
      joints[std::string(body::KinectV2JointName(static_cast<KinectV2Joint>(j)))] = {p.x(), p.y(),
                                                                                     p.z()};
    }
    frames.push_back(
        {{"depth", name}, {"intrinsics", {k.fx, k.fy, k.cx, k.cy}}, {"joints_m", joints}});
  }
  nlohmann::json meta = {
      {"dataset", "reenact tracker synth"},
      {"description",
       absl::StrCat(o.sequence ? "one motion seen by a fixed camera, " : "shuffled crops of ",
                    flags->Has("held-out") ? "held-out motions" : "training motions", ", seed ",
                    o.seed, ", bodies ", bodies, " x ", o.shapes_per_body, " shapes")},
      {"coordinate_frame", "camera frame, OpenCV axes (x right, y down, z forward), metres"},
      {"joint_names", nlohmann::json::array()},
      {"frames", frames}};
  for (int j = 0; j < kJoints; ++j) {
    meta["joint_names"].push_back(body::KinectV2JointName(static_cast<KinectV2Joint>(j)));
  }
  std::ofstream meta_out(fs::path(*out_dir) / "meta.json", std::ios::trunc);
  meta_out << meta.dump(1) << "\n";
  if (!meta_out.flush()) {
    return ReportError(absl::DataLossError(absl::StrCat("cannot write ", *out_dir, "/meta.json")),
                       err);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (flags->Has("json")) {
    out << nlohmann::json{{"out", *out_dir}, {"images", made->size()}, {"seconds", seconds}}.dump(2)
        << "\n";
  } else {
    out << made->size() << " images written to " << *out_dir << " in " << seconds << " s\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
