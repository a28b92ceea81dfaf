// GradeHeatMapPng and WorstMomentsPng (grading.h), drawn with OpenCV.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_format.h"
#include "clients/mirror/grading.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kPaper(255, 255, 255);
const cv::Scalar kNeutral(200, 200, 200);

cv::Scalar Bgr(const Srgb8& c) { return {double(c.b), double(c.g), double(c.r)}; }

absl::StatusOr<std::string> EncodePng(const cv::Mat& image) {
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png)) return absl::InternalError("PNG encoding failed");
  return std::string(png.begin(), png.end());
}

// Bones drawn for a figure: the 13 parts and the joints beyond them.
std::vector<std::pair<KinectV2Joint, KinectV2Joint>> FigureBones() {
  std::vector<std::pair<KinectV2Joint, KinectV2Joint>> bones;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartBone b = BodyPartBone(BodyPartAt(p));
    bones.emplace_back(b.from, b.to);
  }
  bones.insert(bones.end(), {{KinectV2Joint::kSpineShoulder, KinectV2Joint::kNeck},
                             {KinectV2Joint::kSpineBase, KinectV2Joint::kHipLeft},
                             {KinectV2Joint::kSpineBase, KinectV2Joint::kHipRight},
                             {KinectV2Joint::kWristLeft, KinectV2Joint::kHandLeft},
                             {KinectV2Joint::kWristRight, KinectV2Joint::kHandRight},
                             {KinectV2Joint::kAnkleLeft, KinectV2Joint::kFootLeft},
                             {KinectV2Joint::kAnkleRight, KinectV2Joint::kFootRight}});
  return bones;
}

// Draws `pose` seen from the front of its own spine frame into `panel`:
// the person's left on the image's right, up up, scaled so the spine
// (SpineBase to SpineShoulder) is a fifth of the panel's height. The part
// `outlined` is drawn thick in `outline`, others grey; joints the sensor did
// not see are hollow.
void DrawFigure(cv::Mat panel, const GradeFrame& frame, BodyPart outlined,
                const cv::Scalar& outline) {
  if (!frame.pose) {
    cv::putText(panel, "no skeleton", {10, panel.rows / 2}, kFont, 0.5, kInk, 1, cv::LINE_AA);
    return;
  }
  const body::SkeletonPose& pose = *frame.pose;
  const std::optional<Eigen::Matrix3d> frame_from_spine = SpineFrame(pose);
  if (!frame_from_spine) {
    cv::putText(panel, "no spine", {10, panel.rows / 2}, kFont, 0.5, kInk, 1, cv::LINE_AA);
    return;
  }
  const Eigen::Vector3d origin = pose.position_m[body::Index(KinectV2Joint::kSpineBase)];
  const double spine =
      (pose.position_m[body::Index(KinectV2Joint::kSpineShoulder)] - origin).norm();
  const double scale = panel.rows / 5.0 / std::max(spine, 0.05);
  const auto to_pixel = [&](KinectV2Joint j) {
    const Eigen::Vector3d s =
        frame_from_spine->transpose() * (pose.position_m[body::Index(j)] - origin);
    return cv::Point(static_cast<int>(std::lround(panel.cols / 2.0 + scale * s.x())),
                     static_cast<int>(std::lround(panel.rows * 0.55 - scale * s.y())));
  };
  const PartBone marked = BodyPartBone(outlined);
  for (const auto& [a, b] : FigureBones()) {
    if (!IsJointUsable(pose, a) || !IsJointUsable(pose, b)) continue;
    const bool is_marked = a == marked.from && b == marked.to;
    if (is_marked) cv::line(panel, to_pixel(a), to_pixel(b), outline, 9, cv::LINE_AA);
    cv::line(panel, to_pixel(a), to_pixel(b), is_marked ? kInk : cv::Scalar(110, 110, 110),
             is_marked ? 3 : 2, cv::LINE_AA);
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const auto joint = static_cast<KinectV2Joint>(j);
    if (!IsJointUsable(pose, joint)) continue;
    cv::circle(panel, to_pixel(joint), 3, kInk, frame.seen[j] ? cv::FILLED : 1, cv::LINE_AA);
  }
}

}  // namespace

