// `reenact track`: the people the body tracker finds in one depth image, each
// with the 25 Kinect v2 joints in the camera frame.
#include <filesystem>
#include <fstream>
#include <ostream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/tracking/body_tracker.h"

namespace reenact::cli {
namespace {

namespace fs = std::filesystem;

// Largest depth image read (a 4K frame), so that a hostile size field or a
// huge file is refused before anything is allocated for it.
constexpr int kMaxSide = 4096;

absl::StatusOr<std::pair<int, int>> ParseSize(const std::string& text) {
  const std::vector<std::string> parts = absl::StrSplit(text, 'x');
  int w = 0, h = 0;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &w) || !absl::SimpleAtoi(parts[1], &h) ||
      w <= 0 || h <= 0 || w > kMaxSide || h > kMaxSide) {
    return absl::InvalidArgumentError(
        absl::StrCat("--size must be WxH with sides in 1..", kMaxSide, ", got '", text, "'"));
  }
  return std::pair{w, h};
}

// Raw little-endian uint16 millimetres of exactly width * height values.
absl::StatusOr<DepthImageMm> ReadRawDepth(const std::string& path, int width, int height) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) return absl::NotFoundError(absl::StrCat("cannot read ", path, ": ", ec.message()));
  const uintmax_t expected = static_cast<uintmax_t>(width) * height * 2;
  if (size != expected) {
    return absl::InvalidArgumentError(absl::StrCat(path, " holds ", size, " bytes; --size ", width,
                                                   "x", height, " needs ", expected));
  }
  std::ifstream in(path, std::ios::binary);
  std::vector<uint8_t> bytes(expected);
  if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(expected))) {
    return absl::DataLossError(absl::StrCat("short read of ", path));
  }
  DepthImageMm depth(width, height);
  for (size_t i = 0; i < depth.data.size(); ++i) {
    depth.data[i] = static_cast<uint16_t>(bytes[2 * i] | (bytes[2 * i + 1] << 8));
  }
  return depth;
}

// kinect1 | kinect2 (nominal, scaled to the image) | FX,FY,CX,CY.
absl::StatusOr<CameraIntrinsics> ParseIntrinsics(const std::string& text, int width, int height) {
  CameraIntrinsics k;
  if (text == "kinect2") {
    return ScaledIntrinsics(KinectV2DepthIntrinsics(), width, height);
  }
  if (text == "kinect1") {
    // The nominal Kinect v1 depth camera (fx = fy = 525, principal point at
    // the centre of 640x480), as republished with OpenNI's defaults.
    k.width = 640, k.height = 480, k.fx = 525.0, k.fy = 525.0, k.cx = 319.5, k.cy = 239.5;
    return ScaledIntrinsics(k, width, height);
  }
  const std::vector<std::string> parts = absl::StrSplit(text, ',');
  double v[4];
  bool ok = parts.size() == 4;
  for (int i = 0; ok && i < 4; ++i) ok = absl::SimpleAtod(parts[i], &v[i]);
  if (!ok) {
    return absl::InvalidArgumentError(
        absl::StrCat("--intrinsics must be kinect1, kinect2 or FX,FY,CX,CY; got '", text, "'"));
  }
  k.width = width, k.height = height, k.fx = v[0], k.fy = v[1], k.cx = v[2], k.cy = v[3];
  RETURN_IF_ERROR(k.Validate());
  return k;
}

nlohmann::json PersonToJson(const tracking::TrackedPerson& person) {
  nlohmann::json joints = nlohmann::json::object();
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const tracking::TrackedJoint& joint = person.joints[j];
    const Eigen::Vector3d& p = joint.position_in_camera_m;
    joints[std::string(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)))] = {
        {"position_m", {p.x(), p.y(), p.z()}},
        {"pixel", {joint.pixel.x(), joint.pixel.y()}},
        {"confidence", joint.confidence},
        {"state", std::string(tracking::JointStateName(joint.state))}};
  }
  const Eigen::Vector3d& c = person.centroid_in_camera_m;
  return {{"person_id", person.person_id},
          {"pixels", person.num_pixels},
          {"centroid_m", {c.x(), c.y(), c.z()}},
          {"joints", joints}};
}

}  // namespace

