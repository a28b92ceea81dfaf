#include "common/rpc/auth.h"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <set>

#include <openssl/evp.h>
#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/json_text.h"
#include "common/log/log.h"
#include "common/metrics/metrics.h"

namespace reenact::rpc {
namespace {

// Refusal reasons: the label of reenact_auth_refusals_total and the field of
// the auth_refused log line.
constexpr char kNoToken[] = "no_token";
constexpr char kUnknownToken[] = "unknown_token";
constexpr char kRole[] = "role";

metrics::Counter& RefusalCounter(const char* reason) {
  return metrics::DefaultRegistry().GetCounter(
      "reenact_auth_refusals_total",
      "Calls refused for want of a valid token or of the access the method needs, by reason "
      "(no_token, unknown_token, role).",
      {{"reason", reason}});
}

// One line per refusal, never with the token itself.
void LogRefusal(absl::string_view method, const std::string& peer, const char* reason,
                const absl::Status& status, const std::optional<Principal>& principal) {
  const std::string code = absl::StatusCodeToString(status.code());
  log::Warn("auth_refused",
            {{"rpc", method},
             {"peer", peer},
             {"reason", reason},
             {"status", code},
             {"token_name", principal ? principal->name : std::string()},
             {"role", principal ? RoleName(principal->role) : absl::string_view()}},
            absl::StrCat("refused ", method, peer.empty() ? "" : " from ", peer, ": ", code));
}

constexpr size_t kMaxNameLength = 64;
// A token file of more than this is not one (thousands of entries fit).
constexpr uint64_t kMaxTokenFileBytes = uint64_t{1} << 20;
constexpr absl::string_view kBearer = "Bearer ";

bool IsHex64(absl::string_view s) {
  if (s.size() != 64) return false;
  for (char c : s) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

bool IsPrintableName(absl::string_view s) {
  if (s.empty() || s.size() > kMaxNameLength) return false;
  for (unsigned char c : s) {
    if (c < 0x20 || c > 0x7e) return false;
  }
  return true;
}

// Equal strings of equal length, in time independent of where they differ.
bool ConstantTimeEqual(absl::string_view a, absl::string_view b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

std::string Hex(const unsigned char* bytes, size_t n) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(2 * n, '0');
  for (size_t i = 0; i < n; ++i) {
    out[2 * i] = kDigits[bytes[i] >> 4];
    out[2 * i + 1] = kDigits[bytes[i] & 15];
  }
  return out;
}

}  // namespace

absl::string_view RoleName(Role role) {
  switch (role) {
    case Role::kViewer:
      return "viewer";
    case Role::kCapture:
      return "capture";
    case Role::kCoach:
      return "coach";
    case Role::kWorker:
      return "worker";
    case Role::kAdmin:
      return "admin";
  }
  return "unknown";
}

absl::StatusOr<Role> ParseRole(absl::string_view name) {
  for (Role role : {Role::kViewer, Role::kCapture, Role::kCoach, Role::kWorker, Role::kAdmin}) {
    if (name == RoleName(role)) return role;
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown role \"",
                                                 absl::CHexEscape(name.substr(0, kMaxNameLength)),
                                                 "\" (viewer, capture, coach, worker or admin)"));
}

uint32_t RoleAccess(Role role) {
  switch (role) {
    case Role::kViewer:
      return kRead;
    case Role::kCapture:
      return kIngest;
    case Role::kCoach:
      return kRead | kManage;
    case Role::kWorker:
      return kWork;
    case Role::kAdmin:
      return kRead | kIngest | kManage | kWork;
  }
  return 0;
}

std::string Sha256Hex(absl::string_view bytes) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int length = 0;
  EVP_Digest(bytes.data(), bytes.size(), digest.data(), &length, EVP_sha256(), nullptr);
  return Hex(digest.data(), length);
}

absl::StatusOr<TokenTable> TokenTable::Parse(absl::string_view json, absl::string_view origin) {
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("tokens") ||
      !doc["tokens"].is_array()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "token file ", origin, ": expected JSON {\"tokens\": [{\"name\", \"role\", \"sha256\"}]}"));
  }
  TokenTable table;
  std::set<std::string> names;
  std::set<std::string> hashes;
  int index = 0;
  for (const nlohmann::json& entry : doc["tokens"]) {
    const std::string where = absl::StrCat("token file ", origin, ": entry ", index++);
    if (!entry.is_object() || !entry.contains("name") || !entry["name"].is_string() ||
        !entry.contains("role") || !entry["role"].is_string() || !entry.contains("sha256") ||
        !entry["sha256"].is_string()) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, " needs string fields name, role and sha256"));
    }
    Entry e;
    e.name = entry["name"].get<std::string>();
    if (!IsPrintableName(e.name)) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, ": a name is 1..", kMaxNameLength, " printable ASCII characters"));
    }
    auto role = ParseRole(entry["role"].get<std::string>());
    if (!role.ok())
      return absl::InvalidArgumentError(absl::StrCat(where, ": ", role.status().message()));
    e.role = *role;
    e.sha256 = absl::AsciiStrToLower(entry["sha256"].get<std::string>());
    if (!IsHex64(e.sha256)) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, " (", e.name, "): sha256 must be 64 hex digits"));
    }
    if (!names.insert(e.name).second) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": the name ", e.name, " repeats"));
    }
    if (!hashes.insert(e.sha256).second) {
      return absl::InvalidArgumentError(absl::StrCat(where, " (", e.name, "): the token repeats"));
    }
    table.entries_.push_back(std::move(e));
  }
  return table;
}

