// Where the apps (viewer, mirror) get reenactments from: one interface,
// whether the reenactments live on a server or in files on this machine.
//
//   auto source = client::OpenReenactmentSource("grpc:127.0.0.1:50051");  // or a folder
//   auto list = (*source)->List();
//   auto data = (*source)->Load(list->front().info().reenactment_id());
//
// Remote: the server's Reenactments service (List, Get, Fetch); what was
// fetched is kept in a cache folder as reenactment files and read from there
// next time, as long as the server still has the same reenactment (same id
// and creation time). Local: the reenactment files (*.reen) of a folder, or
// one file (the files reenact-worker and the cache write).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "clients/sdk/takes_client.h"
#include "common/base/progress.h"
#include "common/model/reenactment.h"
#include "reenact/v1/reenactments_service.pb.h"

namespace reenact::client {

class ReenactmentSource {
 public:
  virtual ~ReenactmentSource() = default;

  // Every reenactment the source has, newest first (by creation time).
  virtual absl::StatusOr<std::vector<v1::ReenactmentSummary>> List() const = 0;
  // One reenactment, whole and validated. `skip_keyframes` may leave the
  // texture keyframes out (rigid reenactments drawn with baked textures).
  // NotFound for an unknown id.
  virtual absl::StatusOr<Reenactment> Load(const std::string& reenactment_id,
                                           bool skip_keyframes = false,
                                           const ProgressCallback& progress = {}) const = 0;
  // E.g. "server 127.0.0.1:50051 (cache /home/u/.cache/reenact)" or
  // "folder /data/reenactments", for messages.
  virtual std::string Describe() const = 0;
};

struct RemoteSourceOptions {
  ConnectionOptions connection;
  // Cache folder (created when missing); empty: no cache.
  std::string cache_dir;
};

// The server's reenactments, cached in options.cache_dir.
std::unique_ptr<ReenactmentSource> NewRemoteSource(const RemoteSourceOptions& options);

// The reenactment files of `path`: a folder (its *.reen files) or one
// file. NotFound when it does not exist.
absl::StatusOr<std::unique_ptr<ReenactmentSource>> NewLocalSource(const std::string& path);

// "grpc:HOST:PORT" (remote, cached in `cache_dir`) or a path (local).
absl::StatusOr<std::unique_ptr<ReenactmentSource>> OpenReenactmentSource(
    const std::string& spec, const std::string& cache_dir = "",
    const rpc::ClientSecurity& security = {});

// Reenactment `id` of `source`, or with `id` empty the only one it holds
// (FailedPrecondition when it holds none or several, saying that
// `id_flag`, e.g. "--teacher ID", is required). The id loaded goes to
// *loaded_id when given.
absl::StatusOr<Reenactment> LoadReenactmentOrOnly(ReenactmentSource& source, const std::string& id,
                                                  const std::string& id_flag,
                                                  std::string* loaded_id = nullptr);

// The default cache folder: $XDG_CACHE_HOME/reenact, else
// $HOME/.cache/reenact, else a folder under the system's temp folder.
std::string DefaultReenactmentCacheDir();

}  // namespace reenact::client
