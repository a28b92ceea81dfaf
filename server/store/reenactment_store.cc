#include "server/store/reenactment_store.h"

#include <algorithm>
#include <ctime>
#include <filesystem>
#include <random>
#include <system_error>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/io/mcap_reader.h"
#include "common/io/reenactment_file.h"
#include "common/log/log.h"

namespace reenact::server {
namespace {

constexpr char kExtension[] = ".reen";
// WriteReenactmentFile writes through "<path>.tmp".
constexpr char kTempExtension[] = ".reen.tmp";
// Copies in other formats (DerivedPathFor), removed with their reenactment.
constexpr const char* kDerivedExtensions[] = {".glb", ".appearance.mp4"};

bool IsValidReenactmentId(const std::string& id) {
  return !id.empty() && id.size() <= 128 && std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.';
  }) && id.front() != '.';
}

absl::Status CheckId(const std::string& id) {
  if (IsValidReenactmentId(id)) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat("reenactment id \"", id, "\" must be 1..128 characters of [A-Za-z0-9_.-]"));
}

// Reads the file of `id` at `path` into its catalog entry. `full` validates
// the keyframes too (they hold most of the bytes; Open trusts files that Add
// validated and only counts them).
absl::StatusOr<v1::ReenactmentSummary> Summarize(const std::string& id, const std::string& path,
                                                 bool full) {
  ASSIGN_OR_RETURN(const ReenactmentData data, ReadReenactmentFile(path, !full));
  if (data.info.reenactment_id() != id) {
    return absl::InvalidArgumentError(absl::StrCat(
        path, ": holds reenactment \"", data.info.reenactment_id(), "\", not \"", id, "\""));
  }
  v1::ReenactmentSummary summary;
  *summary.mutable_info() = data.info;
  summary.set_part_count(static_cast<int32_t>(data.parts.size()));
  if (full) {
    summary.set_keyframe_count(static_cast<int32_t>(data.keyframes.size()));
  } else {
    ASSIGN_OR_RETURN(const std::unique_ptr<McapReader> mcap, McapReader::Open(path));
    const McapChannel* channel = mcap->FindChannel(kReenactmentKeyframeTopic);
    if (channel != nullptr) {
      const auto& counts = mcap->statistics().channel_message_counts;
      if (auto it = counts.find(channel->id); it != counts.end()) {
        summary.set_keyframe_count(static_cast<int32_t>(it->second));
      }
    }
  }
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return absl::DataLossError(absl::StrCat(path, ": ", ec.message()));
  summary.set_file_bytes(static_cast<int64_t>(size));
  return summary;
}

}  // namespace

absl::StatusOr<std::unique_ptr<ReenactmentStore>> ReenactmentStore::Open(const std::string& dir) {
  RETURN_IF_ERROR(CreateDirectories(dir));
  std::unique_ptr<ReenactmentStore> store(new ReenactmentStore(dir));
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(dir, ": ", ec.message()));
  std::vector<std::filesystem::path> files;
  for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
    if (ec) return absl::DataLossError(absl::StrCat(dir, ": ", ec.message()));
    if (it->is_regular_file(ec)) files.push_back(it->path());
  }
  for (const std::filesystem::path& path : files) {
    const std::string name = path.filename().string();
    if (absl::EndsWith(name, kTempExtension)) {
      // A writer that died half-way; its file was never added.
      std::filesystem::remove(path, ec);
      continue;
    }
    if (!absl::EndsWith(name, kExtension)) {
      // A derived copy (or the temporary file of one) whose reenactment is
      // gone: what it shows was deleted.
      for (const char* extension : kDerivedExtensions) {
        for (const std::string& suffix :
             {std::string(extension), absl::StrCat(extension, ".tmp")}) {
          if (!absl::EndsWith(name, suffix)) continue;
          const std::string id = name.substr(0, name.size() - suffix.size());
          if (suffix != extension || !std::filesystem::exists(store->PathFor(id), ec)) {
            std::filesystem::remove(path, ec);
          }
        }
      }
      continue;
    }
    const std::string id = name.substr(0, name.size() - (sizeof(kExtension) - 1));
    absl::StatusOr<v1::ReenactmentSummary> summary =
        IsValidReenactmentId(id) ? Summarize(id, path.string(), /*full=*/false)
                                 : absl::StatusOr<v1::ReenactmentSummary>(CheckId(id));
    if (!summary.ok()) {
      log::Warn("reenactment_skipped",
                {{"path", path.string()}, {"error", summary.status().message()}},
                "the reenactment store skips a file it cannot read");
      continue;
    }
    store->entries_.emplace(id, *std::move(summary));
  }
  return store;
}

