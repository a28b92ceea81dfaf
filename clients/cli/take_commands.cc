// `reenact take info`, `reenact take sheet` and `reenact take frame`: look at a take.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <ostream>
#include <set>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "clients/cli/commands.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/depth_codec.h"
#include "common/io/jpeg.h"
#include "common/io/mask_codec.h"
#include "common/io/proto_convert.h"
#include "common/io/recordings/recording.h"
#include "common/io/take.h"

namespace reenact::cli {
namespace {

nlohmann::json TakeInfoJson(const std::string& path, const TakeReader& take) {
  nlohmann::json j;
  j["file"] = path;
  j["name"] = take.info().name();
  j["generator"] = take.info().generator();
  j["synthetic"] = take.info().synthetic();
  j["motion"] = take.info().motion_source();
  j["body_model"] = take.info().body_model();
  j["fps"] = take.info().fps();
  j["frames"] = take.frame_count();
  j["duration_s"] = take.duration_ns() * 1e-9;
  for (const auto& [id, calibration] : take.sensors()) {
    j["sensors"].push_back(
        {{"id", id},
         {"model", calibration.model()},
         {"depth",
          {calibration.depth_intrinsics().width_px(), calibration.depth_intrinsics().height_px()}},
         {"color",
          {calibration.color_intrinsics().width_px(), calibration.color_intrinsics().height_px()}},
         {"clock_offset_ns", calibration.clock_offset_ns()},
         {"world_anchor", calibration.world_anchor()},
         {"world_anchor_rms_px", calibration.world_anchor_rms_px()}});
  }
  for (const TakeChannel& c : take.channels()) {
    j["channels"].push_back(
        {{"topic", c.topic}, {"type", c.message_type}, {"messages", c.message_count}});
  }
  const McapReadReport& report = take.report();
  j["read"] = {{"indexed", report.indexed}, {"complete", report.complete}};
  if (!report.complete) {
    j["read"]["stop_offset"] = report.stop_offset;
    j["read"]["stop_reason"] = report.stop_reason;
    j["read"]["summary_problem"] = report.summary_problem;
    j["read"]["skipped_chunks"] = report.skipped_chunks;
  }
  return j;
}

void PrintTakeInfo(const nlohmann::json& j, std::ostream& out) {
  out << j["file"].get<std::string>() << "\n"
      << "  name       " << j["name"].get<std::string>()
      << (j["synthetic"].get<bool>() ? " (synthetic)" : "") << "\n  motion     "
      << j["motion"].get<std::string>() << "\n  body       " << j["body_model"].get<std::string>()
      << "\n  frames     " << j["frames"] << " at " << j["fps"] << " fps, " << j["duration_s"]
      << " s\n";
  for (const auto& s : j.value("sensors", nlohmann::json::array())) {
    out << "  sensor     " << s["id"].get<std::string>() << " " << s["model"].get<std::string>()
        << " depth " << s["depth"][0] << "x" << s["depth"][1] << " colour " << s["color"][0] << "x"
        << s["color"][1];
    const std::string anchor = s.value("world_anchor", "");
    if (!anchor.empty())
      out << " world " << anchor << " (RMS " << s["world_anchor_rms_px"] << " px)";
    out << "\n";
  }
  for (const auto& c : j.value("channels", nlohmann::json::array())) {
    out << "  channel    " << c["topic"].get<std::string>() << "  " << c["messages"] << " x "
        << c["type"].get<std::string>() << "\n";
  }
  if (!j["read"]["complete"].get<bool>()) {
    out << "  DAMAGED    read up to byte " << j["read"]["stop_offset"] << ": "
        << j["read"]["stop_reason"].get<std::string>() << "\n";
  }
}

// ------------------------------------------------------------ contact sheet

constexpr int kCellHeight = 270;

struct SheetFrame {
  cv::Mat color, depth_mm, mask;
  v1::Skeleton skeleton;
  bool has_skeleton = false;
};

cv::Mat FitHeight(const cv::Mat& image, int height, int interpolation) {
  cv::Mat out;
  const double scale = static_cast<double>(height) / image.rows;
  cv::resize(image, out, cv::Size(static_cast<int>(std::lround(image.cols * scale)), height), 0, 0,
             interpolation);
  return out;
}

cv::Mat DepthColormap(const cv::Mat& depth_mm) {
  cv::Mat scaled, colored;
  depth_mm.convertTo(scaled, CV_8U, 255.0 / 4500.0);
  cv::applyColorMap(scaled, colored, cv::COLORMAP_TURBO);
  colored.setTo(cv::Scalar(0, 0, 0), depth_mm == 0);
  return colored;
}

// Draws the skeleton (depth camera frame) over the colour thumbnail.
void DrawSkeleton(cv::Mat* color, double scale, const v1::Skeleton& skeleton,
                  const v1::SensorCalibration& calibration) {
  auto intrinsics = FromProto(calibration.color_intrinsics());
  auto color_from_depth = FromProto(calibration.color_from_depth());
  if (!intrinsics.ok() || !color_from_depth.ok()) return;
  std::map<std::string, std::pair<cv::Point, int>> pixels;
  for (const auto& joint : skeleton.joints()) {
    const Eigen::Vector3d p = *color_from_depth * FromProto(joint.position_in_depth_m());
    auto pixel = intrinsics->Project(p);
    if (!pixel) continue;
    pixels[joint.name()] = {
        cv::Point(static_cast<int>(pixel->x() * scale), static_cast<int>(pixel->y() * scale)),
        joint.tracking_state()};
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const auto joint = static_cast<body::KinectV2Joint>(j);
    const auto parent = body::KinectV2Parent(joint);
    if (!parent) continue;
    auto a = pixels.find(std::string(body::KinectV2JointName(joint)));
    auto b = pixels.find(std::string(body::KinectV2JointName(*parent)));
    if (a == pixels.end() || b == pixels.end()) continue;
    cv::line(*color, a->second.first, b->second.first, cv::Scalar(255, 255, 255), 2, cv::LINE_AA);
  }
  for (const auto& [name, p] : pixels) {
    const cv::Scalar colour =
        p.second == v1::TRACKING_STATE_TRACKED ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 220, 255);
    cv::circle(*color, p.first, 4, colour, -1, cv::LINE_AA);
  }
}

template <typename Message>
absl::Status CollectFrames(const TakeReader& take, const std::string& topic,
                           const std::set<int64_t>& wanted, std::map<int64_t, Message>* found) {
  return take.ForEach<Message>(topic, [&](const Message& m) {
    if (wanted.count(m.frame_index())) (*found)[m.frame_index()] = m;
    return absl::OkStatus();
  });
}

absl::StatusOr<std::map<int64_t, SheetFrame>> LoadSheetFrames(const TakeReader& take,
                                                              const std::string& id,
                                                              const std::set<int64_t>& wanted) {
  std::map<int64_t, v1::ColorImage> colors;
  std::map<int64_t, v1::DepthImage> depths;
  std::map<int64_t, v1::ActorMask> masks;
  std::map<int64_t, v1::Skeleton> skeletons;
  RETURN_IF_ERROR(CollectFrames(take, SensorTopic(id, "color"), wanted, &colors));
  RETURN_IF_ERROR(CollectFrames(take, SensorTopic(id, "depth"), wanted, &depths));
  RETURN_IF_ERROR(CollectFrames(take, SensorTopic(id, "mask"), wanted, &masks));
  RETURN_IF_ERROR(CollectFrames(take, SensorTopic(id, "skeleton"), wanted, &skeletons));
  std::map<int64_t, SheetFrame> frames;
  for (int64_t f : wanted) {
    SheetFrame& frame = frames[f];
    if (auto it = colors.find(f); it != colors.end()) {
      ASSIGN_OR_RETURN(RgbImage rgb, DecodeJpeg(it->second.data()));
      cv::Mat view(rgb.height, rgb.width, CV_8UC3, rgb.data.data());
      cv::cvtColor(view, frame.color, cv::COLOR_RGB2BGR);
    }
    if (auto it = depths.find(f); it != depths.end()) {
      ASSIGN_OR_RETURN(DepthImageMm depth, DecodeDepth(it->second.data()));
      frame.depth_mm = cv::Mat(depth.height, depth.width, CV_16UC1, depth.data.data()).clone();
    }
    if (auto it = masks.find(f); it != masks.end()) {
      ASSIGN_OR_RETURN(MaskImage mask, DecodeMaskRle(it->second.data()));
      frame.mask = cv::Mat(mask.height, mask.width, CV_8UC1, mask.data.data()).clone();
    }
    if (auto it = skeletons.find(f); it != skeletons.end()) {
      frame.skeleton = it->second;
      frame.has_skeleton = true;
    }
  }
  return frames;
}

// One row of the sheet: colour with the skeleton, depth, mask.
cv::Mat SheetRow(const SheetFrame& frame, const v1::SensorCalibration& calibration,
                 const std::string& label) {
  std::vector<cv::Mat> cells;
  if (!frame.color.empty()) {
    cv::Mat color = FitHeight(frame.color, kCellHeight, cv::INTER_AREA);
    if (frame.has_skeleton) {
      DrawSkeleton(&color, static_cast<double>(kCellHeight) / frame.color.rows, frame.skeleton,
                   calibration);
    }
    cells.push_back(color);
  }
  if (!frame.depth_mm.empty())
    cells.push_back(FitHeight(DepthColormap(frame.depth_mm), kCellHeight, cv::INTER_NEAREST));
  if (!frame.mask.empty()) {
    cv::Mat mask_bgr;
    cv::cvtColor(frame.mask * 255, mask_bgr, cv::COLOR_GRAY2BGR);
    cells.push_back(FitHeight(mask_bgr, kCellHeight, cv::INTER_NEAREST));
  }
  if (cells.empty()) cells.push_back(cv::Mat(kCellHeight, 400, CV_8UC3, cv::Scalar(40, 40, 40)));
  cv::Mat row;
  cv::hconcat(cells, row);
  cv::putText(row, label, cv::Point(8, 24), cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 0), 4);
  cv::putText(row, label, cv::Point(8, 24), cv::FONT_HERSHEY_SIMPLEX, 0.7,
              cv::Scalar(255, 255, 255), 2);
  return row;
}

