#include "server/http/web_api.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <utility>

#include <grpcpp/grpcpp.h>
#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/files.h"
#include "common/base/json_text.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/io/body_reenactment.h"
#include "common/io/gltf_export.h"
#include "common/log/log.h"
#include "common/rpc/auth.h"
#include "proto/state_names.h"
#include "reenact/v1/jobs_service.grpc.pb.h"
#include "reenact/v1/reenactments_service.grpc.pb.h"
#include "reenact/v1/takes_service.grpc.pb.h"
#include "server/http/service_client.h"
#include "server/http/web_request.h"

#ifndef REENACT_VERSION
#define REENACT_VERSION "unknown"
#endif

namespace reenact::server::http {
namespace {

using json = nlohmann::json;

constexpr absl::string_view kApiPrefix = "/api/";
constexpr absl::string_view kReenactmentsPath = "/api/v1/reenactments";
constexpr absl::string_view kJobsPath = "/api/v1/jobs";
// Ids are the services' business (they answer INVALID_ARGUMENT for malformed
// ones); this only keeps path segments from holding a path.
constexpr size_t kMaxIdBytes = 256;
// A page token is the services' (opaque, a few dozen bytes).
constexpr size_t kMaxPageTokenBytes = 1024;

int64_t WallNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

WebResponse JsonResponse(const json& value, int status = 200) {
  WebResponse response;
  response.status = status;
  response.body = JsonText(value);
  response.headers.emplace_back("Cache-Control", "no-store");
  return response;
}

// Page size from the query: absent 0 (the service's default); a number the
// service clamps; anything else InvalidArgument.
absl::Status ReadPaging(const WebRequest& request, int32_t* page_size, std::string* page_token) {
  *page_size = 0;
  if (const auto it = request.query.find("page_size"); it != request.query.end()) {
    if (!absl::SimpleAtoi(it->second, page_size) || *page_size < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("page_size must be a number >= 0, got \"", it->second, "\""));
    }
  }
  if (const auto it = request.query.find("page_token"); it != request.query.end()) {
    if (it->second.size() > kMaxPageTokenBytes) {
      return absl::InvalidArgumentError("page_token is not one this server gave");
    }
    *page_token = it->second;
  }
  return absl::OkStatus();
}

json ReenactmentJson(const v1::ReenactmentSummary& summary, const std::string& take_name) {
  const v1::ReenactmentInfo& info = summary.info();
  const double fps = info.fps();
  return json{
      {"id", info.reenactment_id()},
      {"take_id", info.take_id()},
      {"take_name", take_name},
      {"method", info.method()},
      {"kind", info.part_names().empty() ? "body" : "rigid"},
      {"frames", info.frame_count()},
      {"fps", fps},
      {"duration_s", fps > 0 ? info.frame_count() / fps : 0.0},
      {"created_unix_ns", info.created_unix_ns()},
      {"file_bytes", summary.file_bytes()},
      {"parts", info.part_names_size()},
  };
}

// A job that follows its take while it records (Job.live).
bool IsLive(const v1::Job& job) { return job.live() || job.progress().stage() == "following"; }

json JobJson(const v1::Job& job) {
  return json{
      {"id", job.job_id()},
      {"take_id", job.take_id()},
      {"method", job.method()},
      {"state", JobStateName(job.state())},
      {"live", IsLive(job)},
      {"reenactment_id", job.reenactment_id()},
      {"created_unix_ns", job.submitted_unix_ns()},
      {"stage", job.progress().stage()},
      {"fraction", job.progress().fraction()},
      {"frames_done", job.progress().frames_done()},
      {"message", job.error()},
  };
}

json Vector3Json(const v1::Vector3& v) { return json::array({v.x(), v.y(), v.z()}); }

// The ETag of a file's bytes: a strong validator from their SHA-256.
std::string EtagOf(const std::string& bytes) {
  return absl::StrCat("\"", rpc::Sha256Hex(bytes).substr(0, 32), "\"");
}

// The bytes [first, first + count) of the file at `path`.
absl::StatusOr<std::string> ReadRange(const std::string& path, int64_t first, int64_t count) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return FileError(absl::StrCat(path, ": cannot open"), errno);
  std::string out(static_cast<size_t>(count), '\0');
  int64_t done = 0;
  while (done < count) {
    const ssize_t n = ::pread(fd, out.data() + done, static_cast<size_t>(count - done),
                              static_cast<off_t>(first + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : EIO;
      ::close(fd);
      return FileError(absl::StrCat(path, ": cannot read"), error);
    }
    done += n;
  }
  ::close(fd);
  return out;
}

}  // namespace

