#include "capture_daemon/daemon.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <set>
#include <utility>

#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/usb_hotplug.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/metrics/http_exposer.h"
#include "common/rpc/health_service.h"
#include "common/rpc/request_metrics.h"
#include "reenact/v1/capture_control_service.grpc.pb.h"

namespace reenact::capture {

namespace {

constexpr auto kTick = std::chrono::milliseconds(100);
// A set whose sensors all stall is sent this long after its window.
constexpr int64_t kStallNs = 1'000'000'000;
constexpr char kGenerator[] = "reenactd 0.1.0";

struct SensorEntry {
  std::unique_ptr<Sensor> sensor;
  std::unique_ptr<FrameProcessor> processor;
  v1::SensorInfo info;  // As opened; state and counters below.
  v1::SensorState state = v1::SENSOR_STATE_DETECTED;
  std::string detail;
  std::atomic<int64_t> frames{0};
  std::atomic<int64_t> processing_errors{0};
  std::atomic<int64_t> last_host_stamp_ns{0};
};

// A sensor whose recording ended while others may still stream. The sensors
// of one recording end within a frame of each other, so the end is reported
// to the take (SensorLost) only once another sensor delivers a frame clearly
// later than this one's last: in real time and in --fast playback alike.
struct PendingEnd {
  std::string sensor_id;
  int64_t last_host_stamp_ns = 0;
  int64_t noticed_ns = 0;
  std::string reason;
};

double CpuSeconds(int64_t* user_us, int64_t* sys_us) {
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  *user_us = usage.ru_utime.tv_sec * 1'000'000LL + usage.ru_utime.tv_usec;
  *sys_us = usage.ru_stime.tv_sec * 1'000'000LL + usage.ru_stime.tv_usec;
  return static_cast<double>(*user_us + *sys_us) * 1e-6;
}

double Ms(int64_t ns) { return static_cast<double>(ns) * 1e-6; }

// Frame sets refused because the take's spool was full (the daemon's
// limit; the server counts its own in the same family).
metrics::Counter& SpoolRefusals() {
  static metrics::Counter& counter = metrics::DefaultRegistry().GetCounter(
      "reenact_limit_refusals_total", "Requests refused because they exceeded a limit, by limit.",
      {{"limit", "spool_bytes"}});
  return counter;
}

}  // namespace

absl::Status DaemonOptions::Validate() const {
  if (server_address.empty()) return absl::InvalidArgumentError("--server is empty");
  if (sources.empty()) return absl::InvalidArgumentError("no --source given");
  if (spool_dir.empty()) return absl::InvalidArgumentError("--spool is empty");
  if (spool_max_mb < 1) return absl::InvalidArgumentError("--spool-max-mb must be at least 1");
  if (max_seconds < 0) return absl::InvalidArgumentError("--max-seconds must not be negative");
  if (!(drain_timeout_s >= 0))
    return absl::InvalidArgumentError("--drain-timeout-s must not be negative");
  RETURN_IF_ERROR(sync.Validate());
  RETURN_IF_ERROR(processing.Validate());
  RETURN_IF_ERROR(anchor.Validate());
  RETURN_IF_ERROR(control_tls.Validate());
  RETURN_IF_ERROR(rpc::CheckExposure(absl::StrCat("--control ", control_address), control_address,
                                     control_tls.enabled(), !control_auth_file.empty(), insecure,
                                     "start takes and watch the sensors"));
  if (!metrics_address.empty()) {
    std::string host;
    int port = 0;
    RETURN_IF_ERROR(SplitHostPort("--metrics", metrics_address, &host, &port));
  }
  // The metrics endpoint is plain HTTP without tokens.
  RETURN_IF_ERROR(rpc::CheckExposure(absl::StrCat("--metrics ", metrics_address), metrics_address,
                                     /*tls=*/false, /*tokens=*/false, insecure,
                                     "read the daemon's figures"));
  return uplink.Validate();
}

void AddDaemonMetrics(const v1::DaemonStatus& status, metrics::Snapshot& out) {
  for (const v1::SensorInfo& sensor : status.sensors()) {
    const metrics::Labels labels = {{"sensor", sensor.sensor_id()}};
    out.AddCounter("reenactd_frames_captured_total",
                   "Frames each sensor delivered to the pipeline.", labels,
                   static_cast<double>(sensor.frames_delivered()));
    out.AddGauge("reenactd_sensor_up", "1 while the sensor streams, 0 once it is gone.", labels,
                 sensor.state() == v1::SENSOR_STATE_STREAMING ? 1 : 0);
  }
  for (const v1::SensorSyncStats& sync : status.sync()) {
    out.AddCounter("reenactd_frames_dropped_total",
                   "Frames the sync group dropped (late, or no set to join), by sensor.",
                   {{"sensor", sync.sensor_id()}}, static_cast<double>(sync.frames_dropped()));
  }
  out.AddGauge("reenactd_uplink_queue_bytes",
               "Spooled bytes of frame sets the server has not acknowledged yet.", {},
               static_cast<double>(status.spool_bytes()));
  out.AddGauge("reenactd_uplink_queue_frame_sets",
               "Spooled frame sets the server has not acknowledged yet.", {},
               static_cast<double>(status.spool_frame_sets()));
  out.AddGauge("reenactd_uplink_connected",
               "1 while the uplink of the take has an open stream to the server.", {},
               status.server_connected() ? 1 : 0);
  out.AddCounter("reenactd_uplink_reconnects_total", "Uplink streams begun after the first.", {},
                 static_cast<double>(status.reconnects()));
  out.AddGauge("reenactd_recording", "1 while a take is being recorded.", {},
               status.take_id().empty() ? 0 : 1);
}

std::string DefaultDaemonId(const std::string& spool_dir) {
  char host[256] = {};
  if (gethostname(host, sizeof(host) - 1) != 0) std::snprintf(host, sizeof(host), "host");
  std::string clean;
  for (const char* c = host; *c != '\0' && clean.size() < 32; ++c) {
    clean.push_back(std::isalnum(static_cast<unsigned char>(*c)) || *c == '-' ? *c : '_');
  }
  // FNV-1a over the machine id and the spool folder.
  std::string key = ReadFileToString("/etc/machine-id").value_or(host);
  key += "|" + std::filesystem::absolute(spool_dir).lexically_normal().string();
  uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : key) hash = (hash ^ c) * 1099511628211ull;
  return absl::StrFormat("reenactd-%s-%08x", clean, static_cast<uint32_t>(hash ^ (hash >> 32)));
}

std::string DefaultSpoolDir() {
  if (const char* state = std::getenv("STATE_DIRECTORY"); state != nullptr && *state != '\0') {
    std::string first(state);
    first = first.substr(0, first.find(':'));
    return (std::filesystem::path(first) / "spool").string();
  }
  if (getuid() == 0) return "/var/lib/reenactd/spool";
  if (const char* state = std::getenv("XDG_STATE_HOME"); state != nullptr && *state == '/') {
    return (std::filesystem::path(state) / "reenactd" / "spool").string();
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home == '/') {
    return (std::filesystem::path(home) / ".local" / "state" / "reenactd" / "spool").string();
  }
  return "reenactd-spool";  // The working folder, as a last resort.
}

// ---------------------------------------------------------------------------
// The parts of the daemon. Each guards its own fields; where one thread needs
// several locks it takes them in this order:
//   TakeBook::mutex, SensorSet::mutex, FramePath::mutex, SyncSnapshot::mutex.
// BoardAnchoring's locks are taken alone or under the first two, and no lock
// is taken under them.

