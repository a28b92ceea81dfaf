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

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/usb_hotplug.h"
#include "common/base/files.h"
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
    const size_t colon = metrics_address.rfind(':');
    int port = -1;
    if (colon == std::string::npos || colon == 0 ||
        !absl::SimpleAtoi(metrics_address.substr(colon + 1), &port) || port < 0 || port > 65535) {
      return absl::InvalidArgumentError(
          absl::StrCat("--metrics \"", metrics_address, "\" is not HOST:PORT (port 0..65535)"));
    }
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

// The board anchoring of one take (DaemonOptions.anchor).
struct TakeAnchoring {
  std::shared_ptr<TakeRecorder> take;
  std::vector<v1::SensorCalibration> calibrations;               // As the sensors gave them.
  std::map<std::string, std::shared_ptr<SensorAnchor>> anchors;  // By sensor id.
  int64_t started_steady_ns = 0;
};

struct Daemon::Impl {
  DaemonOptions options;
  std::string daemon_id;
  std::shared_ptr<grpc::Channel> channel;
  TakeRecorderOptions recorder_options;

  boost::asio::io_context io;
  boost::asio::signal_set signals{io, SIGINT, SIGTERM};
  boost::asio::steady_timer timer{io};
  std::unique_ptr<rpc::Authorizer> control_auth;
  std::unique_ptr<grpc::Service> control_service;
  // Registered with the control server, so it outlives it.
  std::unique_ptr<rpc::HealthService> health;
  std::unique_ptr<grpc::Server> control_server;
  std::string bound_control;
  std::unique_ptr<metrics::HttpExposer> metrics_exposer;
  std::string bound_metrics;
  std::atomic<bool> stop_requested{false};
  std::atomic<int> signals_received{0};
  int64_t start_steady_ns = 0;
  int64_t last_log_steady_ns = 0;

  // Sensors, takes. Lock order: mutex before sync_mutex.
  mutable std::mutex mutex;
  std::vector<std::unique_ptr<SensorEntry>> sensors;
  std::shared_ptr<TakeRecorder> take;  // Being recorded.
  int64_t take_started_steady_ns = 0;
  double take_max_seconds = 0.0;
  std::shared_ptr<TakeRecorder> once_take;
  std::vector<std::shared_ptr<TakeRecorder>> draining;  // Stopped or resumed, not done.
  std::set<const TakeRecorder*> resumed;                // Found in the spool at start.
  std::shared_ptr<TakeRecorder> last_take;
  int64_t reconnects_finished = 0;

  // The frame path.
  std::mutex sync_mutex;
  std::unique_ptr<SyncGroup> sync;
  std::shared_ptr<TakeRecorder> recording;
  int64_t refused_logged_steady_ns = 0;

  // Copy of the sync figures for Status (the frame path may hold sync_mutex
  // while it waits for spool space).
  mutable std::mutex snapshot_mutex;
  SyncSummary snapshot;
  std::vector<v1::SensorSyncStats> snapshot_sensors;
  int64_t snapshot_steady_ns = 0;

  // The daemon's events (options.log in options.log_options).
  log::Logger logger{nullptr, log::Options{}};

  // StreamFrames subscribers.
  LiveFrames live;

  // Board anchoring of the take being recorded, until its OpenTake is sent.
  std::mutex anchor_mutex;
  std::unique_ptr<TakeAnchoring> anchoring;
  // Held through FinishAnchoring, so that a StopTake waits for a finish in
  // progress before it stops the take.
  std::mutex anchor_finish_mutex;
  void StartAnchoring(const std::shared_ptr<TakeRecorder>& recorder,
                      const std::vector<v1::SensorCalibration>& calibrations);
  void OfferToAnchoring(const v1::Frame& frame);
  bool AnchoringDue();
  void FinishAnchoring();

  // NOT_SERVING from now on (a drain or the end); ends the health watches,
  // which a shutdown of the control server would otherwise wait for.
  void StopHealth() {
    if (health) health->Shutdown();
  }

  // --- frame path (sensor threads) ---
  void OnFrame(SensorEntry* entry, CapturedFrame frame);
  // Ends of recordings not yet reported to the take (guarded by sync_mutex).
  std::vector<PendingEnd> pending_ends;
  void OnSensorEnd(SensorEntry* entry, const absl::Status& why);
  void RecordLocked(std::vector<v1::FrameSet> sets);
  void SnapshotLocked(bool force);

