// Who may call what: bearer tokens with roles, checked by the servers
// (reenact-server, reenactd's control service) on every call.
//
// A token file is JSON:
//   {"tokens": [{"name": "studio-a", "role": "capture", "sha256": "<hex>"}]}
// It holds the SHA-256 of each token, never a token itself. `reenact auth
// add` (AddToken) mints a random token, appends its line and prints the
// token once. Clients send "authorization: Bearer <token>" (see
// common/rpc/channel.h).
//
// Roles grant kinds of access:
//   viewer:  read (list, get, download, fetch, follow, watch, status)
//   capture: ingest (a capture daemon's uplink; starting and stopping takes)
//   coach:   read, plus manage (submit and cancel jobs, delete takes and
//            reenactments, start and stop takes)
//   admin:   everything, and may resume any credential's take.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <grpcpp/security/auth_metadata_processor.h>
#include <grpcpp/server_context.h>

#include "absl/strings/string_view.h"

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact::rpc {

enum class Role { kViewer, kCapture, kCoach, kWorker, kAdmin };

// "viewer", "capture", "coach", "worker", "admin".
absl::string_view RoleName(Role role);
// InvalidArgument for any other text.
absl::StatusOr<Role> ParseRole(absl::string_view name);

// What an RPC does; a role grants a set of these.
enum Access : uint32_t {
  kRead = 1u << 0,
  kIngest = 1u << 1,
  kManage = 1u << 2,
  // Leasing and running jobs (the Work service).
  kWork = 1u << 3,
};
// The accesses `role` grants (admin: all).
uint32_t RoleAccess(Role role);

// The caller of one RPC.
struct Principal {
  // The token's name in the token file; empty for the anonymous caller of a
  // server that runs without tokens.
  std::string name{};
  Role role = Role::kAdmin;
  bool anonymous() const { return name.empty(); }
  bool admin() const { return role == Role::kAdmin; }
};

// Lowercase hex SHA-256 of `bytes`.
std::string Sha256Hex(absl::string_view bytes);

class TokenTable {
 public:
  // Reads and checks a token file: valid JSON of the form above, every name
  // 1..64 printable characters and unique, every role known, every sha256 64
  // hex digits. InvalidArgument naming the entry; NotFound when missing. A
  // file that others may read or write is refused (PermissionDenied): it
  // decides who reaches people's recordings.
  static absl::StatusOr<TokenTable> Load(const std::string& path);
  // From the file's text (no permission check).
  static absl::StatusOr<TokenTable> Parse(absl::string_view json, absl::string_view origin);

  // The principal whose token this is, compared in constant time per entry.
  std::optional<Principal> Find(absl::string_view token) const;
  // Adds an entry held in memory only (a server's own workers get one);
  // AlreadyExists when the name is taken.
  absl::Status Add(const std::string& name, Role role, absl::string_view token);
  size_t size() const { return entries_.size(); }
  // Each entry's name and role, in the file's order.
  std::vector<std::pair<std::string, Role>> Names() const;

 private:
  struct Entry {
    std::string name;
    Role role;
    std::string sha256;
  };
  std::vector<Entry> entries_;
};

// A new random token (32 bytes from the system's random source, as 64 hex
// digits, prefixed "rnt_").
absl::StatusOr<std::string> NewToken();

// Mints a token for `name` with `role`, appends it to the token file at
// `path` (created with mode 0600 when missing; rewritten atomically) and
// returns the token, which is stored nowhere in clear. AlreadyExists when
// the name is taken; the file's own errors otherwise.
absl::StatusOr<std::string> AddToken(const std::string& path, Role role, const std::string& name);

// `reenact auth remove`: deletes the entry named `name` from the token file
// (checked as Load does, rewritten 0600 atomically). NotFound when it has
// none. A running server forgets the token on SIGHUP or its next start.
absl::Status RemoveToken(const std::string& path, const std::string& name);

// Checks each call against the token table and the access its method needs.
class Authorizer {
 public:
  // Methods ("/reenact.v1.Takes/List") and the accesses of which any one
  // suffices; a method missing from the table is for admins only.
  using MethodTable = std::map<std::string, uint32_t, std::less<>>;

  // Without tokens every caller is the anonymous admin (loopback, or a
  // server started with --insecure).
  Authorizer(std::optional<TokenTable> tokens, MethodTable methods);

  // The caller of `method`, from its "authorization: Bearer <token>"
  // metadata. UNAUTHENTICATED without a token or with an unknown one,
  // PERMISSION_DENIED when the token's role lacks the access. Never echoes
  // the token.
  absl::StatusOr<Principal> Authorize(const grpc::ServerContextBase& context,
                                      absl::string_view method) const;
  // The same from the metadata value itself (tests, and callers that hold it).
  absl::StatusOr<Principal> Authorize(std::optional<absl::string_view> authorization,
                                      absl::string_view method) const;

  bool enabled() const { return enabled_; }
  // Replaces the token table (the token file read again, on SIGHUP); calls
  // already authorised go on. FailedPrecondition for an authorizer made
  // without tokens: tokens cannot be switched on while serving.
  absl::Status ReplaceTokens(TokenTable tokens);
  // Calls refused so far (an operator's counter). Each refusal is also
  // counted in reenact_auth_refusals_total{reason} and logged (event
  // auth_refused, with the caller's address when known, never the token).
  int64_t refusals() const;

 private:
  // Authorize's work; `peer` is the caller's address for the log ("" when
  // unknown).
  absl::StatusOr<Principal> Check(std::optional<absl::string_view> authorization,
                                  absl::string_view method, const std::string& peer) const;

  const bool enabled_;
  mutable std::mutex tokens_mutex_;
  std::shared_ptr<const TokenTable> tokens_;  // Null without tokens.
  MethodTable methods_;
  mutable std::atomic<int64_t> refusals_{0};
};

// For a server with TLS and tokens (grpc::ServerCredentials::
// SetAuthMetadataProcessor): checks each call's token and role as its
// metadata arrives, so that a call that would be refused is refused before
// gRPC reads its request messages (up to --max-message-mb each) into
// memory. Methods under `open_prefixes` (the health service: probes hold no
// token) pass without one. The handlers still authorise every call, as
// they must for the in-process and plain-text channels, which have no
// processor. `authorizer` must outlive the server.
std::shared_ptr<grpc::AuthMetadataProcessor> MakeTokenMetadataProcessor(
    const Authorizer* authorizer, std::vector<std::string> open_prefixes);

}  // namespace reenact::rpc
