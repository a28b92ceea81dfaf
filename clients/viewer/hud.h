// Overlays the viewer and the mirror draw on their images: a timeline bar
// with the play head, and lines of status text.
#pragma once

#include <string>

#include <Eigen/Core>

#include "common/base/image.h"

namespace reenact::viewer {

// Height of the timeline strip at the bottom of the image, pixels.
inline constexpr int kTimelineHeightPx = 18;

// Draws the timeline at the bottom of `image`: the played part up to
// `fraction` (0..1) and the play head.
void DrawTimeline(double fraction, RgbImage* image);

// The fraction of the timeline under image x, when image y is on the
// timeline strip; negative otherwise.
double TimelineFractionAt(double x_px, double y_px, int width, int height);

// Writes `text` at the top-left (line `line`, 0 = first) with a dark outline
// so it reads on any background. Colour sRGB in [0,1].
void DrawStatusLine(const std::string& text, int line, RgbImage* image,
                    const Eigen::Vector3f& colour_srgb = Eigen::Vector3f(1, 1, 1));

}  // namespace reenact::viewer