int HttpStatusOf(absl::StatusCode code) {
  switch (code) {
    case absl::StatusCode::kOk:
      return 200;
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kOutOfRange:
      return 400;
    case absl::StatusCode::kUnauthenticated:
      return 401;
    case absl::StatusCode::kPermissionDenied:
      return 403;
    case absl::StatusCode::kNotFound:
      return 404;
    case absl::StatusCode::kAlreadyExists:
    case absl::StatusCode::kFailedPrecondition:
    case absl::StatusCode::kAborted:
      return 409;
    case absl::StatusCode::kResourceExhausted:
      return 429;
    case absl::StatusCode::kUnimplemented:
      return 501;
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kCancelled:
      return 503;
    case absl::StatusCode::kDeadlineExceeded:
      return 504;
    default:
      return 500;
  }
}

WebResponse ErrorResponse(const absl::Status& status) {
  WebResponse response;
  response.status = HttpStatusOf(status.code());
  response.body = ErrorBody(absl::StatusCodeToString(status.code()), status.message());
  response.headers.emplace_back("Cache-Control", "no-store");
  if (status.code() == absl::StatusCode::kUnauthenticated) {
    response.headers.emplace_back("WWW-Authenticate", "Bearer realm=\"reenact\"");
  }
  return response;
}

WebApi::WebApi(WebApiOptions options, ChannelFactory channel_for)
    : options_(std::move(options)), channel_for_(std::move(channel_for)) {}

bool WebApi::IsApiPath(absl::string_view path) {
  return absl::StartsWith(path, kApiPrefix) || path == "/api";
}

std::string WebApi::FollowJobId(absl::string_view path) {
  if (!absl::StartsWith(path, kJobsPath) || !IsUtf8(path)) return "";
  const std::vector<absl::string_view> parts = absl::StrSplit(path.substr(kJobsPath.size()), '/');
  if (parts.size() != 3 || !parts[0].empty() || parts[1].empty() || parts[2] != "follow") {
    return "";
  }
  return std::string(parts[1]);
}

WebResponse WebApi::Handle(const WebRequest& request) {
  if (request.method != "GET" && request.method != "HEAD") {
    WebResponse response = ErrorResponse(absl::UnimplementedError(
        absl::StrCat("method ", request.method, " is not served; the API only reads (GET)")));
    response.status = 405;
    response.headers.emplace_back("Allow", "GET, HEAD");
    return response;
  }
  const absl::string_view path = request.path;
  // Ids and page tokens go on as protobuf strings, which must be UTF-8.
  if (!IsUtf8(path)) {
    return ErrorResponse(
        absl::InvalidArgumentError(absl::StrCat("the request's path is not UTF-8: ", path)));
  }
  for (const auto& [key, value] : request.query) {
    if (!IsUtf8(key) || !IsUtf8(value)) {
      return ErrorResponse(absl::InvalidArgumentError(
          absl::StrCat("the request's query is not UTF-8: ", key, "=", value)));
    }
  }
  if (path == "/api/v1/info") return Info();
  if (path == kReenactmentsPath) return ListReenactments(request);
  if (path == kJobsPath) return ListJobs(request);
  if (absl::StartsWith(path, absl::StrCat(kReenactmentsPath, "/"))) {
    const std::vector<std::string> parts =
        absl::StrSplit(path.substr(kReenactmentsPath.size() + 1), '/');
    if (parts.empty() || parts[0].empty() || parts[0].size() > kMaxIdBytes || parts.size() > 2) {
      return ErrorResponse(absl::NotFoundError(absl::StrCat("no such path: ", path)));
    }
    if (parts.size() == 1) return GetReenactment(request, parts[0]);
    if (parts[1] == "model.glb") return ServeAsset(request, parts[0], Asset::kGlb);
    if (parts[1] == "appearance.mp4") return ServeAsset(request, parts[0], Asset::kAppearance);
  }
  if (!FollowJobId(path).empty()) {
    return ErrorResponse(absl::InvalidArgumentError(
        "the follow of a job is a WebSocket: connect with an Upgrade: websocket request"));
  }
  return ErrorResponse(absl::NotFoundError(absl::StrCat("no such path: ", path)));
}

