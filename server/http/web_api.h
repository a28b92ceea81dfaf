// The JSON API of reenact-server's HTTP front (server/http/http_front.h),
// the tablet app's view of the server. Every answer comes from the server's
// own gRPC services, called in process with the HTTP client's token, so the
// roles and limits are those of gRPC (viewer is enough for all of it) and
// their statuses become the HTTP errors:
//
//   GET /api/v1/info
//       {"name", "version", "auth", "tls", "server_time_unix_ns"}
//   GET /api/v1/reenactments[?page_size=N&page_token=T&take_id=X]
//       JSON array, newest first, of {"id", "take_id", "take_name", "method",
//       "kind": "body"|"rigid", "frames", "fps", "duration_s",
//       "created_unix_ns", "file_bytes", "parts"}; header X-Next-Page-Token
//       when there is more (Reenactments.List's pagination).
//   GET /api/v1/reenactments/{id}
//       one such object.
//   GET /api/v1/reenactments/{id}/model.glb
//       the glTF 2.0 binary of `reenact export` (common/io/gltf_export.h),
//       built once and kept beside the reenactment (removed with it); ETag,
//       If-None-Match (304), single byte ranges (206, 416), If-Range.
//   GET /api/v1/reenactments/{id}/appearance.mp4
//       a body reenactment's per-frame appearance: the texture video whose
//       frame i is the atlas of instant i (H.264 in MP4, the model.glb's
//       texture layout), kept and served like model.glb; 404 when the
//       reenactment has none (rigid parts, or appearance=false).
//   GET /api/v1/jobs[?live=1&page_size=N&page_token=T]
//       JSON array, newest first, of {"id", "take_id", "method", "state",
//       "live", "reenactment_id", "created_unix_ns", "stage", "fraction",
//       "frames_done", "message" (why it failed)};
//       live=1: only running jobs that follow their take.
//   GET /api/v1/jobs/{id}/follow  (WebSocket; Follow below)
//
// Errors: {"error": {"code": "<gRPC status name>", "message"}} with 400 for
// a malformed id or query, 401 without a (known) token, 403 when the role
// may not, 404 for an unknown id or path, 405 for other methods, 429 past a
// limit, 503 while the server is unavailable, 500 otherwise.
//
// The token comes from "Authorization: Bearer <token>", or from the query
// parameter access_token (RFC 6750 2.3; browsers cannot set headers on a
// WebSocket).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <grpcpp/channel.h>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace reenact::server::http {

// One HTTP request, as far as the API looks at it.
struct WebRequest {
  std::string method;                        // "GET", "HEAD", ...
  std::string path;                          // Percent-decoded, without the query.
  std::map<std::string, std::string> query;  // Percent-decoded.
  std::string token;                         // Bearer token (header or access_token); empty: none.
  // The web client's address: the API's calls count under its caps
  // (Server::InProcessChannel's `client`), not under one for every user of
  // the token. Empty: the front's own.
  std::string client;
  std::string if_none_match;
  std::string range;
  std::string if_range;
};

struct WebResponse {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;
};

// The HTTP status of a gRPC status code (see above).
int HttpStatusOf(absl::StatusCode code);
// The JSON error answer of `status`.
WebResponse ErrorResponse(const absl::Status& status);

struct WebApiOptions {
  // Shown by /api/v1/info.
  bool auth = false;
  bool tls = false;
  // Where files derived from a reenactment are kept (model.glb, the
  // appearance video): the reenactment store's DerivedPathFor(id,
  // extension); and whether the reenactment is still stored (after they are
  // written, so that those of a reenactment deleted meanwhile go at once).
  std::function<std::string(const std::string& reenactment_id, const std::string& extension)>
      derived_path;
  std::function<bool(const std::string& reenactment_id)> still_stored;
  // Deadline of the unary calls it makes, seconds.
  double call_timeout_s = 10.0;
};

class WebApi {
 public:
  // `channel_for(token, client)`: a channel to the server whose calls carry
  // `token` and count under web client `client`'s caps
  // (Server::InProcessChannel(token, client)).
  using ChannelFactory = std::function<std::shared_ptr<grpc::Channel>(const std::string& token,
                                                                      const std::string& client)>;
  WebApi(WebApiOptions options, ChannelFactory channel_for);

  // Whether `path` is the API's (/api/...).
  static bool IsApiPath(absl::string_view path);
  // The job id of a follow path (/api/v1/jobs/{id}/follow), or empty.
  static std::string FollowJobId(absl::string_view path);

  // Answers a request to an API path (not a WebSocket upgrade).
  WebResponse Handle(const WebRequest& request);

  // One message to a WebSocket client; returns false once the client is
  // gone (the follow then stops).
  using SendFunction = std::function<bool(bool binary, const std::string& payload)>;
  // Relays Reenactments.Follow of `job_id` to a WebSocket client (messages
  // in web_api.h's order: the mesh as a JSON line and a binary .glb, a JSON
  // line per fitted frame, then the end, or one error line). Returns the
  // WebSocket close code to end with: 1000 after the end, 4000 + the HTTP
  // status after an error (4404 unknown job, 4401, 4403, 4503, ...), 1001
  // when the client went away.
  // `web_client`: the web client's address (WebRequest::client).
  int Follow(const std::string& job_id, const std::string& token, const std::string& web_client,
             const SendFunction& send);
  // OK when `token` may follow job `job_id` and the job exists (Jobs.Get
  // with the token): checked before a WebSocket is accepted, so that a
  // refused client gets an HTTP answer and never an open socket.
  absl::Status CheckFollow(const std::string& job_id, const std::string& token,
                           const std::string& client);

 private:
  WebResponse Info() const;
  WebResponse ListReenactments(const WebRequest& request);
  WebResponse GetReenactment(const WebRequest& request, const std::string& id);
  // The files served beside a reenactment.
  enum class Asset { kGlb, kAppearance };
  static const char* AssetExtension(Asset asset);
  // model.glb or appearance.mp4 with ETag, ranges and HEAD.
  WebResponse ServeAsset(const WebRequest& request, const std::string& id, Asset asset);
  WebResponse ListJobs(const WebRequest& request);
  // The name of take `take_id`; "" when it is gone (or the id is empty).
  std::string TakeName(const std::shared_ptr<grpc::Channel>& channel,
                       const std::string& take_id) const;

  // A file of `id` on disk (both built when one is missing) and its ETag.
  // NotFound for an appearance video of a reenactment that has none.
  struct AssetFile {
    std::string path;
    std::string etag;
    int64_t size = 0;
  };
  absl::Status EnsureAsset(const std::string& id, Asset asset, const WebRequest& request,
                           AssetFile* file);

  WebApiOptions options_;
  ChannelFactory channel_for_;
  std::mutex mutex_;
  // Per reenactment: a lock held while its files are built (one build at a
  // time); per file on disk, its ETag; the reenactments known to have no
  // appearance video.
  std::map<std::string, std::shared_ptr<std::mutex>> build_locks_;
  std::map<std::string, std::string> etags_;
  std::set<std::string> without_appearance_;
};

}  // namespace reenact::server::http