std::string ReenactmentStore::NewId() const {
  thread_local std::mt19937 random(std::random_device{}());
  const std::time_t now = static_cast<std::time_t>(WallNowNs() / kNanosPerSecond);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", &utc);
  for (;;) {
    std::string id = absl::StrFormat("r-%s-%04x", stamp, static_cast<unsigned>(random() & 0xFFFF));
    std::error_code ec;
    std::lock_guard<std::mutex> lock(mutex_);
    if (!entries_.contains(id) && !std::filesystem::exists(PathFor(id), ec) &&
        !std::filesystem::exists(PathFor(id) + ".tmp", ec)) {
      return id;
    }
  }
}

std::string ReenactmentStore::PathFor(const std::string& reenactment_id) const {
  return absl::StrCat(dir_, "/", reenactment_id, kExtension);
}

std::string ReenactmentStore::DerivedPathFor(const std::string& reenactment_id,
                                             const std::string& extension) const {
  return absl::StrCat(dir_, "/", reenactment_id, extension);
}

absl::StatusOr<v1::ReenactmentSummary> ReenactmentStore::Add(const std::string& reenactment_id) {
  RETURN_IF_ERROR(CheckId(reenactment_id));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (entries_.contains(reenactment_id)) {
      return absl::AlreadyExistsError(
          absl::StrCat("reenactment ", reenactment_id, " is already stored"));
    }
  }
  ASSIGN_OR_RETURN(v1::ReenactmentSummary summary,
                   Summarize(reenactment_id, PathFor(reenactment_id), /*full=*/true));
  std::lock_guard<std::mutex> lock(mutex_);
  if (!entries_.emplace(reenactment_id, summary).second) {
    return absl::AlreadyExistsError(
        absl::StrCat("reenactment ", reenactment_id, " is already stored"));
  }
  return summary;
}

std::vector<v1::ReenactmentSummary> ReenactmentStore::List(const std::string& take_id) const {
  std::vector<v1::ReenactmentSummary> out;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [id, summary] : entries_) {
      if (take_id.empty() || summary.info().take_id() == take_id) out.push_back(summary);
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    if (a.info().created_unix_ns() != b.info().created_unix_ns()) {
      return a.info().created_unix_ns() > b.info().created_unix_ns();
    }
    return a.info().reenactment_id() > b.info().reenactment_id();
  });
  return out;
}

absl::StatusOr<v1::ReenactmentSummary> ReenactmentStore::Get(
    const std::string& reenactment_id) const {
  RETURN_IF_ERROR(CheckId(reenactment_id));
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(reenactment_id);
  if (it == entries_.end()) {
    return absl::NotFoundError(absl::StrCat("no reenactment ", reenactment_id));
  }
  return it->second;
}

absl::Status ReenactmentStore::Delete(const std::string& reenactment_id) {
  RETURN_IF_ERROR(CheckId(reenactment_id));
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(reenactment_id);
  if (it == entries_.end()) {
    return absl::NotFoundError(absl::StrCat("no reenactment ", reenactment_id));
  }
  std::error_code ec;
  std::filesystem::remove(PathFor(reenactment_id), ec);
  if (ec) {
    return absl::InternalError(
        absl::StrCat(PathFor(reenactment_id), ": cannot remove: ", ec.message()));
  }
  entries_.erase(it);
  for (const char* extension : kDerivedExtensions) {
    std::filesystem::remove(DerivedPathFor(reenactment_id, extension), ec);
  }
  return absl::OkStatus();
}

}  // namespace reenact::server