std::string WebApi::TakeName(const std::shared_ptr<grpc::Channel>& channel,
                             const std::string& take_id) const {
  if (take_id.empty()) return "";
  const absl::StatusOr<v1::Take> take =
      ServiceClient(channel, options_.call_timeout_s).GetTake(take_id);
  return take.ok() ? take->name() : "";
}

WebResponse WebApi::Info() const {
  return JsonResponse(json{{"name", "reenact-server"},
                           {"version", REENACT_VERSION},
                           {"auth", options_.auth},
                           {"tls", options_.tls},
                           {"server_time_unix_ns", WallNowNs()}});
}

WebResponse WebApi::ListReenactments(const WebRequest& request) {
  v1::ListReenactmentsRequest list;
  int32_t page_size = 0;
  std::string page_token;
  if (absl::Status paging = ReadPaging(request, &page_size, &page_token); !paging.ok()) {
    return ErrorResponse(paging);
  }
  list.set_page_size(page_size);
  list.set_page_token(page_token);
  if (const auto it = request.query.find("take_id"); it != request.query.end()) {
    list.set_take_id(it->second);
  }
  const std::shared_ptr<grpc::Channel> channel = channel_for_(request.token, request.client);
  const absl::StatusOr<v1::ListReenactmentsResponse> page =
      ServiceClient(channel, options_.call_timeout_s).ListReenactments(list);
  if (!page.ok()) return ErrorResponse(page.status());
  const v1::ListReenactmentsResponse& listed = *page;
  // Take names, once per take of the page.
  std::map<std::string, std::string> names;
  for (const v1::ReenactmentSummary& summary : listed.reenactments()) {
    const std::string& take_id = summary.info().take_id();
    if (!names.contains(take_id)) names[take_id] = TakeName(channel, take_id);
  }
  json items = json::array();
  for (const v1::ReenactmentSummary& summary : listed.reenactments()) {
    items.push_back(ReenactmentJson(summary, names[summary.info().take_id()]));
  }
  WebResponse response = JsonResponse(items);
  if (!listed.next_page_token().empty()) {
    response.headers.emplace_back("X-Next-Page-Token", listed.next_page_token());
  }
  return response;
}

WebResponse WebApi::GetReenactment(const WebRequest& request, const std::string& id) {
  const std::shared_ptr<grpc::Channel> channel = channel_for_(request.token, request.client);
  const absl::StatusOr<v1::ReenactmentSummary> summary =
      ServiceClient(channel, options_.call_timeout_s).GetReenactment(id);
  if (!summary.ok()) return ErrorResponse(summary.status());
  return JsonResponse(ReenactmentJson(*summary, TakeName(channel, summary->info().take_id())));
}

const char* WebApi::AssetExtension(Asset asset) {
  return asset == Asset::kGlb ? ".glb" : ".appearance.mp4";
}

