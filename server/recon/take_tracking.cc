#include "server/recon/take_tracking.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <string_view>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_format.h"
#include "common/io/take.h"
#include "common/io/take_convert.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/pose_net.h"
#include "common/tracking/tracking_proto.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact::recon {
namespace {

namespace fs = std::filesystem;

// First bytes of the file of tracked skeletons (version 1 of its layout).
constexpr char kMagic[] = "REENACT-TRACKED-SKELETONS-1\n";
constexpr size_t kMagicSize = sizeof(kMagic) - 1;
// Bytes of the take's head and tail that its fingerprint reads.
constexpr int64_t kFingerprintSpan = 1 << 20;
// Largest file of tracked skeletons read (a skeleton is about 1.5 kB: an
// hour of three sensors at 30 fps is 0.5 GB).
constexpr uint64_t kMaxSkeletonsFileBytes = uint64_t{1} << 30;
// Largest tracker model file whose checksum is taken.
constexpr uint64_t kMaxModelFileBytes = uint64_t{1} << 30;

// The skeletons tracked from a take, by sensor and frame index.
using Tracked = std::map<std::string, std::map<int64_t, std::vector<v1::Skeleton>>>;

void PutU32(uint32_t v, std::string* out) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

bool GetU32(std::string_view* in, uint32_t* v) {
  if (in->size() < 4) return false;
  *v = 0;
  for (int i = 0; i < 4; ++i)
    *v |= static_cast<uint32_t>(static_cast<uint8_t>((*in)[i])) << (8 * i);
  in->remove_prefix(4);
  return true;
}

bool GetBytes(std::string_view* in, std::string_view* bytes) {
  uint32_t n = 0;
  if (!GetU32(in, &n) || in->size() < n) return false;
  *bytes = in->substr(0, n);
  in->remove_prefix(n);
  return true;
}

// Size and checksums of the take's first and last kFingerprintSpan bytes: an
// MCAP take's head holds its header and first chunk, its tail the summary
// (every chunk's offset, length and CRC), so another take — a take deleted
// and uploaded again under its id — differs there.
absl::StatusOr<std::string> TakeFingerprint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  const uint64_t size = fs::file_size(path, ec);
  if (!in || ec) return absl::NotFoundError(absl::StrCat(path, ": cannot read the take"));
  const auto span = static_cast<int64_t>(std::min<uint64_t>(size, kFingerprintSpan));
  std::string head(span, '\0'), tail(span, '\0');
  in.read(head.data(), span);
  in.seekg(static_cast<std::streamoff>(size - span));
  in.read(tail.data(), span);
  if (!in) return absl::DataLossError(absl::StrCat(path, ": reading the take failed"));
  return absl::StrCat("take ", size, " bytes, head crc ", mcap_format::Crc32(head), ", tail crc ",
                      mcap_format::Crc32(tail));
}

// What the default tracker loads, by size and checksum: skeletons tracked by
// another model (the shipped one retrained, $REENACT_TRACKER_MODEL) are
// tracked again.
absl::StatusOr<std::string> TrackerFingerprint(const tracking::BodyTrackerOptions& options) {
  const bool network = options.method == tracking::TrackerMethod::kNetwork;
  std::string path = network ? options.model_path : options.forest_path;
  if (path.empty()) path = network ? tracking::DefaultPoseNetPath() : tracking::DefaultForestPath();
  absl::StatusOr<std::string> bytes = ReadFileToString(path, kMaxModelFileBytes);
  if (!bytes.ok()) {
    return absl::Status(bytes.status().code(),
                        absl::StrCat("the tracker's model ", path, ": ", bytes.status().message()));
  }
  return absl::StrCat(tracking::kTrackerSource, network ? " network " : " forest ", bytes->size(),
                      " bytes, crc ", mcap_format::Crc32(*bytes));
}

// The file of tracked skeletons: kMagic, the key (the take's and the
// tracker's fingerprints), the sensors tracked (each with its id), the
// skeletons (each a v1::Skeleton naming its sensor and frame), then the
// CRC-32 of all before it. Integers are 32-bit little-endian; strings and
// messages go after their length.
std::string EncodeTracked(const std::string& key, const Tracked& tracked) {
  std::string out(kMagic, kMagicSize);
  PutU32(static_cast<uint32_t>(key.size()), &out);
  out += key;
  PutU32(static_cast<uint32_t>(tracked.size()), &out);
  for (const auto& [sensor_id, frames] : tracked) {
    PutU32(static_cast<uint32_t>(sensor_id.size()), &out);
    out += sensor_id;
    uint32_t count = 0;
    for (const auto& [index, skeletons] : frames) count += static_cast<uint32_t>(skeletons.size());
    PutU32(count, &out);
    for (const auto& [index, skeletons] : frames) {
      for (const v1::Skeleton& skeleton : skeletons) {
        const std::string bytes = skeleton.SerializeAsString();
        PutU32(static_cast<uint32_t>(bytes.size()), &out);
        out += bytes;
      }
    }
  }
  PutU32(mcap_format::Crc32(out), &out);
  return out;
}

