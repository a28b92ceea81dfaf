#include "clients/sdk/reenactment_source.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <utility>

#include "absl/strings/str_cat.h"
#include "clients/sdk/reenactments_client.h"
#include "common/base/status_macros.h"
#include "common/io/reenactment_convert.h"

namespace reenact::client {
namespace {

namespace fs = std::filesystem;

// The summary the server would give of `data` stored at `path`.
v1::ReenactmentSummary SummaryOf(const ReenactmentData& data, const std::string& path) {
  v1::ReenactmentSummary summary;
  *summary.mutable_info() = data.info;
  std::error_code ec;
  const auto bytes = fs::file_size(path, ec);
  summary.set_file_bytes(ec ? 0 : static_cast<int64_t>(bytes));
  summary.set_part_count(static_cast<int32_t>(data.parts.size()));
  summary.set_keyframe_count(static_cast<int32_t>(data.keyframes.size()));
  return summary;
}

void NewestFirst(std::vector<v1::ReenactmentSummary>* list) {
  std::stable_sort(list->begin(), list->end(), [](const auto& a, const auto& b) {
    return a.info().created_unix_ns() > b.info().created_unix_ns();
  });
}

class LocalSource final : public ReenactmentSource {
 public:
  explicit LocalSource(std::string path) : path_(std::move(path)) {}

  absl::StatusOr<std::vector<v1::ReenactmentSummary>> List() const override {
    std::vector<v1::ReenactmentSummary> out;
    ASSIGN_OR_RETURN(const std::vector<std::string> files, Files());
    for (const std::string& file : files) {
      // A damaged file is left out of the list, not an error of the whole.
      absl::StatusOr<ReenactmentData> data = ReadReenactmentFile(file, /*skip_keyframes=*/true);
      if (data.ok()) out.push_back(SummaryOf(*data, file));
    }
    NewestFirst(&out);
    return out;
  }

  absl::StatusOr<Reenactment> Load(const std::string& reenactment_id, bool skip_keyframes,
                                   const ProgressCallback& progress) const override {
    ASSIGN_OR_RETURN(const std::vector<std::string> files, Files());
    // The file named after the id first, then any file holding it.
    for (const std::string& file : files) {
      if (fs::path(file).stem() == reenactment_id) return ReadReenactment(file, skip_keyframes);
    }
    for (const std::string& file : files) {
      absl::StatusOr<ReenactmentData> data = ReadReenactmentFile(file, /*skip_keyframes=*/true);
      if (data.ok() && data->info.reenactment_id() == reenactment_id) {
        return ReadReenactment(file, skip_keyframes);
      }
    }
    return absl::NotFoundError(absl::StrCat("no reenactment ", reenactment_id, " in ", Describe()));
  }

  std::string Describe() const override {
    std::error_code ec;
    return absl::StrCat(fs::is_directory(path_, ec) ? "folder " : "file ", path_);
  }

 private:
  absl::StatusOr<std::vector<std::string>> Files() const {
    std::error_code ec;
    if (!fs::exists(path_, ec)) {
      return absl::NotFoundError(absl::StrCat(path_, ": no such file or folder"));
    }
    if (!fs::is_directory(path_, ec)) return std::vector<std::string>{path_};
    std::vector<std::string> files;
    for (const auto& entry : fs::directory_iterator(path_, ec)) {
      if (entry.is_regular_file(ec) && entry.path().extension() == ".reen") {
        files.push_back(entry.path().string());
      }
    }
    if (ec) return absl::UnavailableError(absl::StrCat(path_, ": ", ec.message()));
    std::sort(files.begin(), files.end());
    return files;
  }

  std::string path_;
};

class RemoteSource final : public ReenactmentSource {
 public:
  explicit RemoteSource(const RemoteSourceOptions& options)
      : options_(options), client_(options.connection) {}

  absl::StatusOr<std::vector<v1::ReenactmentSummary>> List() const override {
    return client_.List();
  }