absl::StatusOr<std::string> GradeHeatMapPng(const Grade& grade, const ErrorColorOptions& colors) {
  constexpr int kLeft = 150, kTop = 60, kRow = 26, kPlotWidth = 900, kRight = 110;
  const int height = kTop + kRow * kNumBodyParts + 90;
  cv::Mat image(height, kLeft + kPlotWidth + kRight, CV_8UC3, kPaper);
  const int n = static_cast<int>(grade.pairs.size());
  cv::putText(image,
              grade.mean_error_deg
                  ? absl::StrFormat("mean error %.1f deg over %.0f%% of the body-time",
                                    *grade.mean_error_deg, 100.0 * grade.coverage)
                  : std::string("nothing could be graded"),
              {kLeft, 30}, kFont, 0.65, kInk, 1, cv::LINE_AA);
  for (int p = 0; p < kNumBodyParts; ++p) {
    const int y0 = kTop + p * kRow;
    cv::putText(image, PartWords(BodyPartAt(p)), {8, y0 + kRow - 8}, kFont, 0.45, kInk, 1,
                cv::LINE_AA);
    const PartGrade& part = grade.parts[p];
    cv::putText(image,
                part.graded ? absl::StrFormat("%3.0f%% seen", 100.0 * part.coverage)
                            : std::string("not graded"),
                {kLeft + kPlotWidth + 8, y0 + kRow - 8}, kFont, 0.42, kInk, 1, cv::LINE_AA);
    for (int i = 0; i < n; ++i) {
      const int x0 = kLeft + i * kPlotWidth / n;
      const int x1 = std::max(x0 + 1, kLeft + (i + 1) * kPlotWidth / n);
      const cv::Rect cell(x0, y0 + 1, x1 - x0, kRow - 2);
      const GradedPair& pair = grade.pairs[i];
      if (part.graded && pair.error_deg[p] && pair.smoothed_deg[p]) {
        cv::rectangle(image, cell, Bgr(ErrorToSrgb(*pair.smoothed_deg[p], colors)), cv::FILLED);
      } else {
        cv::rectangle(image, cell, kNeutral, cv::FILLED);
      }
    }
    // Hatching over the neutral cells.
    for (int x = kLeft - kRow; x < kLeft + kPlotWidth; x += 8) {
      const cv::Point a(x, y0 + kRow - 1), b(x + kRow - 2, y0 + 1);
      const int col = std::clamp((x + kRow / 2 - kLeft) * n / kPlotWidth, 0, std::max(0, n - 1));
      if (n > 0 && part.graded && grade.pairs[col].error_deg[p]) continue;
      cv::LineIterator it(image, a, b);
      for (int k = 0; k < it.count; ++k, ++it) {
        const cv::Point q = it.pos();
        if (q.x >= kLeft && q.x < kLeft + kPlotWidth)
          image.at<cv::Vec3b>(q) = cv::Vec3b(150, 150, 150);
      }
    }
  }
  // Time axis: a tick per second (or per 5 or 10 on long takes).
  const double t0 = n ? grade.pairs.front().time_s : 0.0;
  const double t1 = n ? grade.pairs.back().time_s : 1.0;
  const double span = std::max(t1 - t0, 1e-3);
  const double step = span > 60 ? 10.0 : span > 15 ? 5.0 : 1.0;
  const int axis_y = kTop + kRow * kNumBodyParts + 4;
  cv::line(image, {kLeft, axis_y}, {kLeft + kPlotWidth, axis_y}, kInk, 1);
  for (double t = std::ceil(t0 / step) * step; t <= t1 + 1e-9; t += step) {
    const int x = kLeft + static_cast<int>(std::lround((t - t0) / span * (kPlotWidth - 1)));
    cv::line(image, {x, axis_y}, {x, axis_y + 6}, kInk, 1);
    cv::putText(image, absl::StrFormat("%g", t), {x - 8, axis_y + 22}, kFont, 0.42, kInk, 1,
                cv::LINE_AA);
  }
  cv::putText(image, "time (s)", {kLeft + kPlotWidth / 2 - 30, axis_y + 44}, kFont, 0.45, kInk, 1,
              cv::LINE_AA);
  // Legend: the colour map and the neutral "not graded".
  const int ly = axis_y + 58;
  for (int k = 0; k < 200; ++k) {
    const double deg = k * (colors.red_deg * 1.2) / 200.0;
    cv::line(image, {kLeft + k, ly}, {kLeft + k, ly + 14}, Bgr(ErrorToSrgb(deg, colors)), 1);
  }
  cv::putText(image, absl::StrFormat("0 .. %.0f+ deg", colors.red_deg * 1.2),
              {kLeft + 210, ly + 12}, kFont, 0.42, kInk, 1, cv::LINE_AA);
  cv::rectangle(image, cv::Rect(kLeft + 360, ly, 40, 14), kNeutral, cv::FILLED);
  cv::putText(image, "not seen: not graded", {kLeft + 410, ly + 12}, kFont, 0.42, kInk, 1,
              cv::LINE_AA);
  return EncodePng(image);
}