namespace {

// The sensors, opened at start and by hotplug rescans. Entries are never
// removed (a sensor that ended stays GONE), so the SensorEntry pointers the
// sensor callbacks hold stay valid until the daemon goes.
struct SensorSet {
  // Guards `entries` and each entry's state and detail.
  mutable std::mutex mutex;
  std::vector<std::unique_ptr<SensorEntry>> entries;

  std::vector<v1::SensorInfo> List() const {
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<v1::SensorInfo> out;
    for (const auto& entry : entries) {
      v1::SensorInfo info = entry->info;
      info.set_state(entry->state);
      info.set_detail(entry->detail);
      info.set_frames_delivered(entry->frames.load());
      out.push_back(std::move(info));
    }
    return out;
  }

  std::set<std::string> Ids() const {
    std::lock_guard<std::mutex> lock(mutex);
    std::set<std::string> ids;
    for (const auto& entry : entries) ids.insert(entry->info.sensor_id());
    return ids;
  }

  bool AllGone() const {
    std::lock_guard<std::mutex> lock(mutex);
    return std::all_of(entries.begin(), entries.end(),
                       [](const auto& e) { return e->state == v1::SENSOR_STATE_GONE; });
  }

  // A sensor with this id was here before and is gone.
  bool WasGone(const std::string& sensor_id) const {
    std::lock_guard<std::mutex> lock(mutex);
    return std::any_of(entries.begin(), entries.end(), [&sensor_id](const auto& known) {
      return known->info.sensor_id() == sensor_id && known->state == v1::SENSOR_STATE_GONE;
    });
  }

  // "backend|serial|uri" of each streaming sensor: a rescan opens only the
  // devices not among them.
  std::set<std::string> StreamingKeys() const {
    std::lock_guard<std::mutex> lock(mutex);
    std::set<std::string> keys;
    for (const auto& entry : entries) {
      if (entry->state == v1::SENSOR_STATE_STREAMING) keys.insert(KeyOf(entry->info));
    }
    return keys;
  }
  static std::string KeyOf(const v1::SensorInfo& info) {
    return info.backend() + "|" + info.serial() + "|" + info.uri();
  }

  // Adds `entry` as streaming; returns it.
  SensorEntry* Add(std::unique_ptr<SensorEntry> entry) {
    std::lock_guard<std::mutex> lock(mutex);
    entry->state = v1::SENSOR_STATE_STREAMING;
    entries.push_back(std::move(entry));
    return entries.back().get();
  }

  // Marks `entry` gone with `detail`; true when another sensor still streams.
  bool MarkGone(SensorEntry* entry, const std::string& detail) {
    std::lock_guard<std::mutex> lock(mutex);
    entry->state = v1::SENSOR_STATE_GONE;
    entry->detail = detail;
    return std::any_of(entries.begin(), entries.end(), [entry](const auto& other) {
      return other.get() != entry && other->state != v1::SENSOR_STATE_GONE;
    });
  }

  // Stops every sensor and joins its thread. The sensors are stopped outside
  // the lock: a sensor's end callback takes it.
  void StopAll() {
    std::vector<Sensor*> all;
    {
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& entry : entries) all.push_back(entry->sensor.get());
    }
    for (Sensor* sensor : all) sensor->Stop();
  }
};

// The takes: the one being recorded and those still uploading.
struct TakeBook {
  // Guards every field below.
  mutable std::mutex mutex;
  std::shared_ptr<ingest::TakeRecorder> current;  // Being recorded.
  int64_t current_started_steady_ns = 0;
  double current_max_seconds = 0.0;
  std::shared_ptr<ingest::TakeRecorder> once;                   // The --once take.
  std::vector<std::shared_ptr<ingest::TakeRecorder>> draining;  // Stopped or resumed, not done.
  std::set<const ingest::TakeRecorder*> resumed;                // Found in the spool at start.
  std::shared_ptr<ingest::TakeRecorder> last;
  // Uplink reconnects of the takes that are done.
  int64_t reconnects_finished = 0;

  // Reconnects of every take so far; the caller holds `mutex`.
  int64_t ReconnectsLocked() const {
    int64_t reconnects = reconnects_finished;
    for (const auto& r : draining) reconnects += r->Stats().uplink.reconnects;
    if (current) reconnects += current->Stats().uplink.reconnects;
    return reconnects;
  }
};

// The frame path: what the sensor threads share once a frame is processed.
struct FramePath {
  // Guards every field below. Held while a set is spooled, which may wait for
  // spool space (SyncSnapshot keeps Status() from waiting with it).
  std::mutex mutex;
  std::unique_ptr<SyncGroup> sync;
  std::shared_ptr<ingest::TakeRecorder> recording;  // The take the sets go to; null between takes.
  std::vector<PendingEnd> pending_ends;             // Ends of recordings not yet told to the take.
  int64_t refused_logged_steady_ns = 0;
  int64_t snapshot_steady_ns = 0;
};

// Copy of the sync figures for Status().
struct SyncSnapshot {
  // Guards both fields.
  mutable std::mutex mutex;
  SyncSummary summary;
  std::vector<v1::SensorSyncStats> sensors;
};

// The board anchoring of one take (DaemonOptions.anchor).
struct TakeAnchoring {
  std::shared_ptr<ingest::TakeRecorder> take;
  std::vector<v1::SensorCalibration> calibrations;               // As the sensors gave them.
  std::map<std::string, std::shared_ptr<SensorAnchor>> anchors;  // By sensor id.
  int64_t started_steady_ns = 0;
};

// Board anchoring of the take being recorded, until its OpenTake is sent:
// Start when the take starts (it holds the take's OpenTake back), Offer the
// colour frames, Finish when Due or when the take stops.
class BoardAnchoring {
 public:
  BoardAnchoring(const AnchorOptions* options, log::Logger* logger)
      : options_(options), logger_(logger) {}

  void Start(const std::shared_ptr<ingest::TakeRecorder>& recorder,
             const std::vector<v1::SensorCalibration>& calibrations);
  // From the sensor threads.
  void Offer(const v1::Frame& frame);
  // Every sensor finished, or anchor.timeout_s passed.
  bool Due();
  // Combines each sensor's detections, and sends the take's OpenTake with the
  // anchored calibrations (the others as given, with a warning).
  void Finish();

 private:
  const AnchorOptions* options_;
  log::Logger* logger_;
  // Guards state_.
  std::mutex mutex_;
  std::unique_ptr<TakeAnchoring> state_;
  // Held through Finish, so that a StopTake waits for a finish in progress
  // before it stops the take.
  std::mutex finish_mutex_;
};

void BoardAnchoring::Start(const std::shared_ptr<ingest::TakeRecorder>& recorder,
                           const std::vector<v1::SensorCalibration>& calibrations) {
  auto state = std::make_unique<TakeAnchoring>();
  state->take = recorder;
  state->calibrations = calibrations;
  state->started_steady_ns = SteadyNowNs();
  for (const v1::SensorCalibration& calibration : calibrations) {
    absl::StatusOr<std::unique_ptr<SensorAnchor>> anchor =
        SensorAnchor::Create(*options_, calibration);
    if (anchor.ok()) {
      state->anchors[calibration.sensor_id()] = std::move(*anchor);
    } else {
      logger_->Warn("sensor_not_anchored",
                    {{"sensor_id", calibration.sensor_id()}, {"error", anchor.status().message()}},
                    absl::StrCat("sensor ", calibration.sensor_id(),
                                 " cannot be anchored on the board; it keeps its calibration"));
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  state_ = std::move(state);
}

void BoardAnchoring::Offer(const v1::Frame& frame) {
  if (!frame.has_color()) return;
  std::shared_ptr<SensorAnchor> anchor;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!state_) return;
    auto it = state_->anchors.find(frame.sensor_id());
    if (it == state_->anchors.end()) return;
    anchor = it->second;
  }
  anchor->Offer(frame.color());
}