absl::Status WriteSheet(const TakeReader& take, int num_frames, const std::string& out_path) {
  const int64_t total = take.frame_count();
  if (total <= 0) return absl::FailedPreconditionError("take has no frames to show");
  std::set<int64_t> wanted;
  for (int i = 0; i < num_frames; ++i) {
    wanted.insert(num_frames == 1 ? 0 : (total - 1) * i / (num_frames - 1));
  }
  std::vector<cv::Mat> rows;
  int width = 0;
  for (const auto& [id, calibration] : take.sensors()) {
    ASSIGN_OR_RETURN(auto frames, LoadSheetFrames(take, id, wanted));
    for (const auto& [f, frame] : frames) {
      const double t = take.info().fps() > 0 ? f / take.info().fps() : 0.0;
      char label[96];
      std::snprintf(label, sizeof(label), "%s  frame %lld  t=%.2fs", id.c_str(),
                    static_cast<long long>(f), t);
      rows.push_back(SheetRow(frame, calibration, label));
      width = std::max(width, rows.back().cols);
    }
  }
  for (cv::Mat& row : rows) {
    if (row.cols < width)
      cv::copyMakeBorder(row, row, 0, 0, 0, width - row.cols, cv::BORDER_CONSTANT);
  }
  cv::Mat sheet;
  cv::vconcat(rows, sheet);
  if (!cv::imwrite(out_path, sheet)) {
    return absl::PermissionDeniedError(absl::StrCat(out_path, ": cannot write the image"));
  }
  return absl::OkStatus();
}

}  // namespace