absl::StatusOr<std::string> WorstMomentsPng(const Grade& grade,
                                            const std::vector<GradeFrame>& teacher,
                                            const std::vector<GradeFrame>& learner) {
  constexpr int kPanelW = 220, kPanelH = 280, kCaption = 50;
  const int moments = std::max<int>(1, static_cast<int>(grade.worst_moments.size()));
  cv::Mat image(moments * (kPanelH + kCaption), 2 * kPanelW + 10, CV_8UC3, kPaper);
  if (grade.worst_moments.empty()) {
    cv::putText(image, "no graded moment", {10, 40}, kFont, 0.6, kInk, 1, cv::LINE_AA);
    return EncodePng(image);
  }
  const cv::Scalar outline = Bgr(ErrorToSrgb(90.0));
  for (int m = 0; m < static_cast<int>(grade.worst_moments.size()); ++m) {
    const WorstMoment& wm = grade.worst_moments[m];
    const int y0 = m * (kPanelH + kCaption);
    cv::putText(
        image,
        absl::StrFormat("%.1f s: %s %.0f deg off", wm.time_s, PartWords(wm.part), wm.error_deg),
        {8, y0 + 22}, kFont, 0.55, kInk, 1, cv::LINE_AA);
    cv::putText(image, "you", {8, y0 + 44}, kFont, 0.45, kInk, 1, cv::LINE_AA);
    cv::putText(image, "teacher", {kPanelW + 18, y0 + 44}, kFont, 0.45, kInk, 1, cv::LINE_AA);
    cv::Mat left = image(cv::Rect(0, y0 + kCaption, kPanelW, kPanelH));
    cv::Mat right = image(cv::Rect(kPanelW + 10, y0 + kCaption, kPanelW, kPanelH));
    cv::rectangle(left, cv::Rect(0, 0, kPanelW, kPanelH), kNeutral, 1);
    cv::rectangle(right, cv::Rect(0, 0, kPanelW, kPanelH), kNeutral, 1);
    if (wm.learner_frame >= 0 && wm.learner_frame < static_cast<int>(learner.size())) {
      DrawFigure(left, learner[wm.learner_frame], wm.part, outline);
    }
    if (wm.teacher_frame >= 0 && wm.teacher_frame < static_cast<int>(teacher.size())) {
      DrawFigure(right, teacher[wm.teacher_frame], wm.part, Bgr(ErrorToSrgb(0.0)));
    }
  }
  return EncodePng(image);
}

}  // namespace reenact::mirror