bool BoardAnchoring::Due() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!state_) return false;
  if (NsToSeconds(SteadyNowNs() - state_->started_steady_ns) >= options_->timeout_s) return true;
  return std::all_of(state_->anchors.begin(), state_->anchors.end(),
                     [](const auto& entry) { return entry.second->finished(); });
}

void BoardAnchoring::Finish() {
  std::lock_guard<std::mutex> finish_lock(finish_mutex_);
  std::unique_ptr<TakeAnchoring> state;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state = std::move(state_);
  }
  if (!state) return;
  const absl::StatusOr<std::string> anchor_name = WorldAnchorName(options_->board_spec);
  std::vector<v1::SensorCalibration> calibrations = state->calibrations;
  for (v1::SensorCalibration& calibration : calibrations) {
    auto it = state->anchors.find(calibration.sensor_id());
    if (it == state->anchors.end() || !anchor_name.ok()) continue;
    absl::StatusOr<AnchorResult> found = it->second->Finish();
    absl::StatusOr<v1::SensorCalibration> anchored =
        found.ok() ? AnchorCalibration(calibration, *found, *anchor_name) : found.status();
    if (!anchored.ok()) {
      logger_->Warn("sensor_not_anchored",
                    {{"sensor_id", calibration.sensor_id()},
                     {"anchor", *anchor_name},
                     {"error", anchored.status().message()}},
                    absl::StrCat("sensor ", calibration.sensor_id(), " is not anchored on ",
                                 *anchor_name, "; it keeps its calibration (world_anchor empty)"));
      continue;
    }
    calibration = *std::move(anchored);
    logger_->Info("sensor_anchored",
                  {{"sensor_id", calibration.sensor_id()},
                   {"anchor", *anchor_name},
                   {"detections", found->detections},
                   {"frames_tried", found->frames_tried},
                   {"rms_px", found->rms_px}},
                  absl::StrFormat("sensor %s anchored on %s: %d of %d colour frames, RMS %.2f px",
                                  calibration.sensor_id(), *anchor_name, found->detections,
                                  found->frames_tried, found->rms_px));
  }
  state->take->ReleaseOpen(calibrations);
}

// The CaptureControl gRPC server. Started by Run's start-up before the
// io_context runs and read-only from then on.
struct ControlEndpoint {
  std::unique_ptr<rpc::Authorizer> auth;
  std::unique_ptr<grpc::Service> service;
  // Registered with the server, so it outlives it.
  std::unique_ptr<rpc::HealthService> health;
  std::unique_ptr<grpc::Server> server;
  std::string bound_address;

  // NOT_SERVING from now on (a drain or the end); ends the health watches,
  // which a shutdown of the server would otherwise wait for.
  void StopHealth() {
    if (health) health->Shutdown();
  }
};

}  // namespace

struct Daemon::Impl {
  // Set by Create, read-only afterwards.
  DaemonOptions options;
  std::string daemon_id;
  std::shared_ptr<grpc::Channel> channel;
  ingest::TakeRecorderOptions recorder_options;
  int64_t start_steady_ns = 0;
  // The daemon's events (options.log in options.log_options).
  log::Logger logger{nullptr, log::Options{}};

  // The io_context and what only its thread (Run's) touches.
  boost::asio::io_context io;
  boost::asio::signal_set signals{io, SIGINT, SIGTERM};
  boost::asio::steady_timer timer{io};
  int64_t last_log_steady_ns = 0;
  std::optional<absl::Status> once_result;
  // Set from any thread.
  std::atomic<bool> stop_requested{false};
  std::atomic<int> signals_received{0};

  ControlEndpoint control;
  // Started by Create; read-only afterwards.
  std::unique_ptr<metrics::HttpExposer> metrics_exposer;
  std::string bound_metrics;

  SensorSet sensors;
  TakeBook takes;
  FramePath frames;
  SyncSnapshot snapshot;
  BoardAnchoring anchoring{&options.anchor, &logger};
  // StreamFrames subscribers.
  LiveFrames live;

  // --- Run's stages (Run's thread) ---
  absl::Status StartUp(CaptureController* controller);
  void ServeUntilStopped();
  absl::Status Drain();
  void ShutDown(const absl::Status& result);

  // --- start-up ---
  SourceOptions MakeSourceOptions() const;
  absl::Status StartServices(CaptureController* controller);
  absl::Status StartControl(CaptureController* controller);
  void ResumeUnfinished();
  absl::Status StartOnceTake();
  absl::Status AddSensors(SensorList opened);
  absl::StatusOr<SensorEntry*> JoinSensor(std::unique_ptr<Sensor> sensor);
  void StartSensor(SensorEntry* entry, bool returning);
  void StopSensors() { sensors.StopAll(); }

  // --- hotplug ---
  std::unique_ptr<UsbHotplugMonitor> StartHotplug();
  void OnUsbEvent(const UsbEvent& event);
  void RescanHardware();

  // --- drain and shutdown ---
  std::vector<std::shared_ptr<ingest::TakeRecorder>> TakesOfThisRun();
  void WaitUntilDurable(const std::vector<std::shared_ptr<ingest::TakeRecorder>>& ours);
  absl::Status ReportDrained(const std::vector<std::shared_ptr<ingest::TakeRecorder>>& ours);
  void AbandonUnfinished();
  void WriteStats(const absl::Status& result);

  // --- frame path (sensor threads) ---
  void OnFrame(SensorEntry* entry, CapturedFrame frame);
  void ReportPendingEndsLocked(const SensorEntry& entry, int64_t host_stamp_ns);
  void OnSensorEnd(SensorEntry* entry, const absl::Status& why);
  void RecordLocked(std::vector<v1::FrameSet> sets);
  void SnapshotLocked(bool force);

  // --- control (gRPC threads, io thread) ---
  absl::StatusOr<std::string> StartTake(const v1::StartTakeRequest& request);
  absl::StatusOr<v1::StopTakeResponse> StopTake(const std::string& reason, bool flush);
  v1::DaemonStatus Status();

  // --- housekeeping (io thread) ---
  void ArmSignals();
  void ArmTimer();
  void Tick();
  void ExpireStalledSets();
  std::vector<std::shared_ptr<ingest::TakeRecorder>> CheckTakes();
  void ReportFinished(const std::shared_ptr<ingest::TakeRecorder>& recorder);
  void LogProgress();
};

// ---------------------------------------------------------------------------
// Frame path

void Daemon::Impl::OnFrame(SensorEntry* entry, CapturedFrame frame) {
  if (absl::Status s = entry->processor->Process(frame); !s.ok()) {
    if (entry->processing_errors++ == 0) {
      logger.Error("sensor_processing_error",
                   {{"sensor_id", entry->info.sensor_id()}, {"error", s.message()}},
                   "further processing errors of this sensor are counted, not logged");
    }
    return;
  }
  ++entry->frames;
  if (options.anchor.enabled()) anchoring.Offer(frame.frame);
  const int64_t host_stamp_ns = frame.frame.host_stamp_ns();
  entry->last_host_stamp_ns = host_stamp_ns;
  std::lock_guard<std::mutex> lock(frames.mutex);
  RecordLocked(frames.sync->Add(std::move(frame.frame)));
  if (!frames.pending_ends.empty()) ReportPendingEndsLocked(*entry, host_stamp_ns);
  SnapshotLocked(false);
}

