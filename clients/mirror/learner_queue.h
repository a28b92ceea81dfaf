// A bounded queue of learner frames between the thread that reads or
// receives them and the app's thread that pulls them (LearnerSource::Next).
// Internal to the learner sources.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/learner_source.h"

namespace reenact::mirror {

class LearnerQueue {
 public:
  // What Push does when the queue holds `capacity` frames: wait for room (a
  // recording: no frame may be lost) or drop the oldest (live: the newest
  // frame matters).
  enum class WhenFull { kWait, kDropOldest };

  LearnerQueue(size_t capacity, WhenFull when_full) : capacity_(capacity), when_full_(when_full) {}

  // Adds a frame; false when the consumer has cancelled (stop producing).
  bool Push(LearnerFrame frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (when_full_ == WhenFull::kWait) {
      room_.wait(lock, [&] { return cancelled_ || frames_.size() < capacity_; });
    } else if (frames_.size() >= capacity_) {
      frames_.pop_front();
      ++dropped_;
    }
    if (cancelled_) return false;
    frames_.push_back(std::move(frame));
    ready_.notify_one();
    return true;
  }

  // Ends the stream after the queued frames; a non-OK status is returned by
  // Pop once they are taken.
  void Close(absl::Status status) {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    end_status_ = std::move(status);
    ready_.notify_all();
  }

  // Stops the producer (its next Push returns false) and wakes it.
  void Cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    room_.notify_all();
    ready_.notify_all();
  }

  // The next frame; nullopt at the end of a stream closed with OK.
  absl::StatusOr<std::optional<LearnerFrame>> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return cancelled_ || closed_ || !frames_.empty(); });
    if (!frames_.empty()) {
      LearnerFrame frame = std::move(frames_.front());
      frames_.pop_front();
      room_.notify_one();
      return std::optional<LearnerFrame>(std::move(frame));
    }
    if (!end_status_.ok()) return end_status_;
    return std::optional<LearnerFrame>();
  }

  // Frames dropped because the consumer fell behind (kDropOldest).
  int64_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  const size_t capacity_;
  const WhenFull when_full_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::condition_variable room_;
  std::deque<LearnerFrame> frames_;
  bool closed_ = false;
  bool cancelled_ = false;
  absl::Status end_status_;
  int64_t dropped_ = 0;
};

}  // namespace reenact::mirror