// The skeletons of a file EncodeTracked wrote with `key`; an error saying
// why the file is not to be trusted otherwise.
absl::StatusOr<Tracked> DecodeTracked(std::string_view data, const std::string& key) {
  const auto corrupt = [](std::string_view what) {
    return absl::DataLossError(absl::StrCat("corrupt: ", std::string(what)));
  };
  if (data.size() < kMagicSize + 4 || data.substr(0, kMagicSize) != kMagic) {
    return corrupt("not a file of tracked skeletons");
  }
  std::string_view crc_bytes = data.substr(data.size() - 4);
  uint32_t crc = 0;
  GetU32(&crc_bytes, &crc);
  data.remove_suffix(4);
  if (mcap_format::Crc32(data) != crc) return corrupt("checksum mismatch");
  data.remove_prefix(kMagicSize);
  std::string_view stored_key;
  if (!GetBytes(&data, &stored_key)) return corrupt("no key");
  if (stored_key != key) {
    return absl::FailedPreconditionError(
        absl::StrCat("stale: made from ", std::string(stored_key), "; now ", key));
  }
  uint32_t sensors = 0;
  if (!GetU32(&data, &sensors)) return corrupt("no sensor count");
  Tracked tracked;
  for (uint32_t s = 0; s < sensors; ++s) {
    std::string_view sensor_id;
    uint32_t count = 0;
    if (!GetBytes(&data, &sensor_id) || !GetU32(&data, &count)) return corrupt("short sensor");
    auto& frames = tracked[std::string(sensor_id)];
    for (uint32_t k = 0; k < count; ++k) {
      std::string_view bytes;
      v1::Skeleton skeleton;
      if (!GetBytes(&data, &bytes) ||
          !skeleton.ParseFromArray(bytes.data(), static_cast<int>(bytes.size())) ||
          skeleton.sensor_id() != sensor_id) {
        return corrupt(absl::StrCat("skeleton ", k, " of sensor ", std::string(sensor_id)));
      }
      frames[skeleton.frame_index()].push_back(std::move(skeleton));
    }
  }
  if (!data.empty()) return corrupt("trailing bytes");
  return tracked;
}

// Writes the file through a name of this process's own and a rename:
// concurrent jobs on the same take each write whole files, and the last
// rename wins.
absl::Status WriteTracked(const std::string& path, const std::string& contents) {
  const std::string mine = absl::StrCat(path, ".", ::getpid(), ".new");
  absl::Status written = WriteFileAtomically(mine, contents);
  std::error_code ec;
  if (written.ok()) {
    fs::rename(mine, path, ec);
    if (!ec) return absl::OkStatus();
    written = absl::UnavailableError(absl::StrCat("rename to ", path, ": ", ec.message()));
  }
  fs::remove(mine, ec);
  return written;
}

bool HasAnySkeleton(const RecordedTake& take) {
  return std::any_of(take.frames.begin(), take.frames.end(),
                     [](const SensorFrame& f) { return !f.skeletons.empty(); });
}