// Tells the take of the recordings that ended clearly before this frame of
// `entry` (see PendingEnd).
void Daemon::Impl::ReportPendingEndsLocked(const SensorEntry& entry, int64_t host_stamp_ns) {
  const double fps = entry.info.nominal_fps() > 0 ? entry.info.nominal_fps() : 30.0;
  const int64_t margin_ns = static_cast<int64_t>(2e9 / fps);
  std::vector<PendingEnd>& pending_ends = frames.pending_ends;
  for (auto it = pending_ends.begin(); it != pending_ends.end();) {
    if (host_stamp_ns <= it->last_host_stamp_ns + margin_ns) {
      ++it;
      continue;
    }
    if (frames.recording) frames.recording->SensorLost(it->sensor_id, it->noticed_ns, it->reason);
    it = pending_ends.erase(it);
  }
}

void Daemon::Impl::RecordLocked(std::vector<v1::FrameSet> sets) {
  for (const v1::FrameSet& set : sets) live.Publish(set);
  ingest::TakeRecorder* const recording = frames.recording.get();
  if (recording == nullptr) return;
  for (v1::FrameSet& set : sets) {
    const absl::Status added = recording->Add(std::move(set));
    if (added.ok() || absl::IsFailedPrecondition(added)) continue;
    const bool full = absl::IsResourceExhausted(added);
    if (full) SpoolRefusals().Increment();
    const int64_t now = SteadyNowNs();
    if (now - frames.refused_logged_steady_ns > kNanosPerSecond) {  // At most a line a second.
      frames.refused_logged_steady_ns = now;
      const int64_t refused = recording->Stats().frame_sets_refused;
      if (full) {
        logger.Error("limit_hit",
                     {{"limit", "spool_bytes"},
                      {"take_id", recording->take_id()},
                      {"refused_frame_sets", refused},
                      {"error", added.message()}},
                     "the take's spool is full: the server is not keeping up or is away");
      } else {
        logger.Error("frame_set_refused",
                     {{"take_id", recording->take_id()},
                      {"refused_frame_sets", refused},
                      {"error", added.message()}},
                     "a frame set could not be spooled");
      }
    }
  }
}

void Daemon::Impl::SnapshotLocked(bool force) {
  const int64_t now = SteadyNowNs();
  if (!force && now - frames.snapshot_steady_ns < 100'000'000) return;
  frames.snapshot_steady_ns = now;
  SyncSummary summary = frames.sync->Summary();
  std::vector<v1::SensorSyncStats> sensor_stats = frames.sync->SensorStats();
  std::lock_guard<std::mutex> lock(snapshot.mutex);
  snapshot.summary = std::move(summary);
  snapshot.sensors = std::move(sensor_stats);
}

void Daemon::Impl::OnSensorEnd(SensorEntry* entry, const absl::Status& why) {
  const std::string id = entry->info.sensor_id();
  const std::string reason = why.ok() ? "end of recording" : std::string(why.message());
  // The take is told of a lost sensor only while others stream on: the
  // last sensor to end ends the take instead.
  const bool others_streaming = sensors.MarkGone(entry, reason);
  if (why.ok()) {
    logger.Info("sensor_ended", {{"sensor_id", id}, {"reason", reason}},
                absl::StrCat("sensor ", id, " ended"));
  } else {
    logger.Warn("sensor_lost", {{"sensor_id", id}, {"reason", reason}},
                absl::StrCat("sensor ", id, " lost: ", reason));
  }
  {
    std::lock_guard<std::mutex> lock(frames.mutex);
    RecordLocked(frames.sync->SensorLost(id));
    if (frames.recording && others_streaming) {
      if (why.ok()) {
        frames.pending_ends.push_back({id, entry->last_host_stamp_ns.load(), WallNowNs(), reason});
      } else {
        frames.recording->SensorLost(id, WallNowNs(), reason);
      }
    }
    SnapshotLocked(true);
  }
  boost::asio::post(io, [this] {
    if (!options.once || !sensors.AllGone()) return;
    std::shared_ptr<ingest::TakeRecorder> current;
    {
      std::lock_guard<std::mutex> lock(takes.mutex);
      current = takes.current;
    }
    if (current) (void)StopTake("end of source", /*flush=*/true);
  });
}

// ---------------------------------------------------------------------------
// Control

absl::StatusOr<std::string> Daemon::Impl::StartTake(const v1::StartTakeRequest& request) {
  std::lock_guard<std::mutex> lock(takes.mutex);
  // Held until the take records, so that a sensor that ends meanwhile is
  // either left out of the take or reported to it.
  std::lock_guard<std::mutex> sensors_lock(sensors.mutex);
  if (takes.current) {
    return absl::FailedPreconditionError(
        absl::StrCat("take ", takes.current->take_id(), " is being recorded"));
  }
  if (stop_requested) return absl::FailedPreconditionError("reenactd is shutting down");
  std::vector<v1::SensorCalibration> calibrations;
  double fps = 0.0;
  for (const auto& entry : sensors.entries) {
    if (entry->state != v1::SENSOR_STATE_STREAMING) continue;
    v1::SensorCalibration calibration = entry->processor->calibration();
    calibration.set_sensor_id(entry->info.sensor_id());
    calibrations.push_back(std::move(calibration));
    fps = std::max(fps, entry->info.nominal_fps());
  }
  if (calibrations.empty()) return absl::FailedPreconditionError("no sensor streams");
  v1::TakeInfo info;
  info.set_name(request.name().empty() ? options.take_name : request.name());
  info.set_notes(request.notes());
  info.set_created_unix_ns(WallNowNs());
  info.set_generator(kGenerator);
  info.set_fps(fps);
  const std::string take_id = ingest::MakeTakeId(info.name());
  ASSIGN_OR_RETURN(std::unique_ptr<ingest::TakeRecorder> recorder,
                   ingest::TakeRecorder::Start(channel, recorder_options, take_id, daemon_id, info,
                                               calibrations));
  std::shared_ptr<ingest::TakeRecorder>& take = takes.current;
  take = std::move(recorder);
  if (options.anchor.enabled()) {
    take->HoldOpen();  // Before the first set: `frames.recording` is set below.
    anchoring.Start(take, calibrations);
  }
  takes.current_started_steady_ns = SteadyNowNs();
  takes.current_max_seconds = request.max_seconds();
  takes.last = take;
  {
    std::lock_guard<std::mutex> frames_lock(frames.mutex);
    frames.recording = take;
    frames.pending_ends.clear();
  }
  logger.Info("take_started",
              {{"take_id", take_id}, {"name", info.name()}, {"sensors", calibrations.size()}},
              absl::StrCat("take ", take_id, " started with ", calibrations.size(), " sensors"));
  return take_id;
}

absl::StatusOr<v1::StopTakeResponse> Daemon::Impl::StopTake(const std::string& reason, bool flush) {
  std::lock_guard<std::mutex> lock(takes.mutex);
  if (!takes.current) return absl::FailedPreconditionError("no take is being recorded");
  std::shared_ptr<ingest::TakeRecorder> stopping = std::move(takes.current);
  takes.current = nullptr;
  anchoring.Finish();
  stopping->StopWaiting();  // Frees the frame path if it waits for spool space.
  {
    std::lock_guard<std::mutex> frames_lock(frames.mutex);
    if (flush) RecordLocked(frames.sync->Flush());
    frames.recording = nullptr;
    frames.pending_ends.clear();
    SnapshotLocked(true);
  }
  stopping->Stop(reason);
  takes.draining.push_back(stopping);
  v1::StopTakeResponse response;
  response.set_take_id(stopping->take_id());
  response.set_frame_set_count(stopping->last_sequence());
  logger.Info("take_stopped",
              {{"take_id", stopping->take_id()},
               {"reason", reason},
               {"frame_sets", stopping->last_sequence()}},
              absl::StrCat("take ", stopping->take_id(), " stopped (", reason, ") after ",
                           stopping->last_sequence(), " frame sets"));
  return response;
}