  absl::StatusOr<Reenactment> Load(const std::string& reenactment_id, bool skip_keyframes,
                                   const ProgressCallback& progress) const override {
    ASSIGN_OR_RETURN(const v1::ReenactmentSummary summary, client_.Get(reenactment_id));
    const std::string cached = CachePath(reenactment_id);
    if (!cached.empty()) {
      // A cached copy serves when it is the same reenactment and has what
      // was asked for (keyframes, unless skipped).
      absl::StatusOr<Reenactment> data = ReadReenactment(cached, skip_keyframes);
      if (data.ok() && data->info.created_unix_ns == summary.info().created_unix_ns() &&
          (skip_keyframes ||
           static_cast<int>(data->keyframes.size()) == summary.keyframe_count())) {
        return data;
      }
    }
    ASSIGN_OR_RETURN(Reenactment data, client_.Fetch(reenactment_id, skip_keyframes, progress));
    if (!cached.empty() && (!skip_keyframes || summary.keyframe_count() == 0)) {
      // Only whole reenactments are cached; a failed write costs the cache
      // only (WriteReenactment leaves no partial file).
      std::error_code ec;
      fs::create_directories(options_.cache_dir, ec);
      // A cache made before (or by another program) may be open to others:
      // it holds people's reenactments.
      fs::permissions(options_.cache_dir, fs::perms::owner_all, ec);
      (void)WriteReenactment(data, cached);
      fs::permissions(cached, fs::perms::owner_read | fs::perms::owner_write, ec);
    }
    return data;
  }

  std::string Describe() const override {
    return absl::StrCat("server ", options_.connection.address,
                        options_.cache_dir.empty() ? "" : " (cache " + options_.cache_dir + ")");
  }

 private:
  std::string CachePath(const std::string& reenactment_id) const {
    if (options_.cache_dir.empty()) return "";
    // Ids are [A-Za-z0-9_-]; anything else is not cached.
    for (char c : reenactment_id) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') return "";
    }
    return (fs::path(options_.cache_dir) / (reenactment_id + ".reen")).string();
  }

  RemoteSourceOptions options_;
  ReenactmentsClient client_;
};

}  // namespace

std::unique_ptr<ReenactmentSource> NewRemoteSource(const RemoteSourceOptions& options) {
  return std::make_unique<RemoteSource>(options);
}

absl::StatusOr<std::unique_ptr<ReenactmentSource>> NewLocalSource(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file or folder"));
  }
  return std::unique_ptr<ReenactmentSource>(std::make_unique<LocalSource>(path));
}

absl::StatusOr<std::unique_ptr<ReenactmentSource>> OpenReenactmentSource(
    const std::string& spec, const std::string& cache_dir, const rpc::ClientSecurity& security) {
  constexpr std::string_view kGrpc = "grpc:";
  if (spec.rfind(kGrpc, 0) == 0) {
    RemoteSourceOptions options;
    options.connection.address = spec.substr(kGrpc.size());
    options.connection.security = security;
    if (options.connection.address.empty()) {
      return absl::InvalidArgumentError("grpc: needs HOST:PORT");
    }
    options.cache_dir = cache_dir;
    return NewRemoteSource(options);
  }
  return NewLocalSource(spec);
}

absl::StatusOr<Reenactment> LoadReenactmentOrOnly(ReenactmentSource& source, const std::string& id,
                                                  const std::string& id_flag,
                                                  std::string* loaded_id) {
  std::string chosen = id;
  if (chosen.empty()) {
    ASSIGN_OR_RETURN(const std::vector<v1::ReenactmentSummary> list, source.List());
    if (list.size() != 1) {
      return absl::FailedPreconditionError(absl::StrCat(
          id_flag, " is required: ", source.Describe(), " has ", list.size(), " reenactments"));
    }
    chosen = list.front().info().reenactment_id();
  }
  if (loaded_id != nullptr) *loaded_id = chosen;
  return source.Load(chosen);
}

std::string DefaultReenactmentCacheDir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg != '\0') {
    return (fs::path(xdg) / "reenact").string();
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return (fs::path(home) / ".cache" / "reenact").string();
  }
  std::error_code ec;
  return (fs::temp_directory_path(ec) / "reenact-cache").string();
}

}  // namespace reenact::client