absl::StatusOr<DepthImageMm> ReadPngDepth(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return absl::NotFoundError(absl::StrCat("no file ", path));
  const cv::Mat image = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  if (image.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, " is not a readable image (a 16-bit PNG in mm, or raw with --size)"));
  }
  if (image.type() != CV_16UC1) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, " is not a 16-bit single-channel image (depth in millimetres)"));
  }
  if (image.cols > kMaxSide || image.rows > kMaxSide) {
    return absl::InvalidArgumentError(absl::StrCat(path, " is larger than ", kMaxSide, " px"));
  }
  DepthImageMm depth(image.cols, image.rows);
  for (int y = 0; y < image.rows; ++y) {
    const uint16_t* row = image.ptr<uint16_t>(y);
    std::copy(row, row + image.cols, depth.data.begin() + static_cast<size_t>(y) * image.cols);
  }
  return depth;
}

int RunTrack(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"depth", "size", "intrinsics", "model", "forest"},
                            {"json", "refine", "no-refine"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto path = flags->Required("depth");
  if (!path.ok()) return ReportError(path.status(), err);
  auto intrinsics_text = flags->Required("intrinsics");
  if (!intrinsics_text.ok()) return ReportError(intrinsics_text.status(), err);
  absl::StatusOr<DepthImageMm> depth;
  if (const std::optional<std::string> size = flags->Get("size")) {
    auto wh = ParseSize(*size);
    if (!wh.ok()) return ReportError(wh.status(), err);
    depth = ReadRawDepth(*path, wh->first, wh->second);
  } else {
    depth = ReadPngDepth(*path);
  }
  if (!depth.ok()) return ReportError(depth.status(), err);
  auto intrinsics = ParseIntrinsics(*intrinsics_text, depth->width, depth->height);
  if (!intrinsics.ok()) return ReportError(intrinsics.status(), err);

  tracking::BodyTrackerOptions options;
  if (flags->Has("forest")) {
    options.method = tracking::TrackerMethod::kForest;
    options.forest_path = *flags->Get("forest");
  }
  options.model_path = flags->GetOr("model", "");
  // --no-refine is the default now; kept so that older command lines run.
  options.refine = flags->Has("refine") && !flags->Has("no-refine");
  auto tracker = tracking::BodyTracker::Create(options);
  if (!tracker.ok()) return ReportError(tracker.status(), err);
  auto people = (*tracker)->Track(*depth, *intrinsics);
  if (!people.ok()) return ReportError(people.status(), err);

  if (flags->Has("json")) {
    nlohmann::json list = nlohmann::json::array();
    for (const tracking::TrackedPerson& person : *people) list.push_back(PersonToJson(person));
    out << nlohmann::json{{"depth", *path},
                          {"width", depth->width},
                          {"height", depth->height},
                          {"people", list}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  out << people->size() << (people->size() == 1 ? " person" : " people") << " in " << *path << "\n";
  for (const tracking::TrackedPerson& person : *people) {
    int tracked = 0;
    for (const auto& j : person.joints) tracked += j.state == tracking::JointState::kTracked;
    const Eigen::Vector3d& c = person.centroid_in_camera_m;
    out << "person " << person.person_id << ": " << person.num_pixels << " px, centroid (" << c.x()
        << ", " << c.y() << ", " << c.z() << ") m, " << tracked << "/" << body::kNumKinectV2Joints
        << " joints tracked\n";
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      const tracking::TrackedJoint& joint = person.joints[j];
      out << "  " << body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)) << " ("
          << joint.position_in_camera_m.x() << ", " << joint.position_in_camera_m.y() << ", "
          << joint.position_in_camera_m.z() << ") m, px (" << joint.pixel.x() << ", "
          << joint.pixel.y() << "), " << tracking::JointStateName(joint.state) << " "
          << joint.confidence << "\n";
    }
  }
  return kExitOk;
}

}  // namespace reenact::cli