v1::DaemonStatus Daemon::Impl::Status() {
  v1::DaemonStatus status;
  status.set_daemon_id(daemon_id);
  status.set_server_address(options.server_address);
  std::vector<std::shared_ptr<ingest::TakeRecorder>> all_takes;
  std::shared_ptr<ingest::TakeRecorder> current;
  std::shared_ptr<ingest::TakeRecorder> latest;
  {
    std::lock_guard<std::mutex> lock(takes.mutex);
    current = takes.current;
    latest = takes.last;
    all_takes = takes.draining;
    if (takes.current) all_takes.push_back(takes.current);
    status.set_reconnects(takes.reconnects_finished);
  }
  for (const auto& recorder : all_takes) {
    const ingest::TakeStats stats = recorder->Stats();
    status.set_spool_frame_sets(status.spool_frame_sets() + stats.spool_frame_sets);
    status.set_spool_bytes(status.spool_bytes() + stats.spool_bytes);
    status.set_spool_refused_frame_sets(status.spool_refused_frame_sets() +
                                        stats.frame_sets_refused);
    status.set_reconnects(status.reconnects() + stats.uplink.reconnects);
    if (recorder == current) {
      status.set_take_id(stats.take_id);
      status.set_server_connected(stats.uplink.connected);
      status.set_last_sequence(static_cast<uint64_t>(stats.frame_sets));
      status.set_durable_sequence(stats.durable_sequence);
      if (!stats.uplink.connected) status.set_uplink_error(stats.uplink.last_error);
    }
  }
  if (!current && latest) {
    const ingest::TakeStats stats = latest->Stats();
    status.set_server_connected(stats.uplink.connected);
    if (!stats.uplink.connected) status.set_uplink_error(stats.uplink.last_error);
    status.set_last_sequence(static_cast<uint64_t>(stats.frame_sets));
    status.set_durable_sequence(stats.durable_sequence);
  }
  {
    std::lock_guard<std::mutex> lock(snapshot.mutex);
    status.set_frame_sets(snapshot.summary.frame_sets);
    status.set_skew_p50_ns(snapshot.summary.skew_p50_ns);
    status.set_skew_max_ns(snapshot.summary.skew_max_ns);
    for (const v1::SensorSyncStats& s : snapshot.sensors) *status.add_sync() = s;
  }
  for (v1::SensorInfo& info : sensors.List()) *status.add_sensors() = std::move(info);
  return status;
}

// ---------------------------------------------------------------------------
// Start-up

// Opens the sources and starts the sensors, then the services around them
// (StartServices); arms the signals and the housekeeping timer.
absl::Status Daemon::Impl::StartUp(CaptureController* controller) {
  ASSIGN_OR_RETURN(SensorList opened, OpenSources(options.sources, MakeSourceOptions()));
  RETURN_IF_ERROR(AddSensors(std::move(opened)));
  if (absl::Status s = StartServices(controller); !s.ok()) {
    StopSensors();
    return s;
  }
  ArmSignals();
  ArmTimer();
  return absl::OkStatus();
}

SourceOptions Daemon::Impl::MakeSourceOptions() const {
  SourceOptions source_options;
  source_options.fast = options.fast;
  source_options.loop = options.loop;
  return source_options;
}

// What starts once the sensors stream: the control service, the uploads of
// takes left in the spool, and the --once take.
absl::Status Daemon::Impl::StartServices(CaptureController* controller) {
  if (sensors.AllGone()) return absl::FailedPreconditionError("no sensor streams");
  // The control address (and its file) appear once the sensors stream.
  RETURN_IF_ERROR(StartControl(controller));
  ResumeUnfinished();
  if (options.once) RETURN_IF_ERROR(StartOnceTake());
  return absl::OkStatus();
}

absl::Status Daemon::Impl::StartControl(CaptureController* controller) {
  if (options.control_address.empty()) return absl::OkStatus();
  ASSIGN_OR_RETURN(const std::shared_ptr<grpc::ServerCredentials> credentials,
                   rpc::MakeServerCredentials(options.control_tls));
  std::optional<rpc::TokenTable> tokens;
  if (!options.control_auth_file.empty()) {
    ASSIGN_OR_RETURN(tokens, rpc::TokenTable::Load(options.control_auth_file));
  }
  control.auth = std::make_unique<rpc::Authorizer>(std::move(tokens), CaptureControlMethodAccess());
  control.service = CreateCaptureControlService(
      controller, control.auth->enabled() ? control.auth.get() : nullptr);
  control.health = std::make_unique<rpc::HealthService>(
      std::vector<std::string>{v1::CaptureControl::service_full_name()});
  std::set<std::string, std::less<>> counted = {"/grpc.health.v1.Health/Check",
                                                "/grpc.health.v1.Health/Watch"};
  for (const auto& [method, access] : CaptureControlMethodAccess()) counted.insert(method);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(options.control_address, credentials, &port);
  builder.RegisterService(control.service.get());
  // No token needed (common/rpc/health_service.h).
  builder.RegisterService(control.health.get());
  builder.experimental().SetInterceptorCreators(rpc::RequestMetricsInterceptors(counted));
  control.server = builder.BuildAndStart();
  if (!control.server || port == 0) {
    return absl::UnavailableError(
        absl::StrCat("cannot listen on --control ", options.control_address));
  }
  const std::string host = options.control_address.substr(0, options.control_address.rfind(':'));
  control.bound_address = absl::StrCat(host, ":", port);
  logger.Info("control_listening", {{"address", control.bound_address}},
              absl::StrCat("control service listening on ", control.bound_address));
  if (!options.control_port_file.empty()) {
    RETURN_IF_ERROR(WriteFileAtomically(options.control_port_file, control.bound_address + "\n"));
  }
  return absl::OkStatus();
}

void Daemon::Impl::ResumeUnfinished() {
  for (const std::string& dir : ingest::ListUnfinishedTakes(options.spool_dir)) {
    absl::StatusOr<std::unique_ptr<ingest::TakeRecorder>> opened =
        ingest::TakeRecorder::ResumeUnfinished(channel, recorder_options, dir);
    if (!opened.ok()) {
      logger.Error("take_resume_failed", {{"spool", dir}, {"error", opened.status().message()}},
                   absl::StrCat("cannot resume the spooled take in ", dir));
      continue;
    }
    std::shared_ptr<ingest::TakeRecorder> resumed_take = std::move(*opened);
    logger.Info("take_resumed", {{"take_id", resumed_take->take_id()}},
                absl::StrCat("resuming the upload of spooled take ", resumed_take->take_id()));
    std::lock_guard<std::mutex> lock(takes.mutex);
    takes.resumed.insert(resumed_take.get());
    takes.draining.push_back(std::move(resumed_take));
  }
}

absl::Status Daemon::Impl::StartOnceTake() {
  v1::StartTakeRequest request;
  request.set_name(options.take_name);
  request.set_max_seconds(options.max_seconds);
  RETURN_IF_ERROR(StartTake(request).status());
  std::lock_guard<std::mutex> lock(takes.mutex);
  takes.once = takes.current;
  return absl::OkStatus();
}

absl::Status Daemon::Impl::AddSensors(SensorList opened) {
  // Every sensor joins the sync group before any of them starts, so that no
  // set leaves early for want of a sensor not yet known.
  std::vector<std::pair<SensorEntry*, bool>> added;  // With: seen before, gone, and back.
  for (auto& sensor : opened) {
    const bool returning = sensors.WasGone(sensor->info().sensor_id());
    ASSIGN_OR_RETURN(SensorEntry* const entry, JoinSensor(std::move(sensor)));
    added.emplace_back(entry, returning);
  }
  for (const auto& [entry, returning] : added) StartSensor(entry, returning);
  return absl::OkStatus();
}

