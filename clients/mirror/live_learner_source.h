// The learner from a live capture daemon (reenactd): its sensor's skeletons
// and colour as they are captured, through a small callback interface
// (LiveFrameFeed) that the daemon's client implements and tests fake.
//
// The daemon's CaptureControl service lists its sensors with their
// calibrations (ListSensors) and streams the sync group's frame sets to live
// clients (StreamFrames: LiveFrameSet, skeletons in each sensor's depth
// camera frame, colour downscaled by an integer factor). The feed asks for one
// sensor's skeletons and colour.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/learner_source.h"
#include "clients/sdk/takes_client.h"
#include "reenact/v1/capture_control_service.pb.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::mirror {

class LiveFrameFeed {
 public:
  virtual ~LiveFrameFeed() = default;

  // The sensors the daemon knows, with their calibrations.
  virtual absl::StatusOr<std::vector<v1::SensorInfo>> Sensors() = 0;
  // Calls `on_set` with every frame set carrying `sensor_id`'s skeletons and
  // colour as it is captured, on the calling thread, until `on_set` returns
  // false (then OK), the stream ends (OK) or fails (its error). Blocks
  // meanwhile; Cancel from another thread makes it return OK soon.
  virtual absl::Status Stream(const std::string& sensor_id,
                              const std::function<bool(const v1::LiveFrameSet&)>& on_set) = 0;
  // Asks a running (or the next) Stream to return; safe from any thread.
  virtual void Cancel() = 0;
  // E.g. "reenactd 127.0.0.1:50052", for messages.
  virtual std::string Describe() const = 0;
};

struct DaemonFeedOptions {
  // HOST:PORT of reenactd; the deadline of ListSensors (the stream has none).
  client::ConnectionOptions connection;
  // Colour is shrunk by the daemon to at most this width, pixels (> 0).
  int color_max_width_px = 960;
  // JPEG quality of the shrunk colour, 1..100.
  int color_jpeg_quality = 80;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// The feed of the reenactd at options.connection.address.
absl::StatusOr<std::unique_ptr<LiveFrameFeed>> NewDaemonFrameFeed(const DaemonFeedOptions& options);
// The same over an existing channel (e.g. an in-process one in tests);
// `address` names the daemon in messages.
absl::StatusOr<std::unique_ptr<LiveFrameFeed>> NewDaemonFrameFeed(
    std::shared_ptr<grpc::Channel> channel, const DaemonFeedOptions& options);

// The learner from `feed`'s sensor `sensor_id` (empty: the first streaming
// sensor that provides or computes skeletons, else the first streaming one).
// Sets are received on a thread of the source; when the app falls behind,
// the oldest waiting frames are dropped (live: the newest matter). The
// stream's error (e.g. Unavailable when the daemon goes away) is returned by
// Next. NotFound for an unknown sensor; FailedPrecondition when no sensor
// streams; the feed's errors from Sensors.
absl::StatusOr<std::unique_ptr<LearnerSource>> OpenLiveLearner(std::unique_ptr<LiveFrameFeed> feed,
                                                               const std::string& sensor_id = "");

// The learner frame of `sensor_id` in one frame set: the exposure stamp of
// its colour image (else of its skeletons, else the set's stamp), the
// learner among its skeletons in the colour camera frame, its colour
// decoded. Exposed for tests.
LearnerFrame LearnerFrameFromSet(const v1::LiveFrameSet& set, const std::string& sensor_id,
                                 const Rigid3d& color_from_depth, int64_t clock_offset_ns);

}  // namespace reenact::mirror