absl::StatusOr<TokenTable> TokenTable::Load(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int error = errno;
    if (error == ENOENT)
      return absl::NotFoundError(absl::StrCat("token file ", path, " is missing"));
    return absl::FailedPreconditionError(
        absl::StrCat("token file ", path, ": ", std::strerror(error)));
  }
  if ((st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
    return absl::PermissionDeniedError(
        absl::StrCat("token file ", path, " may be read or written by others (mode ",
                     absl::StrFormat("%03o", st.st_mode & 0777), "); chmod 600 it"));
  }
  auto text = ReadFileToString(path, kMaxTokenFileBytes);
  if (!text.ok()) return text.status();
  return Parse(*text, path);
}

absl::Status TokenTable::Add(const std::string& name, Role role, absl::string_view token) {
  for (const Entry& entry : entries_) {
    if (entry.name == name)
      return absl::AlreadyExistsError(absl::StrCat("token ", name, " exists"));
  }
  entries_.push_back({name, role, Sha256Hex(token)});
  return absl::OkStatus();
}

std::vector<std::pair<std::string, Role>> TokenTable::Names() const {
  std::vector<std::pair<std::string, Role>> names;
  names.reserve(entries_.size());
  for (const Entry& entry : entries_) names.emplace_back(entry.name, entry.role);
  return names;
}

std::optional<Principal> TokenTable::Find(absl::string_view token) const {
  const std::string hash = Sha256Hex(token);
  std::optional<Principal> found;
  for (const Entry& e : entries_) {  // Every entry, whatever matches first.
    if (ConstantTimeEqual(hash, e.sha256)) found = Principal{e.name, e.role};
  }
  return found;
}

absl::StatusOr<std::string> NewToken() {
  std::array<unsigned char, 32> bytes{};
  size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::getrandom(bytes.data() + got, bytes.size() - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      return absl::UnavailableError(
          absl::StrCat("the system's random source failed: ", std::strerror(errno)));
    }
    got += static_cast<size_t>(n);
  }
  return absl::StrCat("rnt_", Hex(bytes.data(), bytes.size()));
}

absl::StatusOr<std::string> AddToken(const std::string& path, Role role, const std::string& name) {
  if (!IsPrintableName(name)) {
    return absl::InvalidArgumentError(
        absl::StrCat("a token's name is 1..", kMaxNameLength, " printable ASCII characters"));
  }
  nlohmann::json doc = {{"tokens", nlohmann::json::array()}};
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    auto table = TokenTable::Load(path);  // Checks the file before adding to it.
    if (!table.ok()) return table.status();
    auto text = ReadFileToString(path, kMaxTokenFileBytes);
    if (!text.ok()) return text.status();
    doc = nlohmann::json::parse(*text);
    for (const nlohmann::json& entry : doc["tokens"]) {
      if (entry["name"].get<std::string>() == name) {
        return absl::AlreadyExistsError(
            absl::StrCat("token file ", path, " already has a token named ", name));
      }
    }
  }
  auto token = NewToken();
  if (!token.ok()) return token.status();
  doc["tokens"].push_back(
      {{"name", name}, {"role", std::string(RoleName(role))}, {"sha256", Sha256Hex(*token)}});
  // Written 0600 from the start: the temporary file never exists with wider
  // permissions.
  const mode_t old_mask = ::umask(077);
  const absl::Status written = WriteFileAtomically(path, doc.dump(2) + "\n");
  ::umask(old_mask);
  if (!written.ok()) return written;
  if (::chmod(path.c_str(), 0600) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("token file ", path, ": chmod: ", std::strerror(errno)));
  }
  return *token;
}

absl::Status RemoveToken(const std::string& path, const std::string& name) {
  auto table = TokenTable::Load(path);  // Checks the file before changing it.
  if (!table.ok()) return table.status();
  auto text = ReadFileToString(path, kMaxTokenFileBytes);
  if (!text.ok()) return text.status();
  nlohmann::json doc = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (!doc.is_object() || !doc["tokens"].is_array()) {
    return absl::InvalidArgumentError(absl::StrCat("token file ", path, " is not a token file"));
  }
  nlohmann::json kept = nlohmann::json::array();
  bool found = false;
  for (const nlohmann::json& entry : doc["tokens"]) {
    if (entry.value("name", std::string()) == name) {
      found = true;
    } else {
      kept.push_back(entry);
    }
  }
  if (!found) {
    return absl::NotFoundError(absl::StrCat("token file ", path, " has no token named ", name));
  }
  doc["tokens"] = std::move(kept);
  const mode_t old_mask = ::umask(077);
  absl::Status written = WriteFileAtomically(path, JsonText(doc, 2) + "\n");
  ::umask(old_mask);
  return written;
}