// Gives `sensor` its processor and a place in the sync group and the
// SensorSet; not started yet.
absl::StatusOr<SensorEntry*> Daemon::Impl::JoinSensor(std::unique_ptr<Sensor> sensor) {
  auto entry = std::make_unique<SensorEntry>();
  entry->info = sensor->info();
  ASSIGN_OR_RETURN(entry->processor, FrameProcessor::Create(entry->info, options.processing));
  entry->sensor = std::move(sensor);
  {
    std::lock_guard<std::mutex> lock(frames.mutex);
    RETURN_IF_ERROR(frames.sync->AddSensor(entry->info.sensor_id(), entry->info.nominal_fps()));
  }
  return sensors.Add(std::move(entry));
}

void Daemon::Impl::StartSensor(SensorEntry* entry, bool returning) {
  const absl::Status started =
      entry->sensor->Start([this, entry](CapturedFrame frame) { OnFrame(entry, std::move(frame)); },
                           [this, entry](const absl::Status& why) { OnSensorEnd(entry, why); });
  const v1::SensorInfo& info = entry->info;
  if (started.ok()) {
    logger.Info(returning ? "sensor_recovered" : "sensor_opened",
                {{"sensor_id", info.sensor_id()},
                 {"backend", info.backend()},
                 {"model", info.model()},
                 {"serial", info.serial()},
                 {"fps", info.nominal_fps()}},
                absl::StrCat("sensor ", info.sensor_id(), returning ? " is back" : " streams"));
    return;
  }
  logger.Error("sensor_failed", {{"sensor_id", info.sensor_id()}, {"error", started.message()}},
               absl::StrCat("sensor ", info.sensor_id(), " did not start"));
  sensors.MarkGone(entry, std::string(started.message()));
  std::lock_guard<std::mutex> lock(frames.mutex);
  (void)frames.sync->SensorLost(info.sensor_id());
}

// ---------------------------------------------------------------------------
// Hotplug

// USB hotplug for hardware sources: arrivals rescan the backends, and a
// departure is logged (the sensor's own stream ends by itself). Without USB
// access (e.g. a container without /dev/bus/usb) the daemon runs on; null
// then, and without hardware sources.
std::unique_ptr<UsbHotplugMonitor> Daemon::Impl::StartHotplug() {
  const bool hardware = std::any_of(options.sources.begin(), options.sources.end(),
                                    [](const SourceSpec& s) { return IsHardware(s); });
  if (!hardware) return nullptr;
  auto monitor = UsbHotplugMonitor::Start([this](const UsbHotplugEvent& event) {
    logger.Info("usb_event",
                {{"arrived", event.kind == UsbHotplugKind::kArrived}, {"usb_id", event.usb_id()}},
                absl::StrCat("usb: ", event.ToString()));
    OnUsbEvent(UsbEvent{event.kind == UsbHotplugKind::kArrived, event.usb_id(), ""});
  });
  if (!monitor.ok()) {
    logger.Warn("usb_hotplug_off", {{"error", monitor.status().message()}},
                "usb hotplug is off: new sensors are not noticed");
    return nullptr;
  }
  return std::move(*monitor);
}

void Daemon::Impl::OnUsbEvent(const UsbEvent& event) {
  if (!event.arrived) return;
  boost::asio::post(io, [this] { RescanHardware(); });
}

void Daemon::Impl::RescanHardware() {
  std::vector<SourceSpec> hardware;
  for (const SourceSpec& spec : options.sources) {
    if (IsHardware(spec)) hardware.push_back(spec);
  }
  if (hardware.empty()) return;
  const std::set<std::string> streaming = sensors.StreamingKeys();
  const SourceOptions source_options = MakeSourceOptions();
  for (const SourceSpec& spec : hardware) {
    absl::StatusOr<SensorList> opened = OpenSources({spec}, source_options);
    if (!opened.ok()) continue;  // Nothing new there (or the device is busy).
    SensorList fresh;
    for (auto& sensor : *opened) {
      if (!streaming.count(SensorSet::KeyOf(sensor->info()))) fresh.push_back(std::move(sensor));
    }
    if (absl::Status s = AddSensors(std::move(fresh)); !s.ok()) {
      logger.Error("hotplug_failed", {{"error", s.message()}}, "new sensors could not be added");
    }
  }
}

// ---------------------------------------------------------------------------
// Housekeeping (io thread)

void Daemon::Impl::ArmSignals() {
  signals.async_wait([this](const boost::system::error_code& error, int signal) {
    if (error) return;
    ++signals_received;
    if (signals_received == 1) {
      logger.Info("daemon_stopping",
                  {{"signal", signal}, {"drain_timeout_s", options.drain_timeout_s}},
                  absl::StrCat("signal ", signal, ": stopping (", options.drain_timeout_s,
                               " s to make the take durable)"));
    } else {
      logger.Warn("daemon_drain_abandoned", {{"signal", signal}},
                  "second signal: giving up on the drain");
    }
    stop_requested = true;
    io.stop();
    ArmSignals();
  });
}

void Daemon::Impl::ArmTimer() {
  timer.expires_after(kTick);
  timer.async_wait([this](const boost::system::error_code& error) {
    if (error) return;
    Tick();
    ArmTimer();
  });
}

void Daemon::Impl::Tick() {
  if (stop_requested) {
    io.stop();
    return;
  }
  ExpireStalledSets();
  if (anchoring.Due()) anchoring.Finish();
  for (const auto& recorder : CheckTakes()) ReportFinished(recorder);
  if (options.verbose && SteadyNowNs() - last_log_steady_ns >= kNanosPerSecond) {
    last_log_steady_ns = SteadyNowNs();
    LogProgress();
  }
}

// Sends the sets whose sensors stalled. Skipped while the frame path holds
// its lock (it may wait for spool space); the next tick tries again.
void Daemon::Impl::ExpireStalledSets() {
  std::unique_lock<std::mutex> lock(frames.mutex, std::try_to_lock);
  if (!lock.owns_lock()) return;
  RecordLocked(frames.sync->Expire(WallNowNs(), kStallNs));
  SnapshotLocked(false);
}

// Stops the current take when its uplink failed or its max_seconds passed;
// returns the takes that are done (and no longer draining).
std::vector<std::shared_ptr<ingest::TakeRecorder>> Daemon::Impl::CheckTakes() {
  std::shared_ptr<ingest::TakeRecorder> current;
  double max_seconds = 0;
  int64_t started_ns = 0;
  std::vector<std::shared_ptr<ingest::TakeRecorder>> finished;
  {
    std::lock_guard<std::mutex> lock(takes.mutex);
    current = takes.current;
    max_seconds = takes.current_max_seconds;
    started_ns = takes.current_started_steady_ns;
    for (auto it = takes.draining.begin(); it != takes.draining.end();) {
      if ((*it)->done()) {
        finished.push_back(*it);
        it = takes.draining.erase(it);
      } else {
        ++it;
      }
    }
  }
  if (current && current->done()) {  // The uplink failed while recording.
    logger.Error("take_failed",
                 {{"take_id", current->take_id()}, {"error", current->result().message()}},
                 absl::StrCat("take ", current->take_id(), " failed while recording"));
    (void)StopTake("uplink failed", /*flush=*/false);
    finished.push_back(current);
    std::lock_guard<std::mutex> lock(takes.mutex);
    takes.draining.erase(std::remove(takes.draining.begin(), takes.draining.end(), current),
                         takes.draining.end());
  } else if (current && max_seconds > 0 && NsToSeconds(SteadyNowNs() - started_ns) >= max_seconds) {
    (void)StopTake("max seconds reached", /*flush=*/false);
  }
  return finished;
}

