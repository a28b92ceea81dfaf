// Live frame sets for clients of the CaptureControl service (StreamFrames):
// the daemon publishes every set its sync group makes, and each subscriber
// receives LiveFrameSets cut to its request (skeletons of chosen sensors,
// colour of chosen sensors shrunk and re-encoded).
//
// The capture never waits for a client: Publish keeps a light copy of the
// newest set (skeletons, and colour only of sensors someone asked for) and
// returns; one worker thread turns the newest set into each subscriber's
// LiveFrameSet, skipping sets that arrived while it was busy, and hands it
// to the subscriber, which keeps only the newest one it has not yet written
// (drops are counted in LiveFrameSet.dropped_sets).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "reenact/v1/capture_control_service.pb.h"

namespace reenact::capture {

class LiveFrames {
 public:
  // Called on the worker thread with each set for the subscriber, and once
  // with nullptr when the stream ends (Close). Must not block.
  using Callback = std::function<void(std::shared_ptr<const v1::LiveFrameSet>)>;

  LiveFrames();
  ~LiveFrames();  // Close()s.

  // Adds a subscriber; the request's sensor ids are taken as valid (the
  // caller checks them). Returns its id for Unsubscribe.
  uint64_t Subscribe(const v1::StreamFramesRequest& request, Callback callback);
  // No callback of `id` runs after this returns.
  void Unsubscribe(uint64_t id);
  // Offers the sync group's newest set; cheap, never waits for clients.
  void Publish(const v1::FrameSet& set);
  // Ends every subscription (callback with nullptr) and stops the worker.
  void Close();

 private:
  struct Subscriber {
    v1::StreamFramesRequest request;
    Callback callback;
  };
  struct Published {
    v1::FrameSet set;  // Skeletons, and colour of the wanted sensors only.
    uint64_t index = 0;
  };
  void Work();
  void Deliver(const Published& published);

  std::mutex mutex_;  // Guards the fields below but subscribers_.
  std::condition_variable cv_;
  std::unique_ptr<Published> newest_;
  uint64_t published_ = 0;
  bool closed_ = false;
  std::set<std::string> colour_wanted_;  // Sensors some subscriber wants colour of.
  std::atomic<int> subscriber_count_{0};

  std::mutex subscribers_mutex_;  // Held while callbacks run.
  std::map<uint64_t, Subscriber> subscribers_;
  uint64_t next_id_ = 1;
  std::thread worker_;
};

// `set` cut to `request`: skeletons of its sensors, colour of its colour
// sensors shrunk (StreamFramesRequest). Colour that does not decode is left
// out.
v1::LiveFrameSet MakeLiveFrameSet(const v1::FrameSet& set, uint64_t index,
                                  const v1::StreamFramesRequest& request);

}  // namespace reenact::capture