int RunTakeInfo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (flags->positional().size() != 1) {
    return ReportError(absl::InvalidArgumentError("take info needs exactly one FILE"), err);
  }
  const std::string& path = flags->positional()[0];
  auto take = TakeReader::Open(path);
  if (!take.ok()) {
    ReportError(take.status(), err);  // Not a usage error: the file is unreadable.
    return kExitFailure;
  }
  const nlohmann::json j = TakeInfoJson(path, **take);
  if (flags->Has("json")) {
    out << j.dump(2) << "\n";
  } else {
    PrintTakeInfo(j, out);
  }
  if (!(*take)->report().complete) {
    err << "reenact: " << path << " is damaged; showing every complete chunk (stopped at byte "
        << (*take)->report().stop_offset << ": " << (*take)->report().stop_reason << ")\n";
  }
  return kExitOk;
}

int RunTakeSheet(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"out", "frames"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto out_path = flags->Required("out");
  auto frames = flags->GetInt("frames", 4);
  if (!out_path.ok()) return ReportError(out_path.status(), err);
  if (!frames.ok()) return ReportError(frames.status(), err);
  if (flags->positional().size() != 1 || *frames < 1 || *frames > 32) {
    return ReportError(absl::InvalidArgumentError("take sheet needs one FILE and 1..32 --frames"),
                       err);
  }
  auto take = TakeReader::Open(flags->positional()[0]);
  if (!take.ok()) {
    ReportError(take.status(), err);
    return kExitFailure;
  }
  if (auto status = WriteSheet(**take, *frames, *out_path); !status.ok())
    return ReportError(status, err);
  out << "wrote " << *out_path << "\n";
  return kExitOk;
}

}  // namespace reenact::cli