Authorizer::Authorizer(std::optional<TokenTable> tokens, MethodTable methods)
    : enabled_(tokens.has_value()),
      tokens_(tokens.has_value() ? std::make_shared<const TokenTable>(*std::move(tokens))
                                 : nullptr),
      methods_(std::move(methods)) {
  // Every reason shows in the metrics from the start, at 0.
  for (const char* reason : {kNoToken, kUnknownToken, kRole}) RefusalCounter(reason);
}

absl::StatusOr<Principal> Authorizer::Authorize(const grpc::ServerContextBase& context,
                                                absl::string_view method) const {
  if (!enabled_) return Principal{};
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  std::optional<absl::string_view> authorization;
  if (it != metadata.end()) authorization = absl::string_view(it->second.data(), it->second.size());
  return Check(authorization, method, context.peer());
}

absl::StatusOr<Principal> Authorizer::Authorize(std::optional<absl::string_view> authorization,
                                                absl::string_view method) const {
  return Check(authorization, method, "");
}

absl::StatusOr<Principal> Authorizer::Check(std::optional<absl::string_view> authorization,
                                            absl::string_view method,
                                            const std::string& peer) const {
  if (!enabled_) return Principal{};
  std::shared_ptr<const TokenTable> tokens;
  {
    std::lock_guard<std::mutex> lock(tokens_mutex_);
    tokens = tokens_;
  }
  auto refuse = [&](const char* reason, absl::Status status,
                    const std::optional<Principal>& principal) -> absl::Status {
    refusals_.fetch_add(1, std::memory_order_relaxed);
    RefusalCounter(reason).Increment();
    LogRefusal(method, peer, reason, status, principal);
    return status;
  };
  if (!authorization.has_value() || !absl::StartsWith(*authorization, kBearer)) {
    return refuse(
        kNoToken,
        absl::UnauthenticatedError(absl::StrCat(
            method, " needs a token (--token-file FILE or REENACT_TOKEN); none was sent")),
        std::nullopt);
  }
  const std::optional<Principal> principal = tokens->Find(authorization->substr(kBearer.size()));
  if (!principal.has_value()) {
    return refuse(kUnknownToken,
                  absl::UnauthenticatedError(
                      absl::StrCat(method, ": the token is not one this server knows")),
                  std::nullopt);
  }
  const auto needed = methods_.find(method);
  const uint32_t granted = RoleAccess(principal->role);
  const bool allowed =
      principal->admin() || (needed != methods_.end() && (granted & needed->second) != 0);
  if (!allowed) {
    return refuse(
        kRole,
        absl::PermissionDeniedError(absl::StrCat(method, " is not allowed for ", principal->name,
                                                 " (role ", RoleName(principal->role), ")")),
        principal);
  }
  return *principal;
}

absl::Status Authorizer::ReplaceTokens(TokenTable tokens) {
  if (!enabled_) {
    return absl::FailedPreconditionError(
        "this server started without tokens; restart it with --auth to use them");
  }
  auto table = std::make_shared<const TokenTable>(std::move(tokens));
  std::lock_guard<std::mutex> lock(tokens_mutex_);
  tokens_ = std::move(table);
  return absl::OkStatus();
}

int64_t Authorizer::refusals() const { return refusals_.load(std::memory_order_relaxed); }

namespace {

class TokenMetadataProcessor final : public grpc::AuthMetadataProcessor {
 public:
  TokenMetadataProcessor(const Authorizer* authorizer, std::vector<std::string> open_prefixes)
      : authorizer_(authorizer), open_prefixes_(std::move(open_prefixes)) {}

  // Inline on gRPC's thread: a lookup in a small table, no I/O.
  bool IsBlocking() const override { return false; }

  grpc::Status Process(const InputMetadata& metadata, grpc::AuthContext* /*context*/,
                       OutputMetadata* /*consumed*/, OutputMetadata* /*response*/) override {
    absl::string_view path;
    std::optional<absl::string_view> authorization;
    for (const auto& [key, value] : metadata) {
      const absl::string_view k(key.data(), key.size());
      if (k == ":path") path = absl::string_view(value.data(), value.size());
      if (k == "authorization") authorization = absl::string_view(value.data(), value.size());
    }
    for (const std::string& open : open_prefixes_) {
      if (absl::StartsWith(path, open)) return grpc::Status::OK;
    }
    const absl::StatusOr<Principal> principal = authorizer_->Authorize(authorization, path);
    if (principal.ok()) return grpc::Status::OK;
    return grpc::Status(static_cast<grpc::StatusCode>(principal.status().code()),
                        std::string(principal.status().message()));
  }

 private:
  const Authorizer* const authorizer_;
  const std::vector<std::string> open_prefixes_;
};

}  // namespace

std::shared_ptr<grpc::AuthMetadataProcessor> MakeTokenMetadataProcessor(
    const Authorizer* authorizer, std::vector<std::string> open_prefixes) {
  return std::make_shared<TokenMetadataProcessor>(authorizer, std::move(open_prefixes));
}

}  // namespace reenact::rpc