  // --- control (gRPC threads, io thread) ---
  absl::StatusOr<std::string> StartTake(const v1::StartTakeRequest& request);
  absl::StatusOr<v1::StopTakeResponse> StopTake(const std::string& reason, bool flush);
  v1::DaemonStatus Status();
  std::vector<v1::SensorInfo> ListSensors();

  // --- io thread ---
  absl::Status AddSensors(SensorList opened);
  absl::Status StartControl(CaptureController* controller);
  void ResumeUnfinished();
  void ArmSignals();
  void ArmTimer();
  void Tick();
  void StopSensors();
  bool AllSensorsGone();
  void RescanHardware();
  void WriteStats(const absl::Status& result);
  std::optional<absl::Status> once_result;
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
  if (options.anchor.enabled()) OfferToAnchoring(frame.frame);
  const int64_t host_stamp_ns = frame.frame.host_stamp_ns();
  entry->last_host_stamp_ns = host_stamp_ns;
  std::lock_guard<std::mutex> lock(sync_mutex);
  RecordLocked(sync->Add(std::move(frame.frame)));
  if (!pending_ends.empty()) {
    const double fps = entry->info.nominal_fps() > 0 ? entry->info.nominal_fps() : 30.0;
    const int64_t margin_ns = static_cast<int64_t>(2e9 / fps);
    for (auto it = pending_ends.begin(); it != pending_ends.end();) {
      if (host_stamp_ns <= it->last_host_stamp_ns + margin_ns) {
        ++it;
        continue;
      }
      if (recording) recording->SensorLost(it->sensor_id, it->noticed_ns, it->reason);
      it = pending_ends.erase(it);
    }
  }
  SnapshotLocked(false);
}

