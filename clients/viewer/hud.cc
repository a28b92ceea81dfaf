#include "clients/viewer/hud.h"

#include <algorithm>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace reenact::viewer {
namespace {

cv::Mat Wrap(RgbImage* image) {
  return cv::Mat(image->height, image->width, CV_8UC3, image->data.data());
}

}  // namespace

void DrawTimeline(double fraction, RgbImage* image) {
  if (image->empty() || image->height < 3 * kTimelineHeightPx) return;
  cv::Mat mat = Wrap(image);
  const int top = image->height - kTimelineHeightPx;
  const int head = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * (image->width - 1));
  cv::rectangle(mat, cv::Rect(0, top, image->width, kTimelineHeightPx), cv::Scalar(40, 40, 48),
                cv::FILLED);
  cv::rectangle(mat, cv::Rect(0, top + 6, head + 1, kTimelineHeightPx - 12),
                cv::Scalar(90, 160, 255), cv::FILLED);
  cv::rectangle(mat, cv::Rect(std::max(head - 2, 0), top + 1, 5, kTimelineHeightPx - 2),
                cv::Scalar(255, 255, 255), cv::FILLED);
}

double TimelineFractionAt(double x_px, double y_px, int width, int height) {
  if (width <= 1 || y_px < height - kTimelineHeightPx || y_px >= height || x_px < 0 ||
      x_px >= width) {
    return -1.0;
  }
  return x_px / (width - 1);
}

void DrawStatusLine(const std::string& text, int line, RgbImage* image,
                    const Eigen::Vector3f& colour_srgb) {
  if (image->empty()) return;
  cv::Mat mat = Wrap(image);
  const cv::Point origin(10, 24 + 24 * line);
  cv::putText(mat, text, origin, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 4,
              cv::LINE_AA);
  const cv::Scalar colour(255 * colour_srgb.x(), 255 * colour_srgb.y(), 255 * colour_srgb.z());
  cv::putText(mat, text, origin, cv::FONT_HERSHEY_SIMPLEX, 0.6, colour, 1, cv::LINE_AA);
}

}  // namespace reenact::viewer
