#include "clients/viewer/playback.h"

#include <algorithm>
#include <cmath>

namespace reenact::viewer {

Playback::Playback(int frame_count, double fps)
    : frame_count_(std::max(frame_count, 1)), fps_(fps > 0 && std::isfinite(fps) ? fps : 30.0) {}

void Playback::Advance(double wall_seconds) {
  if (!playing_ || !(wall_seconds > 0) || !std::isfinite(wall_seconds)) return;
  const double last = frame_count_ - 1;
  position_ += wall_seconds * fps_ * speed_;
  if (position_ <= last + 0.5) return;
  if (loop_ && frame_count_ > 1) {
    position_ = std::fmod(position_, static_cast<double>(frame_count_));
  } else {
    position_ = last;
    playing_ = false;
  }
}

void Playback::SetSpeed(double speed) {
  if (std::isfinite(speed)) speed_ = std::clamp(speed, 0.05, 8.0);
}

void Playback::Scrub(double fraction) {
  if (!std::isfinite(fraction)) return;
  position_ = std::clamp(fraction, 0.0, 1.0) * (frame_count_ - 1);
}

void Playback::Step(int instants) {
  playing_ = false;
  position_ = std::clamp(std::round(position_) + instants, 0.0, frame_count_ - 1.0);
}

int Playback::frame() const {
  return std::clamp(static_cast<int>(std::lround(position_)), 0, frame_count_ - 1);
}

double Playback::fraction() const {
  return frame_count_ > 1 ? position_ / (frame_count_ - 1) : 0.0;
}

}  // namespace reenact::viewer
