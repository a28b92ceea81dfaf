// reenactd, the capture daemon: sensors -> per-sensor processing -> sync
// group -> take recorder (disk spool + Ingest uplink), with the
// CaptureControl service beside it. Runs on a Boost.Asio io_context that
// handles SIGINT/SIGTERM and a 100 ms housekeeping timer (stalled sets,
// --max-seconds, --once completion, per-second log lines with --verbose).
//
// Frame path: each sensor's thread runs its FrameProcessor, then adds the
// frame to the sync group under one lock; the sets it completes go to the
// take being recorded (if any), whose spool write is the only disk work on
// that path. When a take is stopped the sensors keep streaming (daemon mode)
// or are stopped (--once, shutdown); the take closes once the server holds
// every set, and a shutdown waits up to drain_timeout_s for that.
#pragma once

#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "capture_daemon/board_anchor.h"
#include "capture_daemon/capture_control_service.h"
#include "capture_daemon/processing/frame_processor.h"
#include "capture_daemon/sensor_factory.h"
#include "capture_daemon/sensors/sensor.h"
#include "capture_daemon/sync_group.h"
#include "common/ingest/take_recorder.h"
#include "common/ingest/uplink.h"
#include "common/log/log.h"
#include "common/metrics/metrics.h"

namespace reenact::capture {

struct DaemonOptions {
  // Ingest service of reenact-server, "host:port".
  std::string server_address = "127.0.0.1:50051";
  std::vector<SourceSpec> sources;
  // Playback pacing (SourceOptions.fast / loop).
  bool fast = false;
  bool loop = false;
  // Start a take at once, end it when every source ended (or after
  // max_seconds), and return when the server holds all of it.
  bool once = false;
  // Length limit of the --once take, seconds (0: none).
  double max_seconds = 0.0;
  // CaptureControl listening address ("host:0" picks a free port); empty
  // disables the service.
  std::string control_address = "127.0.0.1:50052";
  // File that receives the bound control address ("host:port\n").
  std::string control_port_file;
  // TLS of the control service (common/rpc/channel.h), and its token file
  // (common/rpc/auth.h; empty: every caller may do everything). Without
  // both, a non-loopback control address needs `insecure`.
  rpc::ServerTlsFiles control_tls{};
  std::string control_auth_file{};
  bool insecure = false;
  // Folder of the take spools; bound of each take's spool.
  std::string spool_dir;
  int64_t spool_max_mb = 1024;
  // Name of the --once take (the take id derives from it).
  std::string take_name = "take";
  // Stable id of this daemon (DefaultDaemonId when empty).
  std::string daemon_id;
  SyncOptions sync;
  ProcessingOptions processing;
  ingest::UplinkOptions uplink;
  // Board anchoring (--anchor board[:SPEC]): at the start of each take every
  // sensor looks for the board in its colour frames; the take's OpenTake
  // waits (up to anchor.timeout_s) and carries each anchored sensor's
  // calibration with world_from_depth in the board's frame and world_anchor
  // "board:SPEC". A sensor that does not see the board keeps its calibration
  // (a warning is logged). The daemon puts nothing else in world coordinates
  // (skeletons stay in the depth camera; the segmenter uses only the source
  // calibration's up direction, which the board on the floor shares).
  AnchorOptions anchor;
  // How long a shutdown waits for the take to become durable, seconds.
  double drain_timeout_s = 10.0;
  // Figures for the end-to-end benchmark, written at exit (JSON).
  std::string stats_json;
  // Per-second progress events on `log`.
  bool verbose = false;
  // Where the daemon's events go (common/log/log.h: sensors, takes, the
  // control service; progress with verbose); nullptr: none. The uplink's
  // events and refusals of control calls go to the process logger
  // (log::Default()), which reenactd points at the same stderr.
  std::ostream* log = nullptr;
  // Format and level of `log` (--log-format, --log-level).
  log::Options log_options{};
  // "HOST:PORT" of the Prometheus metrics endpoint (GET /metrics; port 0
  // picks one); empty: none. Plain HTTP without tokens: a non-loopback
  // address needs `insecure`.
  std::string metrics_address{};

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// A USB device came or went (from capture_daemon/sensors' hotplug monitor).
struct UsbEvent {
  bool arrived = true;
  std::string usb_id;  // "vendor:product", e.g. "045e:02ae".
  std::string serial;  // When known.
};

// The daemon's figures for the metrics endpoint, from its status:
//   reenactd_frames_captured_total{sensor}  frames each sensor delivered
//   reenactd_frames_dropped_total{sensor}   frames the sync group dropped
//   reenactd_sensor_up{sensor}              1 while the sensor streams
//   reenactd_uplink_queue_bytes             spooled bytes the server has
//                                           not acknowledged yet
//   reenactd_uplink_queue_frame_sets        the same in frame sets
//   reenactd_uplink_connected               1 while the take's stream is open
//   reenactd_uplink_reconnects_total        streams begun after the first
//   reenactd_recording                      1 while a take is recorded
void AddDaemonMetrics(const v1::DaemonStatus& status, metrics::Snapshot& out);

// "reenactd-<host>-<8 hex>": stable for one machine and spool folder.
std::string DefaultDaemonId(const std::string& spool_dir);
// The spool folder used when none is given: $STATE_DIRECTORY/spool under
// systemd, else /var/lib/reenactd/spool for root, else
// $XDG_STATE_HOME/reenactd/spool (default ~/.local/state). Never the system's
// temporary folder: the spool holds frames of people until the server has
// them, and /tmp is shared with every user and emptied at boot.
std::string DefaultSpoolDir();

class Daemon : public CaptureController {
 public:
  // Validates the options and opens the sources (NotFound and friends from
  // the backends, prefixed with the source spec).
  static absl::StatusOr<std::unique_ptr<Daemon>> Create(const DaemonOptions& options);
  ~Daemon() override;

  // Runs until RequestStop() or a signal (or, with once, until the take is
  // closed or failed). OK when every take ended durable on the server;
  // otherwise the error (e.g. a non-retryable server status, or
  // DeadlineExceeded when the drain timed out with the spool left on disk).
  absl::Status Run();
  // Makes Run() shut down as on SIGTERM. Thread-safe.
  void RequestStop();

  // Address the control service is bound to (after Run() started it).
  std::string control_address() const;
  // Address the metrics endpoint is bound to (Create starts it); empty
  // without one.
  std::string metrics_address() const;

  // CaptureController.
  std::vector<v1::SensorInfo> ListSensors() override;
  absl::StatusOr<std::string> StartTake(const v1::StartTakeRequest& request) override;
  absl::StatusOr<v1::StopTakeResponse> StopTake() override;
  v1::DaemonStatus Status() override;
  // Every set of the sync group, recording or not (capture_daemon/live_frames.h).
  absl::StatusOr<uint64_t> SubscribeFrames(const v1::StreamFramesRequest& request,
                                           LiveFrames::Callback on_set) override;
  void UnsubscribeFrames(uint64_t subscription) override;

  // Hotplug hook: an arrival rescans the hardware sources and starts the
  // sensors that are new; a departure needs nothing (the sensor's stream
  // ends by itself). Thread-safe; the work runs on the daemon's io_context.
  void OnUsbEvent(const UsbEvent& event);

 private:
  struct Impl;
  explicit Daemon(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact::capture