namespace reenact::cli {
namespace {

nlohmann::json IntrinsicsJson(const v1::CameraIntrinsics& k) {
  return {{"width", k.width_px()}, {"height", k.height_px()},
          {"fx", k.fx_px()},       {"fy", k.fy_px()},
          {"cx", k.cx_px()},       {"cy", k.cy_px()},
          {"k1", k.k1()},          {"k2", k.k2()},
          {"k3", k.k3()},          {"p1", k.p1()},
          {"p2", k.p2()}};
}

// The message of `topic` with frame_index `index`; nullopt when none.
template <typename Message>
absl::StatusOr<std::optional<Message>> FindFrame(const TakeReader& take, const std::string& topic,
                                                 int64_t index) {
  std::optional<Message> found;
  RETURN_IF_ERROR(take.ForEach<Message>(topic, [&](const Message& m) {
    if (!found && m.frame_index() == index) found = m;
    return absl::OkStatus();
  }));
  return found;
}

}  // namespace

int RunTakeFrame(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"sensor", "index", "depth-png", "color"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  auto index = flags->GetInt("index", -1);
  if (!index.ok()) return ReportError(index.status(), err);
  if (flags->positional().size() != 1 || *index < 0) {
    return ReportError(
        absl::InvalidArgumentError("take frame needs one TAKE.mcap and --index N (N >= 0)"), err);
  }
  const std::string& path = flags->positional()[0];
  auto take = TakeReader::Open(path);
  if (!take.ok()) {
    ReportError(take.status(), err);
    return kExitFailure;
  }
  std::string sensor_id = flags->GetOr("sensor", "");
  if (sensor_id.empty()) {
    if ((*take)->sensors().size() != 1) {
      return ReportError(
          absl::InvalidArgumentError(absl::StrCat(path, " has ", (*take)->sensors().size(),
                                                  " sensors; name one with --sensor ID")),
          err);
    }
    sensor_id = (*take)->sensors().begin()->first;
  }
  const auto calibration = (*take)->sensors().find(sensor_id);
  if (calibration == (*take)->sensors().end()) {
    std::string ids;
    for (const auto& [id, c] : (*take)->sensors())
      absl::StrAppend(&ids, ids.empty() ? "" : ", ", id);
    err << "reenact: " << path << " has no sensor \"" << sensor_id << "\" (it has: " << ids
        << ")\n";
    return kExitFailure;
  }
  auto depth = FindFrame<v1::DepthImage>(**take, SensorTopic(sensor_id, "depth"), *index);
  auto color = FindFrame<v1::ColorImage>(**take, SensorTopic(sensor_id, "color"), *index);
  for (const absl::Status& s : {depth.status(), color.status()}) {
    if (!s.ok()) {
      ReportError(s, err);
      return kExitFailure;
    }
  }
  if (!*depth && !*color) {
    err << "reenact: sensor " << sensor_id << " of " << path << " has no frame " << *index << "\n";
    return kExitFailure;
  }
  nlohmann::json j;
  j["file"] = path;
  j["sensor"] = sensor_id;
  j["index"] = *index;
  const v1::SensorCalibration& c = calibration->second;
  j["calibration"] = {
      {"model", c.model()},
      {"serial", c.serial()},
      {"depth_intrinsics", IntrinsicsJson(c.depth_intrinsics())},
      {"color_intrinsics", IntrinsicsJson(c.color_intrinsics())},
      {"color_from_depth",
       {{"rotation_wxyz",
         {c.color_from_depth().rotation().w(), c.color_from_depth().rotation().x(),
          c.color_from_depth().rotation().y(), c.color_from_depth().rotation().z()}},
        {"translation_m",
         {c.color_from_depth().translation_m().x(), c.color_from_depth().translation_m().y(),
          c.color_from_depth().translation_m().z()}}}},
      {"depth_scale_m_per_unit", c.depth_scale_m_per_unit()},
      {"clock_offset_ns", c.clock_offset_ns()},
      {"nominal_fps", c.nominal_fps()}};
  if (*depth) {
    const v1::DepthImage& d = **depth;
    absl::StatusOr<DepthImageMm> mm = DecodeDepth(d.data());
    if (!mm.ok()) {
      err << "reenact: depth frame " << *index << " of " << sensor_id << ": "
          << mm.status().message() << "\n";
      return kExitFailure;
    }
    uint16_t lo = 0, hi = 0;
    int64_t valid = 0;
    for (uint16_t v : mm->data) {
      if (v == 0) continue;
      lo = valid == 0 ? v : std::min(lo, v);
      hi = std::max(hi, v);
      ++valid;
    }
    j["depth"] = {{"device_stamp_ns", d.device_stamp_ns()},
                  {"host_stamp_ns", d.host_stamp_ns()},
                  {"width", d.width_px()},
                  {"height", d.height_px()},
                  {"encoding", d.encoding()},
                  {"valid_pixels", valid},
                  {"min_mm", lo},
                  {"max_mm", hi}};
    if (auto png_path = flags->Get("depth-png")) {
      absl::StatusOr<std::string> png = recordings::EncodePng16(*mm);
      absl::Status written = png.ok() ? WriteFileAtomically(*png_path, *png) : png.status();
      if (!written.ok()) {
        err << "reenact: " << *png_path << ": " << written.message() << "\n";
        return kExitFailure;
      }
      j["depth"]["png"] = *png_path;
    }
  } else if (flags->Has("depth-png")) {
    err << "reenact: frame " << *index << " of " << sensor_id << " has no depth\n";
    return kExitFailure;
  }
  if (*color) {
    const v1::ColorImage& col = **color;
    j["color"] = {{"device_stamp_ns", col.device_stamp_ns()},
                  {"host_stamp_ns", col.host_stamp_ns()},
                  {"width", col.width_px()},
                  {"height", col.height_px()},
                  {"encoding", col.encoding()},
                  {"quality", col.quality()},
                  {"bytes", col.data().size()}};
    if (auto color_path = flags->Get("color")) {
      if (absl::Status written = WriteFileAtomically(*color_path, col.data()); !written.ok()) {
        err << "reenact: " << *color_path << ": " << written.message() << "\n";
        return kExitFailure;
      }
      j["color"]["file"] = *color_path;
    }
  } else if (flags->Has("color")) {
    err << "reenact: frame " << *index << " of " << sensor_id << " has no colour\n";
    return kExitFailure;
  }
  if (flags->Has("json")) {
    out << j.dump(2) << "\n";
    return kExitOk;
  }
  out << path << " sensor " << sensor_id << " frame " << *index << "\n";
  if (j.contains("depth")) {
    out << "  depth      " << j["depth"]["width"] << "x" << j["depth"]["height"] << " "
        << j["depth"]["encoding"].get<std::string>() << ", device stamp "
        << j["depth"]["device_stamp_ns"] << " ns, host stamp " << j["depth"]["host_stamp_ns"]
        << " ns, " << j["depth"]["valid_pixels"] << " valid pixels, " << j["depth"]["min_mm"]
        << ".." << j["depth"]["max_mm"] << " mm\n";
  }
  if (j.contains("color")) {
    out << "  colour     " << j["color"]["width"] << "x" << j["color"]["height"] << " "
        << j["color"]["encoding"].get<std::string>() << ", " << j["color"]["bytes"]
        << " bytes, device stamp " << j["color"]["device_stamp_ns"] << " ns\n";
  }
  const auto& dk = c.depth_intrinsics();
  const auto& ck = c.color_intrinsics();
  out << "  depth K    " << dk.width_px() << "x" << dk.height_px() << " fx " << dk.fx_px() << " fy "
      << dk.fy_px() << " cx " << dk.cx_px() << " cy " << dk.cy_px() << " k " << dk.k1() << " "
      << dk.k2() << " " << dk.k3() << " p " << dk.p1() << " " << dk.p2() << "\n"
      << "  colour K   " << ck.width_px() << "x" << ck.height_px() << " fx " << ck.fx_px() << " fy "
      << ck.fy_px() << " cx " << ck.cx_px() << " cy " << ck.cy_px() << " k " << ck.k1() << " "
      << ck.k2() << " " << ck.k3() << " p " << ck.p1() << " " << ck.p2() << "\n"
      << "  colour<-depth t " << j["calibration"]["color_from_depth"]["translation_m"].dump()
      << " m, q " << j["calibration"]["color_from_depth"]["rotation_wxyz"].dump() << "\n";
  if (j.contains("depth") && j["depth"].contains("png"))
    out << "  wrote " << j["depth"]["png"].get<std::string>() << "\n";
  if (j.contains("color") && j["color"].contains("file")) {
    out << "  wrote " << j["color"]["file"].get<std::string>() << "\n";
  }
  return kExitOk;
}

}  // namespace reenact::cli
