// RepetitionPlotPng (repetition_report.h): per-part error over time, drawn
// with OpenCV.
#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_format.h"
#include "clients/mirror/repetition_report.h"

namespace reenact::mirror {
namespace {

constexpr int kWidth = 1280;
constexpr int kHeight = 720;
// The plot area inside the image; the legend sits right of it.
const cv::Rect kPlotArea(80, 75, 950, 585);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kGrid(225, 225, 225);

// One colour per part, BGR, told apart by hue and by shade for left/right.
const std::array<cv::Scalar, kNumBodyParts> kPartColors = {{
    {0, 128, 128},    // head: olive
    {230, 160, 60},   // left_shoulder: light blue
    {150, 80, 0},     // right_shoulder: dark blue
    {90, 220, 90},    // left_upper_arm: light green
    {0, 120, 0},      // right_upper_arm: dark green
    {80, 180, 255},   // left_lower_arm: light orange
    {0, 90, 220},     // right_lower_arm: dark orange
    {140, 140, 140},  // torso: grey
    {60, 100, 140},   // abdomen: brown
    {255, 120, 220},  // left_upper_leg: pink
    {160, 0, 160},    // right_upper_leg: magenta
    {220, 220, 0},    // left_lower_leg: cyan
    {130, 130, 0},    // right_lower_leg: teal
}};

struct Axes {
  double max_time_s = 1.0;
  double max_error_deg = 30.0;
  cv::Point ToPixel(double time_s, double error_deg) const {
    const double x = kPlotArea.x + kPlotArea.width * std::clamp(time_s / max_time_s, 0.0, 1.0);
    const double y =
        kPlotArea.y + kPlotArea.height * (1.0 - std::clamp(error_deg / max_error_deg, 0.0, 1.0));
    return {static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y))};
  }
};

// Ranges: time to the last frame, error to a multiple of 15 at or above the
// largest error (at least 30, at most 180).
Axes FitAxes(const RepetitionReport& report) {
  Axes axes;
  double largest_deg = 0.0;
  for (const ComparedFrame& frame : report.frames) {
    axes.max_time_s = std::max(axes.max_time_s, frame.time_s);
    for (const std::optional<double>& e : frame.comparison.part_error_deg) {
      if (e) largest_deg = std::max(largest_deg, *e);
    }
  }
  axes.max_error_deg = std::clamp(std::ceil(largest_deg / 15.0) * 15.0, 30.0, 180.0);
  return axes;
}

// A tick step from 1-2-5 steps giving at most `max_ticks` ticks over `range`.
double TickStep(double range, int max_ticks) {
  for (double decade = 0.1;; decade *= 10.0) {
    for (double factor : {1.0, 2.0, 5.0}) {
      if (range / (factor * decade) <= max_ticks) return factor * decade;
    }
  }
}

void PutText(cv::Mat& image, const std::string& text, cv::Point at, double scale = 0.5) {
  cv::putText(image, text, at, kFont, scale, kInk, 1, cv::LINE_AA);
}

void DrawAxes(cv::Mat& image, const Axes& axes) {
  const double error_step = axes.max_error_deg <= 90.0 ? 15.0 : 30.0;
  for (double e = 0.0; e <= axes.max_error_deg + 1e-9; e += error_step) {
    const cv::Point p = axes.ToPixel(0.0, e);
    cv::line(image, p, {kPlotArea.x + kPlotArea.width, p.y}, kGrid, 1);
    PutText(image, absl::StrFormat("%.0f", e), {p.x - 40, p.y + 5});
  }
  const double time_step = TickStep(axes.max_time_s, 12);
  for (double t = 0.0; t <= axes.max_time_s + 1e-9; t += time_step) {
    const cv::Point p = axes.ToPixel(t, 0.0);
    cv::line(image, p, {p.x, p.y + 6}, kInk, 1);
    // absl::StrFormat checks its format at compile time: one literal per branch.
    const std::string label =
        time_step < 1.0 ? absl::StrFormat("%.1f", t) : absl::StrFormat("%.0f", t);
    PutText(image, label, {p.x - 12, p.y + 24});
  }
  cv::rectangle(image, kPlotArea, kInk, 1);
  PutText(image, "error (deg)", {kPlotArea.x - 70, kPlotArea.y - 16});
  PutText(image, "time (s)", {kPlotArea.x + kPlotArea.width / 2 - 30, kHeight - 12});
}

// One polyline per run of consecutive frames where `value` is present.
template <typename Value>
void DrawSeries(cv::Mat& image, const RepetitionReport& report, const Axes& axes, Value value,
                const cv::Scalar& color, int thickness) {
  std::vector<cv::Point> run;
  auto flush = [&] {
    if (run.size() >= 2) cv::polylines(image, run, false, color, thickness, cv::LINE_AA);
    if (run.size() == 1) cv::circle(image, run[0], thickness + 1, color, cv::FILLED);
    run.clear();
  };
  for (const ComparedFrame& frame : report.frames) {
    const std::optional<double> v = value(frame);
    if (!v) {
      flush();
      continue;
    }
    run.push_back(axes.ToPixel(frame.time_s, *v));
  }
  flush();
}

void DrawLegend(cv::Mat& image, const RepetitionReport& report) {
  const int x = kPlotArea.x + kPlotArea.width + 20;
  PutText(image, "part, mean (deg)", {x, kPlotArea.y - 16});
  int y = kPlotArea.y + 10;
  auto entry = [&](const std::string& label, const cv::Scalar& color, int thickness) {
    cv::line(image, {x, y}, {x + 30, y}, color, thickness, cv::LINE_AA);
    PutText(image, label, {x + 40, y + 5});
    y += 26;
  };
  for (int p = 0; p < kNumBodyParts; ++p) {
    const std::optional<double>& mean = report.part_mean_error_deg[p];
    const std::string value = mean ? absl::StrFormat(" %.1f", *mean) : std::string(" -");
    entry(std::string(BodyPartName(BodyPartAt(p))) + value, kPartColors[p], 2);
  }
  entry("frame mean", kInk, 3);
}

}  // namespace

absl::StatusOr<std::string> RepetitionPlotPng(const RepetitionReport& report) {
  cv::Mat image(kHeight, kWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  const Axes axes = FitAxes(report);
  DrawAxes(image, axes);
  for (int p = 0; p < kNumBodyParts; ++p) {
    DrawSeries(
        image, report, axes, [p](const ComparedFrame& f) { return f.comparison.part_error_deg[p]; },
        kPartColors[p], 2);
  }
  DrawSeries(
      image, report, axes, [](const ComparedFrame& f) { return f.comparison.mean_error_deg; }, kInk,
      3);
  DrawLegend(image, report);
  const std::string mean =
      report.mean_error_deg ? absl::StrFormat("%.1f deg", *report.mean_error_deg) : "-";
  PutText(image,
          absl::StrFormat("repetition %d: mean error %s, view %.0f deg, %s%s", report.repetition,
                          mean, report.view_yaw_deg, report.used_dtw ? "DTW" : "one to one",
                          report.complete ? ""
                                          : absl::StrFormat(" (cut short: %d of %d frames)",
                                                            report.teacher_frames_played,
                                                            report.num_teacher_frames)),
          {kPlotArea.x, 30}, 0.7);
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png)) {
    return absl::InternalError("could not encode the repetition plot as PNG");
  }
  return std::string(png.begin(), png.end());
}

}  // namespace reenact::mirror
