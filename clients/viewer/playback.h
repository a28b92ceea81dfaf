// The viewer's playback clock: play/pause, speed, loop and scrub over the
// instants of a reenactment, driven by wall-clock time.
#pragma once

namespace reenact::viewer {

class Playback {
 public:
  // `frame_count` instants (>= 1) at `fps` (> 0; else 30 is used).
  Playback(int frame_count, double fps);

  // Moves the play head by `wall_seconds` x speed when playing. At the end
  // it wraps to the start when looping, else it stops (paused) on the last
  // instant.
  void Advance(double wall_seconds);

  void SetPlaying(bool playing) { playing_ = playing; }
  void TogglePlaying() { playing_ = !playing_; }
  // Speed factor, clamped to 0.05..8.
  void SetSpeed(double speed);
  void SetLoop(bool loop) { loop_ = loop; }
  // Jumps to `fraction` (0..1, clamped) of the take.
  void Scrub(double fraction);
  // Steps `instants` (may be negative), clamped to the take; pauses.
  void Step(int instants);

  // The instant to draw: index into the reenactment's frames.
  int frame() const;
  // Where the play head is, 0..1.
  double fraction() const;
  bool playing() const { return playing_; }
  bool loop() const { return loop_; }
  double speed() const { return speed_; }
  int frame_count() const { return frame_count_; }

 private:
  int frame_count_;
  double fps_;
  double position_ = 0.0;  // Instants, 0 .. frame_count_ - 1.
  double speed_ = 1.0;
  bool playing_ = true;
  bool loop_ = true;
};

}  // namespace reenact::viewer