absl::Status WebApi::EnsureAsset(const std::string& id, Asset asset, const WebRequest& request,
                                 AssetFile* file) {
  const std::shared_ptr<grpc::Channel> channel = channel_for_(request.token, request.client);
  // Existence and the caller's right to read it, every time: a cached file
  // is served only to whom the service would give the reenactment.
  {
    const absl::StatusOr<v1::ReenactmentSummary> summary =
        ServiceClient(channel, options_.call_timeout_s).GetReenactment(id);
    if (!summary.ok()) {
      if (absl::IsNotFound(summary.status())) {
        std::lock_guard<std::mutex> lock(mutex_);
        for (const Asset a : {Asset::kGlb, Asset::kAppearance}) {
          etags_.erase(options_.derived_path(id, AssetExtension(a)));
        }
        build_locks_.erase(id);
        without_appearance_.erase(id);
      }
      return summary.status();
    }
  }
  std::shared_ptr<std::mutex> build_lock;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    std::shared_ptr<std::mutex>& slot = build_locks_[id];
    if (slot == nullptr) slot = std::make_shared<std::mutex>();
    build_lock = slot;
  }
  std::lock_guard<std::mutex> building(*build_lock);
  const auto no_video = [&id] {
    return absl::NotFoundError(absl::StrCat(
        "reenactment ", id,
        " has no appearance video (rigid parts, or a body job run with appearance=false): the "
        "static atlas in model.glb is its texture"));
  };
  if (asset == Asset::kAppearance) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (without_appearance_.contains(id)) return no_video();
  }
  file->path = options_.derived_path(id, AssetExtension(asset));
  std::error_code error;
  const auto on_disk = std::filesystem::file_size(file->path, error);
  if (!error) {
    file->size = static_cast<int64_t>(on_disk);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (const auto it = etags_.find(file->path); it != etags_.end()) {
        file->etag = it->second;
        return absl::OkStatus();
      }
    }
    // On disk from before a restart: its ETag from its bytes.
    ASSIGN_OR_RETURN(const std::string bytes, ReadRange(file->path, 0, file->size));
    file->etag = EtagOf(bytes);
    std::lock_guard<std::mutex> lock(mutex_);
    etags_[file->path] = file->etag;
    return absl::OkStatus();
  }
  // Missing: the reenactment is fetched once and both files are written
  // from it (the glb with the static atlas, and the body's appearance video
  // when it has one).
  const auto started = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(const Reenactment data, ServiceClient(channel, options_.call_timeout_s)
                                               .FetchReenactment(id, /*skip_keyframes=*/true));
  GltfExportSummary summary;
  ASSIGN_OR_RETURN(const std::string glb,
                   ExportReenactmentGlb(data, GltfExportOptions{}, &summary));
  const std::string glb_path = options_.derived_path(id, AssetExtension(Asset::kGlb));
  const std::string video_path = options_.derived_path(id, AssetExtension(Asset::kAppearance));
  const std::string* video =
      data.body && !data.body->appearance_mp4.empty() ? &data.body->appearance_mp4 : nullptr;
  RETURN_IF_ERROR(WriteFileAtomically(glb_path, glb));
  if (video != nullptr) RETURN_IF_ERROR(WriteFileAtomically(video_path, *video));
  if (!options_.still_stored(id)) {
    // Deleted while they were built: what they show must not stay.
    std::filesystem::remove(glb_path, error);
    std::filesystem::remove(video_path, error);
    return absl::NotFoundError(absl::StrCat("no reenactment ", id));
  }
  log::Info("glb_built",
            {{"reenactment_id", id},
             {"bytes", static_cast<int64_t>(glb.size())},
             {"appearance_bytes", static_cast<int64_t>(video ? video->size() : 0)},
             {"seconds",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()}},
            absl::StrCat("built the glTF of reenactment ", id, ": ", summary.BriefReport()));
  std::lock_guard<std::mutex> lock(mutex_);
  etags_[glb_path] = EtagOf(glb);
  if (video != nullptr) {
    etags_[video_path] = EtagOf(*video);
  } else {
    without_appearance_.insert(id);
  }
  if (asset == Asset::kAppearance && video == nullptr) return no_video();
  file->size = static_cast<int64_t>(asset == Asset::kGlb ? glb.size() : video->size());
  file->etag = etags_[file->path];
  return absl::OkStatus();
}