// Every sensor's skeletons tracked from the take's depth; `progress` gets
// stage "track" per depth frame (over all sensors).
absl::StatusOr<Tracked> TrackTake(const std::string& path, const RecordedTake& take,
                                  const tracking::BodyTrackerOptions& options,
                                  const ProgressCallback& progress) {
  ASSIGN_OR_RETURN(const std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  int64_t total = 0;
  for (const SensorFrame& f : take.frames) total += f.depth ? 1 : 0;
  int64_t done = 0;
  const auto frame_done = [&]() {
    ++done;
    if (!progress) return true;
    return progress({"track", total > 0 ? static_cast<double>(done) / total : 1.0, done, total});
  };
  Tracked tracked;
  for (const SensorCalibration& sensor : take.sensors) {
    absl::StatusOr<std::map<int64_t, std::vector<v1::Skeleton>>> skeletons =
        tracking::TrackTakeSensor(*reader, sensor.sensor_id, options, frame_done);
    if (!skeletons.ok()) {
      return absl::Status(skeletons.status().code(),
                          absl::StrCat(path, ": tracking: ", skeletons.status().message()));
    }
    tracked[sensor.sensor_id] = *std::move(skeletons);
  }
  return tracked;
}

// Moves the tracked skeletons into the frames they were tracked in.
void AttachSkeletons(const Tracked& tracked, RecordedTake* take) {
  for (SensorFrame& frame : take->frames) {
    const auto sensor = tracked.find(frame.sensor_id);
    if (sensor == tracked.end()) continue;
    const auto found = sensor->second.find(frame.frame_index);
    if (found == sensor->second.end()) continue;
    for (const v1::Skeleton& skeleton : found->second) {
      frame.skeletons.push_back(SkeletonFromProto(skeleton));
    }
  }
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::string TrackedSkeletonsPath(const std::string& take_path) { return take_path + ".skeletons"; }

absl::StatusOr<std::unique_ptr<TakeFrames>> LoadTakeForMethod(
    const std::string& path, const TakeFramesOptions& options,
    const ProgressCallback& load_progress, const ProgressCallback& track_progress,
    const LogCallback& log) {
  RETURN_IF_ERROR(options.Validate());
  RecordedTakeOptions read;
  read.load_color = options.load_color;
  ASSIGN_OR_RETURN(RecordedTake take, ReadRecordedTake(path, read, load_progress));
  if (HasAnySkeleton(take)) return TakeFrames::FromRecording(std::move(take), options, path);

  const auto start = std::chrono::steady_clock::now();
  const tracking::BodyTrackerOptions tracker;
  ASSIGN_OR_RETURN(const std::string take_key, TakeFingerprint(path));
  ASSIGN_OR_RETURN(const std::string tracker_key, TrackerFingerprint(tracker));
  const std::string key = absl::StrCat(take_key, "; ", tracker_key);
  const std::string stored_path = TrackedSkeletonsPath(path);

  absl::StatusOr<Tracked> tracked = absl::NotFoundError("none");
  bool reused = false;
  std::error_code ec;
  if (fs::exists(stored_path, ec)) {
    absl::StatusOr<std::string> bytes = ReadFileToString(stored_path, kMaxSkeletonsFileBytes);
    tracked = bytes.ok() ? DecodeTracked(*bytes, key) : bytes.status();
    reused = tracked.ok();
    // Every sensor of the take must have been tracked.
    for (const SensorCalibration& sensor : take.sensors) {
      if (reused && !tracked->contains(sensor.sensor_id)) {
        tracked = absl::DataLossError(absl::StrCat("no sensor ", sensor.sensor_id));
        reused = false;
      }
    }
    if (!reused && log) {
      log(absl::StrCat("track: ignoring the stored skeletons ", stored_path, " (",
                       tracked.status().message(), "); tracking again"));
    }
  }
  if (!reused) {
    ASSIGN_OR_RETURN(tracked, TrackTake(path, take, tracker, track_progress));
    if (absl::Status kept = WriteTracked(stored_path, EncodeTracked(key, *tracked));
        !kept.ok() && log) {
      log(absl::StrCat("track: the skeletons could not be kept beside the take (", kept.message(),
                       "); later jobs track it again"));
    }
  }
  const double track_s = SecondsSince(start);
  const int sensors = static_cast<int>(take.sensors.size());
  int64_t depth_frames = 0;
  for (const SensorFrame& f : take.frames) depth_frames += f.depth ? 1 : 0;
  int64_t frames_with_people = 0;
  for (const auto& [sensor_id, by_frame] : *tracked) {
    frames_with_people += static_cast<int64_t>(by_frame.size());
  }
  AttachSkeletons(*tracked, &take);
  ASSIGN_OR_RETURN(std::unique_ptr<TakeFrames> frames,
                   TakeFrames::FromRecording(std::move(take), options, path));
  const int found = frames->num_valid_instants();
  const std::string sensors_text = absl::StrCat(sensors, sensors == 1 ? " sensor" : " sensors");
  if (log) {
    log(absl::StrCat("track: ", found, " instants tracked from depth (", sensors_text, "), ",
                     reused ? absl::StrCat("stored skeletons reused from ", stored_path, ", ") : "",
                     track_s, " s"));
  }
  // With max_frames the people may all lie past the instants kept: the
  // method's own error then says that no instant has a skeleton.
  if (frames_with_people == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": no person in this take: the take holds no skeleton and the tracker ",
                     "found nobody in the ", depth_frames, " depth frames of its ", sensors_text));
  }
  return frames;
}

}  // namespace reenact::recon
