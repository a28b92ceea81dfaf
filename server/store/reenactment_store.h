// The reenactments of a server: one reenactment file per reenactment
// (common/io/reenactment_file.h) in DATA/reenactments/<id>.reen, indexed in
// memory from the files' infos when the store opens. Thread-safe.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "reenact/v1/reenactments_service.pb.h"

namespace reenact::server {

class ReenactmentStore {
 public:
  // Opens (creating) `dir` and indexes every *.reen file in it; files that do
  // not read are logged and left alone (never deleted), temporary files of
  // writers that died are removed.
  static absl::StatusOr<std::unique_ptr<ReenactmentStore>> Open(const std::string& dir);

  // A fresh id, "r-YYYYMMDD-HHMMSS-xxxx".
  std::string NewId() const;
  // Where the file of `reenactment_id` lives (a worker writes it there).
  std::string PathFor(const std::string& reenactment_id) const;
  // Where a copy of it in another format may be kept (the HTTP front's
  // glTF export ".glb" and appearance video ".appearance.mp4"): beside the
  // file, so that Delete removes it with the reenactment and Open removes
  // copies whose reenactment is gone.
  std::string DerivedPathFor(const std::string& reenactment_id, const std::string& extension) const;

  // Indexes the file a worker finished at PathFor(id): reads and validates
  // it. InvalidArgument / DataLoss when it is not a valid reenactment (the
  // file is then left for inspection); AlreadyExists for a known id.
  absl::StatusOr<v1::ReenactmentSummary> Add(const std::string& reenactment_id);

  // Newest first; only those of `take_id` when it is not empty.
  std::vector<v1::ReenactmentSummary> List(const std::string& take_id = "") const;
  // NotFound for an unknown id, InvalidArgument for a malformed one.
  absl::StatusOr<v1::ReenactmentSummary> Get(const std::string& reenactment_id) const;
  // Removes the file, its derived copies and the entry. NotFound for an
  // unknown id, InvalidArgument for a malformed one.
  absl::Status Delete(const std::string& reenactment_id);

  const std::string& dir() const { return dir_; }

 private:
  explicit ReenactmentStore(std::string dir) : dir_(std::move(dir)) {}
  std::string dir_;
  mutable std::mutex mutex_;
  std::map<std::string, v1::ReenactmentSummary> entries_;
};

}  // namespace reenact::server