WebResponse WebApi::ServeAsset(const WebRequest& request, const std::string& id, Asset asset) {
  AssetFile file;
  if (absl::Status status = EnsureAsset(id, asset, request, &file); !status.ok()) {
    return ErrorResponse(status);
  }
  const int64_t size = file.size;
  WebResponse response;
  response.content_type = asset == Asset::kGlb ? "model/gltf-binary" : "video/mp4";
  response.headers.emplace_back("ETag", file.etag);
  response.headers.emplace_back("Accept-Ranges", "bytes");
  response.headers.emplace_back("Cache-Control", "private, no-cache");
  if (!request.if_none_match.empty() &&
      (request.if_none_match == file.etag || request.if_none_match == "*" ||
       absl::StrContains(request.if_none_match, file.etag))) {
    response.status = 304;
    return response;
  }
  int64_t first = 0, last = size - 1;
  bool partial = false;
  if (!request.range.empty() && (request.if_range.empty() || request.if_range == file.etag)) {
    bool ignore = false;
    if (ParseByteRange(request.range, size, &first, &last, &ignore)) {
      partial = true;
    } else if (!ignore) {
      WebResponse refused = ErrorResponse(absl::OutOfRangeError(
          absl::StrCat("range ", request.range, " is outside the ", size, " bytes of the ",
                       asset == Asset::kGlb ? "glb" : "appearance video")));
      refused.status = 416;
      refused.headers.emplace_back("Content-Range", absl::StrCat("bytes */", size));
      return refused;
    }
  }
  if (partial) {
    response.status = 206;
    response.headers.emplace_back("Content-Range",
                                  absl::StrCat("bytes ", first, "-", last, "/", size));
  } else {
    first = 0;
    last = size - 1;
  }
  if (request.method == "HEAD") {
    response.headers.emplace_back("Content-Length", absl::StrCat(last - first + 1));
    return response;
  }
  absl::StatusOr<std::string> bytes = ReadRange(file.path, first, last - first + 1);
  if (!bytes.ok()) return ErrorResponse(bytes.status());
  response.body = *std::move(bytes);
  return response;
}

WebResponse WebApi::ListJobs(const WebRequest& request) {
  v1::ListJobsRequest list;
  int32_t page_size = 0;
  std::string page_token;
  if (absl::Status paging = ReadPaging(request, &page_size, &page_token); !paging.ok()) {
    return ErrorResponse(paging);
  }
  bool live_only = false;
  if (const auto it = request.query.find("live"); it != request.query.end()) {
    if (it->second != "0" && it->second != "1") {
      return ErrorResponse(absl::InvalidArgumentError(
          absl::StrCat("live must be 0 or 1, got \"", it->second, "\"")));
    }
    live_only = it->second == "1";
  }
  list.set_page_size(page_size);
  list.set_page_token(page_token);
  if (live_only) list.set_state(v1::JOB_STATE_RUNNING);
  const absl::StatusOr<v1::ListJobsResponse> page =
      ServiceClient(channel_for_(request.token, request.client), options_.call_timeout_s)
          .ListJobs(list);
  if (!page.ok()) return ErrorResponse(page.status());
  const v1::ListJobsResponse& listed = *page;
  json items = json::array();
  for (const v1::Job& job : listed.jobs()) {
    if (!live_only || IsLive(job)) items.push_back(JobJson(job));
  }
  WebResponse response = JsonResponse(items);
  if (!listed.next_page_token().empty()) {
    response.headers.emplace_back("X-Next-Page-Token", listed.next_page_token());
  }
  return response;
}

absl::Status WebApi::CheckFollow(const std::string& job_id, const std::string& token,
                                 const std::string& client) {
  return ServiceClient(channel_for_(token, client), options_.call_timeout_s)
      .GetJob(job_id)
      .status();
}