// Logs how a finished take ended; the end of the --once take ends Run.
void Daemon::Impl::ReportFinished(const std::shared_ptr<ingest::TakeRecorder>& recorder) {
  recorder->WaitDone(0);  // Removes the spool folder of a closed take.
  const absl::Status result = recorder->result();
  bool once = false;
  {
    std::lock_guard<std::mutex> lock(takes.mutex);
    takes.reconnects_finished += recorder->Stats().uplink.reconnects;
    once = recorder == takes.once;
  }
  if (result.ok()) {
    logger.Info("take_durable", {{"take_id", recorder->take_id()}},
                absl::StrCat("take ", recorder->take_id(), " is durable on the server"));
  } else {
    logger.Error("take_failed", {{"take_id", recorder->take_id()}, {"error", result.message()}},
                 absl::StrCat("take ", recorder->take_id(), " failed; its spool stays on disk"));
  }
  if (once) {
    once_result = result;
    io.stop();
  }
}

// The per-second progress line (--verbose).
void Daemon::Impl::LogProgress() {
  const v1::DaemonStatus status = Status();
  std::string line = absl::StrCat("sets ", status.frame_sets(), " skew p50 ",
                                  absl::StrFormat("%.1f", Ms(status.skew_p50_ns())), " ms");
  for (const auto& s : status.sync()) {
    absl::StrAppend(&line, " | ", s.sensor_id(), " in ", s.frames_in(), " drop ",
                    s.frames_dropped(), " dup ", s.frames_duplicate());
  }
  absl::StrAppend(&line, " | take ", status.take_id().empty() ? "-" : status.take_id(), " sent ",
                  status.last_sequence(), " durable ", status.durable_sequence(), " spool ",
                  status.spool_frame_sets(), " sets ", status.spool_bytes() >> 20, " MiB",
                  status.server_connected() ? " connected" : " not connected", " reconnects ",
                  status.reconnects());
  logger.Info("progress",
              {{"frame_sets", status.frame_sets()},
               {"skew_p50_ms", Ms(status.skew_p50_ns())},
               {"take_id", status.take_id()},
               {"sent_sequence", status.last_sequence()},
               {"durable_sequence", status.durable_sequence()},
               {"spool_frame_sets", status.spool_frame_sets()},
               {"spool_bytes", status.spool_bytes()},
               {"connected", status.server_connected()},
               {"reconnects", status.reconnects()}},
              line);
}

// ---------------------------------------------------------------------------
// Serving, draining, shutdown

// Runs the io_context (signals, housekeeping, hotplug rescans, the end of the
// --once take) until a stop, a signal or the end of the --once take.
void Daemon::Impl::ServeUntilStopped() {
  std::unique_ptr<UsbHotplugMonitor> hotplug = StartHotplug();
  io.run();
  hotplug.reset();
  // Draining (or done): probes hear NOT_SERVING from here on.
  control.StopHealth();
}

// The --once result; or a shutdown: stop the sensors, put what the sync
// group holds in the take, close it, and wait for the server to make it
// durable. Returns what Run returns.
absl::Status Daemon::Impl::Drain() {
  if (once_result.has_value() && !stop_requested) {
    StopSensors();
    return *once_result;
  }
  {
    std::lock_guard<std::mutex> lock(takes.mutex);
    if (takes.current) takes.current->StopWaiting();
  }
  StopSensors();
  (void)StopTake("stopped", /*flush=*/true);
  const std::vector<std::shared_ptr<ingest::TakeRecorder>> ours = TakesOfThisRun();
  WaitUntilDurable(ours);
  return ReportDrained(ours);
}

// The takes still uploading that this run recorded (not resumed ones).
std::vector<std::shared_ptr<ingest::TakeRecorder>> Daemon::Impl::TakesOfThisRun() {
  std::vector<std::shared_ptr<ingest::TakeRecorder>> ours;
  std::lock_guard<std::mutex> lock(takes.mutex);
  for (const auto& r : takes.draining) {
    if (!takes.resumed.count(r.get())) ours.push_back(r);
  }
  return ours;
}

// Runs the io_context until `ours` are done, a second signal, or
// drain_timeout_s.
void Daemon::Impl::WaitUntilDurable(
    const std::vector<std::shared_ptr<ingest::TakeRecorder>>& ours) {
  auto all_done = [&ours] {
    return std::all_of(ours.begin(), ours.end(), [](const auto& r) { return r->done(); });
  };
  io.restart();
  const int64_t deadline = SteadyNowNs() + SecondsToNs(options.drain_timeout_s);
  while (!all_done() && signals_received < 2 && SteadyNowNs() < deadline) {
    io.run_for(std::chrono::milliseconds(50));
    io.restart();
  }
}

// Logs how each of `ours` ended; the first error (a failed take, or
// DeadlineExceeded for one that is not durable yet) is the result.
absl::Status Daemon::Impl::ReportDrained(
    const std::vector<std::shared_ptr<ingest::TakeRecorder>>& ours) {
  absl::Status result = absl::OkStatus();
  for (const auto& r : ours) {
    if (r->done()) {
      r->WaitDone(0);
      if (result.ok()) result = r->result();
      if (r->result().ok()) {
        logger.Info("take_durable", {{"take_id", r->take_id()}},
                    absl::StrCat("take ", r->take_id(), " is durable on the server"));
      } else {
        logger.Error("take_failed", {{"take_id", r->take_id()}, {"error", r->result().message()}},
                     absl::StrCat("take ", r->take_id(), " failed"));
      }
      continue;
    }
    const ingest::TakeStats stats = r->Stats();
    const absl::Status timed_out = absl::DeadlineExceededError(
        absl::StrCat("the server did not make take ", r->take_id(), " durable within ",
                     options.drain_timeout_s, " s; ", stats.spool_frame_sets, " frame sets (",
                     stats.spool_bytes, " bytes) stay in the spool ", options.spool_dir, "/",
                     r->take_id(), " and are sent when reenactd starts again"));
    if (result.ok()) {
      result = timed_out;  // The caller reports it.
    } else {
      logger.Error("take_not_durable",
                   {{"take_id", r->take_id()},
                    {"spool_frame_sets", stats.spool_frame_sets},
                    {"spool_bytes", stats.spool_bytes}},
                   timed_out.message());
    }
  }
  return result;
}

// Ends Run: what still uploads is given up (its spool stays for the next
// start), --stats-json is written, the StreamFrames calls and the control
// service end.
void Daemon::Impl::ShutDown(const absl::Status& result) {
  AbandonUnfinished();
  WriteStats(result);
  live.Close();  // Ends the StreamFrames calls.
  if (control.server) {
    control.server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
  }
}

void Daemon::Impl::AbandonUnfinished() {
  std::lock_guard<std::mutex> lock(takes.mutex);
  if (takes.current) takes.current->Abort();
  for (const auto& r : takes.draining) {
    if (r->done()) {
      r->WaitDone(0);  // Removes the spool folder of a closed take.
    } else {
      r->Abort();
    }
  }
}