void Daemon::Impl::RecordLocked(std::vector<v1::FrameSet> sets) {
  for (const v1::FrameSet& set : sets) live.Publish(set);
  if (recording == nullptr) return;
  for (v1::FrameSet& set : sets) {
    const absl::Status added = recording->Add(std::move(set));
    if (added.ok() || absl::IsFailedPrecondition(added)) continue;
    const bool full = absl::IsResourceExhausted(added);
    if (full) SpoolRefusals().Increment();
    const int64_t now = SteadyNowNs();
    if (now - refused_logged_steady_ns > kNanosPerSecond) {  // At most a line a second.
      refused_logged_steady_ns = now;
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
  if (!force && now - snapshot_steady_ns < 100'000'000) return;
  snapshot_steady_ns = now;
  SyncSummary summary = sync->Summary();
  std::vector<v1::SensorSyncStats> sensor_stats = sync->SensorStats();
  std::lock_guard<std::mutex> lock(snapshot_mutex);
  snapshot = std::move(summary);
  snapshot_sensors = std::move(sensor_stats);
}

void Daemon::Impl::OnSensorEnd(SensorEntry* entry, const absl::Status& why) {
  const std::string id = entry->info.sensor_id();
  const std::string reason = why.ok() ? "end of recording" : std::string(why.message());
  // The take is told of a lost sensor only while others stream on: the
  // last sensor to end ends the take instead.
  bool others_streaming = false;
  {
    std::lock_guard<std::mutex> lock(mutex);
    entry->state = v1::SENSOR_STATE_GONE;
    entry->detail = reason;
    for (const auto& other : sensors) {
      if (other.get() != entry && other->state != v1::SENSOR_STATE_GONE) others_streaming = true;
    }
  }
  if (why.ok()) {
    logger.Info("sensor_ended", {{"sensor_id", id}, {"reason", reason}},
                absl::StrCat("sensor ", id, " ended"));
  } else {
    logger.Warn("sensor_lost", {{"sensor_id", id}, {"reason", reason}},
                absl::StrCat("sensor ", id, " lost: ", reason));
  }
  {
    std::lock_guard<std::mutex> lock(sync_mutex);
    RecordLocked(sync->SensorLost(id));
    if (recording && others_streaming) {
      if (why.ok()) {
        pending_ends.push_back({id, entry->last_host_stamp_ns.load(), WallNowNs(), reason});
      } else {
        recording->SensorLost(id, WallNowNs(), reason);
      }
    }
    SnapshotLocked(true);
  }
  boost::asio::post(io, [this] {
    if (!options.once || !AllSensorsGone()) return;
    std::shared_ptr<TakeRecorder> current;
    {
      std::lock_guard<std::mutex> lock(mutex);
      current = take;
    }
    if (current) (void)StopTake("end of source", /*flush=*/true);
  });
}

// ---------------------------------------------------------------------------
// Control

std::vector<v1::SensorInfo> Daemon::Impl::ListSensors() {
  std::lock_guard<std::mutex> lock(mutex);
  std::vector<v1::SensorInfo> out;
  for (const auto& entry : sensors) {
    v1::SensorInfo info = entry->info;
    info.set_state(entry->state);
    info.set_detail(entry->detail);
    info.set_frames_delivered(entry->frames.load());
    out.push_back(std::move(info));
  }
  return out;
}

absl::StatusOr<std::string> Daemon::Impl::StartTake(const v1::StartTakeRequest& request) {
  std::lock_guard<std::mutex> lock(mutex);
  if (take) {
    return absl::FailedPreconditionError(
        absl::StrCat("take ", take->take_id(), " is being recorded"));
  }
  if (stop_requested) return absl::FailedPreconditionError("reenactd is shutting down");
  std::vector<v1::SensorCalibration> calibrations;
  double fps = 0.0;
  for (const auto& entry : sensors) {
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
  const std::string take_id = MakeTakeId(info.name());
  ASSIGN_OR_RETURN(
      std::unique_ptr<TakeRecorder> recorder,
      TakeRecorder::Start(channel, recorder_options, take_id, daemon_id, info, calibrations));
  take = std::move(recorder);
  if (options.anchor.enabled()) {
    take->HoldOpen();  // Before the first set: `recording` is set below.
    StartAnchoring(take, calibrations);
  }
  take_started_steady_ns = SteadyNowNs();
  take_max_seconds = request.max_seconds();
  last_take = take;
  {
    std::lock_guard<std::mutex> sync_lock(sync_mutex);
    recording = take;
    pending_ends.clear();
  }
  logger.Info("take_started",
              {{"take_id", take_id}, {"name", info.name()}, {"sensors", calibrations.size()}},
              absl::StrCat("take ", take_id, " started with ", calibrations.size(), " sensors"));
  return take_id;
}

absl::StatusOr<v1::StopTakeResponse> Daemon::Impl::StopTake(const std::string& reason, bool flush) {
  std::lock_guard<std::mutex> lock(mutex);
  if (!take) return absl::FailedPreconditionError("no take is being recorded");
  std::shared_ptr<TakeRecorder> stopping = std::move(take);
  take = nullptr;
  FinishAnchoring();
  stopping->StopWaiting();  // Frees the frame path if it waits for spool space.
  {
    std::lock_guard<std::mutex> sync_lock(sync_mutex);
    if (flush) RecordLocked(sync->Flush());
    recording = nullptr;
    pending_ends.clear();
    SnapshotLocked(true);
  }
  stopping->Stop(reason);
  draining.push_back(stopping);
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
  std::vector<std::shared_ptr<TakeRecorder>> takes;
  std::shared_ptr<TakeRecorder> current;
  std::shared_ptr<TakeRecorder> latest;
  {
    std::lock_guard<std::mutex> lock(mutex);
    current = take;
    latest = last_take;
    takes = draining;
    if (take) takes.push_back(take);
    status.set_reconnects(reconnects_finished);
  }
  std::map<std::string, int64_t> refused_frames;
  for (const auto& recorder : takes) {
    const TakeStats stats = recorder->Stats();
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
    const TakeStats stats = latest->Stats();
    status.set_server_connected(stats.uplink.connected);
    if (!stats.uplink.connected) status.set_uplink_error(stats.uplink.last_error);
    status.set_last_sequence(static_cast<uint64_t>(stats.frame_sets));
    status.set_durable_sequence(stats.durable_sequence);
  }
  {
    std::lock_guard<std::mutex> lock(snapshot_mutex);
    status.set_frame_sets(snapshot.frame_sets);
    status.set_skew_p50_ns(snapshot.skew_p50_ns);
    status.set_skew_max_ns(snapshot.skew_max_ns);
    for (const v1::SensorSyncStats& s : snapshot_sensors) *status.add_sync() = s;
  }
  for (v1::SensorInfo& info : ListSensors()) *status.add_sensors() = std::move(info);
  return status;
}

// ---------------------------------------------------------------------------
// Board anchoring

void Daemon::Impl::StartAnchoring(const std::shared_ptr<TakeRecorder>& recorder,
                                  const std::vector<v1::SensorCalibration>& calibrations) {
  auto state = std::make_unique<TakeAnchoring>();
  state->take = recorder;
  state->calibrations = calibrations;
  state->started_steady_ns = SteadyNowNs();
  for (const v1::SensorCalibration& calibration : calibrations) {
    absl::StatusOr<std::unique_ptr<SensorAnchor>> anchor =
        SensorAnchor::Create(options.anchor, calibration);
    if (anchor.ok()) {
      state->anchors[calibration.sensor_id()] = std::move(*anchor);
    } else {
      logger.Warn("sensor_not_anchored",
                  {{"sensor_id", calibration.sensor_id()}, {"error", anchor.status().message()}},
                  absl::StrCat("sensor ", calibration.sensor_id(),
                               " cannot be anchored on the board; it keeps its calibration"));
    }
  }
  std::lock_guard<std::mutex> lock(anchor_mutex);
  anchoring = std::move(state);
}

void Daemon::Impl::OfferToAnchoring(const v1::Frame& frame) {
  if (!frame.has_color()) return;
  std::shared_ptr<SensorAnchor> anchor;
  {
    std::lock_guard<std::mutex> lock(anchor_mutex);
    if (!anchoring) return;
    auto it = anchoring->anchors.find(frame.sensor_id());
    if (it == anchoring->anchors.end()) return;
    anchor = it->second;
  }
  anchor->Offer(frame.color());
}

bool Daemon::Impl::AnchoringDue() {
  std::lock_guard<std::mutex> lock(anchor_mutex);
  if (!anchoring) return false;
  if (NsToSeconds(SteadyNowNs() - anchoring->started_steady_ns) >= options.anchor.timeout_s) {
    return true;
  }
  return std::all_of(anchoring->anchors.begin(), anchoring->anchors.end(),
                     [](const auto& entry) { return entry.second->finished(); });
}

// Combines each sensor's detections, and sends the take's OpenTake with the
// anchored calibrations (the others as given, with a warning).
void Daemon::Impl::FinishAnchoring() {
  std::lock_guard<std::mutex> finish_lock(anchor_finish_mutex);
  std::unique_ptr<TakeAnchoring> state;
  {
    std::lock_guard<std::mutex> lock(anchor_mutex);
    state = std::move(anchoring);
  }
  if (!state) return;
  const absl::StatusOr<std::string> anchor_name = WorldAnchorName(options.anchor.board_spec);
  std::vector<v1::SensorCalibration> calibrations = state->calibrations;
  for (v1::SensorCalibration& calibration : calibrations) {
    auto it = state->anchors.find(calibration.sensor_id());
    if (it == state->anchors.end() || !anchor_name.ok()) continue;
    absl::StatusOr<AnchorResult> found = it->second->Finish();
    absl::StatusOr<v1::SensorCalibration> anchored =
        found.ok() ? AnchorCalibration(calibration, *found, *anchor_name) : found.status();
    if (!anchored.ok()) {
      logger.Warn("sensor_not_anchored",
                  {{"sensor_id", calibration.sensor_id()},
                   {"anchor", *anchor_name},
                   {"error", anchored.status().message()}},
                  absl::StrCat("sensor ", calibration.sensor_id(), " is not anchored on ",
                               *anchor_name, "; it keeps its calibration (world_anchor empty)"));
      continue;
    }
    calibration = *std::move(anchored);
    logger.Info("sensor_anchored",
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

// ---------------------------------------------------------------------------
// Setup, housekeeping, shutdown

absl::Status Daemon::Impl::AddSensors(SensorList opened) {
  // Every sensor joins the sync group before any of them starts, so that no
  // set leaves early for want of a sensor not yet known.
  std::vector<SensorEntry*> added;
  std::set<std::string> returning;  // Sensors seen before, gone, and back.
  for (auto& sensor : opened) {
    auto entry = std::make_unique<SensorEntry>();
    entry->info = sensor->info();
    {
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& known : sensors) {
        if (known->info.sensor_id() == entry->info.sensor_id() &&
            known->state == v1::SENSOR_STATE_GONE) {
          returning.insert(entry->info.sensor_id());
        }
      }
    }
    ASSIGN_OR_RETURN(entry->processor, FrameProcessor::Create(entry->info, options.processing));
    entry->sensor = std::move(sensor);
    {
      std::lock_guard<std::mutex> lock(sync_mutex);
      RETURN_IF_ERROR(sync->AddSensor(entry->info.sensor_id(), entry->info.nominal_fps()));
    }
    std::lock_guard<std::mutex> lock(mutex);
    entry->state = v1::SENSOR_STATE_STREAMING;
    added.push_back(entry.get());
    sensors.push_back(std::move(entry));
  }
  for (SensorEntry* raw : added) {
    const absl::Status started =
        raw->sensor->Start([this, raw](CapturedFrame frame) { OnFrame(raw, std::move(frame)); },
                           [this, raw](const absl::Status& why) { OnSensorEnd(raw, why); });
    const v1::SensorInfo& info = raw->info;
    if (started.ok()) {
      const bool back = returning.contains(info.sensor_id());
      logger.Info(back ? "sensor_recovered" : "sensor_opened",
                  {{"sensor_id", info.sensor_id()},
                   {"backend", info.backend()},
                   {"model", info.model()},
                   {"serial", info.serial()},
                   {"fps", info.nominal_fps()}},
                  absl::StrCat("sensor ", info.sensor_id(), back ? " is back" : " streams"));
      continue;
    }
    logger.Error("sensor_failed", {{"sensor_id", info.sensor_id()}, {"error", started.message()}},
                 absl::StrCat("sensor ", info.sensor_id(), " did not start"));
    {
      std::lock_guard<std::mutex> lock(mutex);
      raw->state = v1::SENSOR_STATE_GONE;
      raw->detail = std::string(started.message());
    }
    std::lock_guard<std::mutex> lock(sync_mutex);
    (void)sync->SensorLost(raw->info.sensor_id());
  }
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
  control_auth = std::make_unique<rpc::Authorizer>(std::move(tokens), CaptureControlMethodAccess());
  control_service = CreateCaptureControlService(
      controller, control_auth->enabled() ? control_auth.get() : nullptr);
  health = std::make_unique<rpc::HealthService>(
      std::vector<std::string>{v1::CaptureControl::service_full_name()});
  std::set<std::string, std::less<>> counted = {"/grpc.health.v1.Health/Check",
                                                "/grpc.health.v1.Health/Watch"};
  for (const auto& [method, access] : CaptureControlMethodAccess()) counted.insert(method);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(options.control_address, credentials, &port);
  builder.RegisterService(control_service.get());
  // No token needed (common/rpc/health_service.h).
  builder.RegisterService(health.get());
  builder.experimental().SetInterceptorCreators(rpc::RequestMetricsInterceptors(counted));
  control_server = builder.BuildAndStart();
  if (!control_server || port == 0) {
    return absl::UnavailableError(
        absl::StrCat("cannot listen on --control ", options.control_address));
  }
  const std::string host = options.control_address.substr(0, options.control_address.rfind(':'));
  bound_control = absl::StrCat(host, ":", port);
  logger.Info("control_listening", {{"address", bound_control}},
              absl::StrCat("control service listening on ", bound_control));
  if (!options.control_port_file.empty()) {
    RETURN_IF_ERROR(WriteFileAtomically(options.control_port_file, bound_control + "\n"));
  }
  return absl::OkStatus();
}

void Daemon::Impl::ResumeUnfinished() {
  for (const std::string& dir : ListUnfinishedTakes(options.spool_dir)) {
    absl::StatusOr<std::unique_ptr<TakeRecorder>> opened =
        TakeRecorder::ResumeUnfinished(channel, recorder_options, dir);
    if (!opened.ok()) {
      logger.Error("take_resume_failed", {{"spool", dir}, {"error", opened.status().message()}},
                   absl::StrCat("cannot resume the spooled take in ", dir));
      continue;
    }
    std::shared_ptr<TakeRecorder> resumed_take = std::move(*opened);
    logger.Info("take_resumed", {{"take_id", resumed_take->take_id()}},
                absl::StrCat("resuming the upload of spooled take ", resumed_take->take_id()));
    std::lock_guard<std::mutex> lock(mutex);
    resumed.insert(resumed_take.get());
    draining.push_back(std::move(resumed_take));
  }
}

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

bool Daemon::Impl::AllSensorsGone() {
  std::lock_guard<std::mutex> lock(mutex);
  return std::all_of(sensors.begin(), sensors.end(),
                     [](const auto& e) { return e->state == v1::SENSOR_STATE_GONE; });
}

void Daemon::Impl::Tick() {
  if (stop_requested) {
    io.stop();
    return;
  }
  {
    std::unique_lock<std::mutex> lock(sync_mutex, std::try_to_lock);
    if (lock.owns_lock()) {
      RecordLocked(sync->Expire(WallNowNs(), kStallNs));
      SnapshotLocked(false);
    }
  }
  if (AnchoringDue()) FinishAnchoring();
  std::shared_ptr<TakeRecorder> current;
  double max_seconds = 0;
  int64_t started_ns = 0;
  std::vector<std::shared_ptr<TakeRecorder>> finished;
  {
    std::lock_guard<std::mutex> lock(mutex);
    current = take;
    max_seconds = take_max_seconds;
    started_ns = take_started_steady_ns;
    for (auto it = draining.begin(); it != draining.end();) {
      if ((*it)->done()) {
        finished.push_back(*it);
        it = draining.erase(it);
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
    std::lock_guard<std::mutex> lock(mutex);
    draining.erase(std::remove(draining.begin(), draining.end(), current), draining.end());
  } else if (current && max_seconds > 0 && NsToSeconds(SteadyNowNs() - started_ns) >= max_seconds) {
    (void)StopTake("max seconds reached", /*flush=*/false);
  }
  for (const auto& recorder : finished) {
    recorder->WaitDone(0);  // Removes the spool folder of a closed take.
    const absl::Status result = recorder->result();
    {
      std::lock_guard<std::mutex> lock(mutex);
      reconnects_finished += recorder->Stats().uplink.reconnects;
    }
    if (result.ok()) {
      logger.Info("take_durable", {{"take_id", recorder->take_id()}},
                  absl::StrCat("take ", recorder->take_id(), " is durable on the server"));
    } else {
      logger.Error("take_failed", {{"take_id", recorder->take_id()}, {"error", result.message()}},
                   absl::StrCat("take ", recorder->take_id(), " failed; its spool stays on disk"));
    }
    if (recorder == once_take) {
      once_result = result;
      io.stop();
    }
  }
  if (options.verbose && SteadyNowNs() - last_log_steady_ns >= kNanosPerSecond) {
    last_log_steady_ns = SteadyNowNs();
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
}

void Daemon::Impl::StopSensors() {
  std::vector<Sensor*> all;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& entry : sensors) all.push_back(entry->sensor.get());
  }
  for (Sensor* sensor : all) sensor->Stop();
}

void Daemon::Impl::RescanHardware() {
  std::vector<SourceSpec> hardware;
  for (const SourceSpec& spec : options.sources) {
    if (spec.backend != "playback") hardware.push_back(spec);
  }
  if (hardware.empty()) return;
  std::set<std::string> streaming;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& entry : sensors) {
      if (entry->state == v1::SENSOR_STATE_STREAMING) {
        streaming.insert(entry->info.backend() + "|" + entry->info.serial() + "|" +
                         entry->info.uri());
      }
    }
  }
  SourceOptions source_options;
  source_options.fast = options.fast;
  source_options.loop = options.loop;
  for (const SourceSpec& spec : hardware) {
    absl::StatusOr<SensorList> opened = OpenSources({spec}, source_options);
    if (!opened.ok()) continue;  // Nothing new there (or the device is busy).
    SensorList fresh;
    for (auto& sensor : *opened) {
      const v1::SensorInfo info = sensor->info();
      if (!streaming.count(info.backend() + "|" + info.serial() + "|" + info.uri())) {
        fresh.push_back(std::move(sensor));
      }
    }
    if (absl::Status s = AddSensors(std::move(fresh)); !s.ok()) {
      logger.Error("hotplug_failed", {{"error", s.message()}}, "new sensors could not be added");
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
    std::lock_guard<std::mutex> lock(sync_mutex);
    sync_summary = sync->Summary();
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
  std::shared_ptr<TakeRecorder> recorder;
  int64_t reconnects = 0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    recorder = last_take;
    reconnects = reconnects_finished;
    for (const auto& r : draining) reconnects += r->Stats().uplink.reconnects;
    if (take) reconnects += take->Stats().uplink.reconnects;
  }
  if (recorder) {
    const TakeStats stats = recorder->Stats();
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
  impl_->StopHealth();  // Ends the health watches the shutdown would wait for.
  if (impl_->control_server) impl_->control_server->Shutdown();
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
  impl->channel = MakeIngestChannel(options.server_address, options.uplink);
  impl->recorder_options.spool_root = options.spool_dir;
  impl->recorder_options.spool_max_bytes = options.spool_max_mb << 20;
  impl->recorder_options.uplink = options.uplink;
  // Recordings can wait for the server; live sensors cannot.
  impl->recorder_options.wait_when_full =
      std::all_of(options.sources.begin(), options.sources.end(),
                  [](const SourceSpec& s) { return s.backend == "playback"; });
  if (impl->recorder_options.wait_when_full) {
    impl->options.anchor.queued_frames = impl->options.anchor.frames;
  }
  ASSIGN_OR_RETURN(impl->sync, SyncGroup::Create(options.sync));
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
  Impl& d = *impl_;
  SourceOptions source_options;
  source_options.fast = d.options.fast;
  source_options.loop = d.options.loop;
  ASSIGN_OR_RETURN(SensorList opened, OpenSources(d.options.sources, source_options));
  RETURN_IF_ERROR(d.AddSensors(std::move(opened)));
  if (d.AllSensorsGone()) {
    d.StopSensors();
    return absl::FailedPreconditionError("no sensor streams");
  }
  // The control address (and its file) appear once the sensors stream.
  if (absl::Status s = d.StartControl(this); !s.ok()) {
    d.StopSensors();
    return s;
  }
  d.ResumeUnfinished();
  if (d.options.once) {
    v1::StartTakeRequest request;
    request.set_name(d.options.take_name);
    request.set_max_seconds(d.options.max_seconds);
    absl::StatusOr<std::string> take_id = d.StartTake(request);
    if (!take_id.ok()) {
      d.StopSensors();
      return take_id.status();
    }
    std::lock_guard<std::mutex> lock(d.mutex);
    d.once_take = d.take;
  }
  d.ArmSignals();
  d.ArmTimer();
  // USB hotplug for hardware sources: arrivals rescan the backends, and a
  // departure is logged (the sensor's own stream ends by itself). Without
  // USB access (e.g. a container without /dev/bus/usb) the daemon runs on.
  std::unique_ptr<UsbHotplugMonitor> hotplug;
  const bool hardware = std::any_of(d.options.sources.begin(), d.options.sources.end(),
                                    [](const SourceSpec& s) { return s.backend != "playback"; });
  if (hardware) {
    auto monitor = UsbHotplugMonitor::Start([this](const UsbHotplugEvent& event) {
      impl_->logger.Info(
          "usb_event",
          {{"arrived", event.kind == UsbHotplugKind::kArrived}, {"usb_id", event.usb_id()}},
          absl::StrCat("usb: ", event.ToString()));
      OnUsbEvent(UsbEvent{event.kind == UsbHotplugKind::kArrived, event.usb_id(), ""});
    });
    if (monitor.ok()) {
      hotplug = std::move(*monitor);
    } else {
      d.logger.Warn("usb_hotplug_off", {{"error", monitor.status().message()}},
                    "usb hotplug is off: new sensors are not noticed");
    }
  }
  d.io.run();
  hotplug.reset();
  // Draining (or done): probes hear NOT_SERVING from here on.
  d.StopHealth();

  absl::Status result = absl::OkStatus();
  if (d.once_result.has_value() && !d.stop_requested) {
    result = *d.once_result;
    d.StopSensors();
  } else {
    // Shut down: stop the sensors, put what the sync group holds in the
    // take, close it, and wait for the server to make it durable.
    {
      std::lock_guard<std::mutex> lock(d.mutex);
      if (d.take) d.take->StopWaiting();
    }
    d.StopSensors();
    (void)d.StopTake("stopped", /*flush=*/true);
    std::vector<std::shared_ptr<TakeRecorder>> ours;
    {
      std::lock_guard<std::mutex> lock(d.mutex);
      for (const auto& r : d.draining) {
        if (!d.resumed.count(r.get())) ours.push_back(r);
      }
    }
    auto all_done = [&ours] {
      return std::all_of(ours.begin(), ours.end(), [](const auto& r) { return r->done(); });
    };
    d.io.restart();
    const int64_t deadline = SteadyNowNs() + SecondsToNs(d.options.drain_timeout_s);
    while (!all_done() && d.signals_received < 2 && SteadyNowNs() < deadline) {
      d.io.run_for(std::chrono::milliseconds(50));
      d.io.restart();
    }
    for (const auto& r : ours) {
      if (r->done()) {
        r->WaitDone(0);
        if (result.ok()) result = r->result();
        if (r->result().ok()) {
          d.logger.Info("take_durable", {{"take_id", r->take_id()}},
                        absl::StrCat("take ", r->take_id(), " is durable on the server"));
        } else {
          d.logger.Error("take_failed",
                         {{"take_id", r->take_id()}, {"error", r->result().message()}},
                         absl::StrCat("take ", r->take_id(), " failed"));
        }
        continue;
      }
      const TakeStats stats = r->Stats();
      const absl::Status timed_out = absl::DeadlineExceededError(
          absl::StrCat("the server did not make take ", r->take_id(), " durable within ",
                       d.options.drain_timeout_s, " s; ", stats.spool_frame_sets, " frame sets (",
                       stats.spool_bytes, " bytes) stay in the spool ", d.options.spool_dir, "/",
                       r->take_id(), " and are sent when reenactd starts again"));
      if (result.ok()) {
        result = timed_out;  // The caller reports it.
      } else {
        d.logger.Error("take_not_durable",
                       {{"take_id", r->take_id()},
                        {"spool_frame_sets", stats.spool_frame_sets},
                        {"spool_bytes", stats.spool_bytes}},
                       timed_out.message());
      }
    }
  }
  {
    std::lock_guard<std::mutex> lock(d.mutex);
    if (d.take) d.take->Abort();
    for (const auto& r : d.draining) {
      if (r->done()) {
        r->WaitDone(0);  // Removes the spool folder of a closed take.
      } else {
        r->Abort();
      }
    }
  }
  d.WriteStats(result);
  d.live.Close();  // Ends the StreamFrames calls.
  if (d.control_server)
    d.control_server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
  return result;
}

void Daemon::RequestStop() {
  impl_->stop_requested = true;
  boost::asio::post(impl_->io, [this] { impl_->io.stop(); });
}

std::string Daemon::control_address() const { return impl_->bound_control; }

std::string Daemon::metrics_address() const { return impl_->bound_metrics; }

std::vector<v1::SensorInfo> Daemon::ListSensors() { return impl_->ListSensors(); }

absl::StatusOr<std::string> Daemon::StartTake(const v1::StartTakeRequest& request) {
  return impl_->StartTake(request);
}

absl::StatusOr<v1::StopTakeResponse> Daemon::StopTake() {
  return impl_->StopTake("stopped", /*flush=*/false);
}

v1::DaemonStatus Daemon::Status() { return impl_->Status(); }

absl::StatusOr<uint64_t> Daemon::SubscribeFrames(const v1::StreamFramesRequest& request,
                                                 LiveFrames::Callback on_set) {
  std::set<std::string> known;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    for (const auto& entry : impl_->sensors) known.insert(entry->info.sensor_id());
  }
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

void Daemon::OnUsbEvent(const UsbEvent& event) {
  if (!event.arrived) return;
  boost::asio::post(impl_->io, [this] { impl_->RescanHardware(); });
}

}  // namespace reenact::capture