int WebApi::Follow(const std::string& job_id, const std::string& token,
                   const std::string& web_client, const SendFunction& send) {
  bool client_gone = false;
  Eigen::Vector3d rest_root = Eigen::Vector3d::Zero();
  const auto send_json = [&](const json& message) {
    if (client_gone) return false;
    if (!send(false, JsonText(message))) client_gone = true;
    return !client_gone;
  };
  const auto on_event = [&](const v1::FollowEvent& event) -> bool {
    switch (event.event_case()) {
      case v1::FollowEvent::kMesh: {
        const v1::BodyMesh& mesh = event.mesh();
        GltfExportOptions glb_options;
        glb_options.unlit = false;  // No atlas yet: a lit grey body shows its shape.
        absl::StatusOr<std::string> glb = ExportBodyMeshGlb(mesh, glb_options);
        if (!glb.ok()) {
          send_json(json{{"type", "error"},
                         {"code", absl::StatusCodeToString(absl::StatusCode::kDataLoss)},
                         {"message", absl::StrCat("the live body mesh does not convert: ",
                                                  glb.status().message())}});
          return false;
        }
        const int root = body::Index(body::KinectV2Joint::kSpineBase);
        if (mesh.rest_joints_m_size() > root) {
          const v1::Vector3& j = mesh.rest_joints_m(root);
          rest_root = Eigen::Vector3d(j.x(), j.y(), j.z());
        }
        if (!send_json(json{{"type", "mesh"},
                            {"model_name", mesh.model_name()},
                            {"vertices", mesh.rest_positions_m_f32().size() / 12},
                            {"triangles", mesh.triangle_indices_size() / 3},
                            {"bytes", glb->size()}})) {
          return false;
        }
        if (!send(true, *glb)) client_gone = true;
        return !client_gone;
      }
      case v1::FollowEvent::kFrame: {
        const v1::PartFrame& frame = event.frame();
        const v1::BodyPose& pose = frame.body();
        json rotations = json::array();
        for (const v1::Quaternion& q : pose.local_rotations()) {
          rotations.push_back(json::array({q.x(), q.y(), q.z(), q.w()}));
        }
        json joints = json::array();
        for (const v1::Vector3& j : frame.joints_in_world_m()) joints.push_back(Vector3Json(j));
        const v1::Vector3& t = pose.root_translation_m();
        return send_json(json{
            {"type", "frame"},
            {"frame_index", frame.frame_index()},
            {"sequence", event.sequence()},
            {"stamp_ns", frame.stamp_ns()},
            {"arrived_unix_ns", event.arrived_unix_ns()},
            {"published_unix_ns", event.published_unix_ns()},
            {"sent_unix_ns", WallNowNs()},
            {"fit_ms", event.fit_ms()},
            {"frames_skipped", event.frames_skipped()},
            {"valid", pose.valid()},
            {"root_position_m",
             json::array({rest_root.x() + t.x(), rest_root.y() + t.y(), rest_root.z() + t.z()})},
            {"local_rotations", std::move(rotations)},
            {"joints_m", std::move(joints)},
        });
      }
      case v1::FollowEvent::kEnd:  // Follow returns it.
      default:
        return true;
    }
  };
  const absl::StatusOr<v1::FollowEnd> end =
      ServiceClient(channel_for_(token, web_client), options_.call_timeout_s)
          .Follow(job_id, on_event);
  if (client_gone) return 1001;
  if (!end.ok()) {
    send_json(json{{"type", "error"},
                   {"code", absl::StatusCodeToString(end.status().code())},
                   {"message", std::string(end.status().message())}});
    return 4000 + HttpStatusOf(end.status().code());
  }
  std::string reason = absl::AsciiStrToLower(v1::FollowEndReason_Name(end->reason()));
  constexpr absl::string_view kPrefix = "follow_end_reason_";
  if (absl::StartsWith(reason, kPrefix)) reason = reason.substr(kPrefix.size());
  send_json(json{{"type", "end"},
                 {"reason", reason},
                 {"message", end->message()},
                 {"frames_received", end->frames_received()},
                 {"frames_followed", end->frames_followed()},
                 {"frames_skipped", end->frames_skipped()},
                 {"frames_unfitted", end->frames_unfitted()}});
  return client_gone ? 1001 : 1000;
}

}  // namespace reenact::server::http