void Daemon::Impl::WriteStats(const absl::Status& result) {
  if (options.stats_json.empty()) return;
  int64_t user_us = 0;
  int64_t sys_us = 0;
  const double cpu_s = CpuSeconds(&user_us, &sys_us);
  SyncSummary sync_summary;
  {
    std::lock_guard<std::mutex> lock(frames.mutex);
    sync_summary = frames.sync->Summary();
  }
  nlohmann::json j;
  j["daemon_id"] = daemon_id;
  j["result"] = result.ok() ? "ok" : std::string(result.message());
  int64_t dropped = 0;
  int64_t duplicates = 0;
  nlohmann::json sync_sensors = nlohmann::json::object();
  for (const SyncSensorStats& s : sync_summary.sensors) {
    dropped += s.frames_dropped;
    duplicates += s.frames_duplicate;
    sync_sensors[s.sensor_id] = {{"frames_in", s.frames_in},
                                 {"frames_dropped", s.frames_dropped},
                                 {"frames_duplicate", s.frames_duplicate},
                                 {"clock_offset_ms", Ms(s.clock_offset_ns)}};
  }
  j["sync"] = {{"frame_sets", sync_summary.frame_sets},
               {"incomplete_sets", sync_summary.incomplete_sets},
               {"skew_p50_ms", Ms(sync_summary.skew_p50_ns)},
               {"skew_p99_ms", Ms(sync_summary.skew_p99_ns)},
               {"skew_max_ms", Ms(sync_summary.skew_max_ns)},
               {"sensors", sync_sensors}};
  j["frames_dropped"] = dropped;
  j["frames_duplicate"] = duplicates;
  j["skew_p50_ms"] = Ms(sync_summary.skew_p50_ns);
  j["skew_p99_ms"] = Ms(sync_summary.skew_p99_ns);
  std::shared_ptr<ingest::TakeRecorder> recorder;
  int64_t reconnects = 0;
  {
    std::lock_guard<std::mutex> lock(takes.mutex);
    recorder = takes.last;
    reconnects = takes.ReconnectsLocked();
  }
  if (recorder) {
    const ingest::TakeStats stats = recorder->Stats();
    j["take_id"] = stats.take_id;
    j["frame_sets"] = stats.frame_sets;
    j["frame_sets_durable"] = stats.durable_sequence;
    j["frame_sets_refused"] = stats.frame_sets_refused;
    j["frames_per_sensor"] = stats.frames_per_sensor;
    j["frame_set_bytes_mean"] =
        stats.frame_sets > 0 ? static_cast<double>(stats.bytes_total) / stats.frame_sets : 0.0;
    j["latency_ms"] = {{"p50", Ms(stats.latency_p50_ns)},
                       {"p99", Ms(stats.latency_p99_ns)},
                       {"max", Ms(stats.latency_max_ns)},
                       {"frame_sets", stats.acked_sets}};
    j["frame_sets_sent"] = stats.uplink.frame_sets_sent;
    // Not "ok" when the take did not reach the server whole: why it stopped.
    j["uplink_error"] = stats.uplink.last_error;
    j["uplink_ok"] =
        stats.uplink.done && stats.durable_sequence == static_cast<uint64_t>(stats.frame_sets);
  } else {
    j["take_id"] = "";
    j["frame_sets"] = 0;
  }
  j["reconnects"] = reconnects;
  j["cpu_s"] = cpu_s;
  j["cpu_user_s"] = static_cast<double>(user_us) * 1e-6;
  j["cpu_sys_s"] = static_cast<double>(sys_us) * 1e-6;
  j["wall_s"] = NsToSeconds(SteadyNowNs() - start_steady_ns);
  if (absl::Status s = WriteFileAtomically(options.stats_json, j.dump(2) + "\n"); !s.ok()) {
    logger.Error("stats_json_failed", {{"path", options.stats_json}, {"error", s.message()}},
                 "--stats-json could not be written");
  }
}

// ---------------------------------------------------------------------------
// Daemon

Daemon::Daemon(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Daemon::~Daemon() {
  impl_->metrics_exposer.reset();  // No scrape reads the daemon from here on.
  impl_->StopSensors();
  impl_->live.Close();
  impl_->control.StopHealth();  // Ends the health watches the shutdown would wait for.
  if (impl_->control.server) impl_->control.server->Shutdown();
}

absl::StatusOr<std::unique_ptr<Daemon>> Daemon::Create(const DaemonOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->logger = log::Logger(options.log, options.log_options);
  impl->start_steady_ns = SteadyNowNs();
  if (absl::Status s = CreateDirectories(options.spool_dir); !s.ok()) {
    return absl::UnavailableError(absl::StrCat("--spool: ", s.message()));
  }
  impl->daemon_id =
      options.daemon_id.empty() ? DefaultDaemonId(options.spool_dir) : options.daemon_id;
  impl->channel = ingest::MakeIngestChannel(options.server_address, options.uplink);
  impl->recorder_options.spool_root = options.spool_dir;
  impl->recorder_options.spool_max_bytes = options.spool_max_mb << 20;
  impl->recorder_options.uplink = options.uplink;
  // Takes and recordings can wait for the server; live sensors cannot.
  impl->recorder_options.wait_when_full =
      std::none_of(options.sources.begin(), options.sources.end(),
                   [](const SourceSpec& s) { return IsHardware(s); });
  if (impl->recorder_options.wait_when_full) {
    impl->options.anchor.queued_frames = impl->options.anchor.frames;
  }
  ASSIGN_OR_RETURN(impl->frames.sync, SyncGroup::Create(options.sync));
  // The metrics endpoint answers from now on (before Run: no sensor yet),
  // so its address is known once Create returns.
  if (!options.metrics_address.empty()) {
    Impl* const raw = impl.get();
    ASSIGN_OR_RETURN(impl->metrics_exposer,
                     metrics::HttpExposer::Start(options.metrics_address, [raw] {
                       metrics::Snapshot snapshot;
                       metrics::DefaultRegistry().CollectInto(snapshot);
                       AddDaemonMetrics(raw->Status(), snapshot);
                       metrics::AddProcessMetrics(snapshot);
                       return snapshot.Expose();
                     }));
    impl->bound_metrics = impl->metrics_exposer->address();
    impl->logger.Info("metrics_listening", {{"address", impl->bound_metrics}},
                      absl::StrCat("metrics on http://", impl->bound_metrics, "/metrics"));
  }
  return std::unique_ptr<Daemon>(new Daemon(std::move(impl)));
}

absl::Status Daemon::Run() {
  RETURN_IF_ERROR(impl_->StartUp(this));
  impl_->ServeUntilStopped();
  absl::Status result = impl_->Drain();
  impl_->ShutDown(result);
  return result;
}

void Daemon::RequestStop() {
  impl_->stop_requested = true;
  boost::asio::post(impl_->io, [this] { impl_->io.stop(); });
}

std::string Daemon::control_address() const { return impl_->control.bound_address; }

std::string Daemon::metrics_address() const { return impl_->bound_metrics; }

std::vector<v1::SensorInfo> Daemon::ListSensors() { return impl_->sensors.List(); }

absl::StatusOr<std::string> Daemon::StartTake(const v1::StartTakeRequest& request) {
  return impl_->StartTake(request);
}

absl::StatusOr<v1::StopTakeResponse> Daemon::StopTake() {
  return impl_->StopTake("stopped", /*flush=*/false);
}

v1::DaemonStatus Daemon::Status() { return impl_->Status(); }

absl::StatusOr<uint64_t> Daemon::SubscribeFrames(const v1::StreamFramesRequest& request,
                                                 LiveFrames::Callback on_set) {
  const std::set<std::string> known = impl_->sensors.Ids();
  for (const auto* ids : {&request.sensor_ids(), &request.color_sensor_ids()}) {
    for (const std::string& id : *ids) {
      if (!known.count(id)) {
        return absl::InvalidArgumentError(absl::StrCat("no sensor '", id, "' on this daemon"));
      }
    }
  }
  if (request.color_max_width_px() < 0 || request.color_jpeg_quality() < 0 ||
      request.color_jpeg_quality() > 100) {
    return absl::InvalidArgumentError(
        "color_max_width_px must be >= 0 and color_jpeg_quality within 0..100");
  }
  return impl_->live.Subscribe(request, std::move(on_set));
}

void Daemon::UnsubscribeFrames(uint64_t subscription) { impl_->live.Unsubscribe(subscription); }

void Daemon::OnUsbEvent(const UsbEvent& event) { impl_->OnUsbEvent(event); }

}  // namespace reenact::capture
