#include "server/http/http_front.h"

#include <sys/socket.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <openssl/ssl.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "common/base/files.h"
#include "common/base/flags.h"
#include "common/base/status_macros.h"
#include "common/log/log.h"
#include "server/http/web_api.h"
#include "server/http/web_request.h"

namespace reenact::server::http {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;
namespace websocket = beast::websocket;
namespace ssl = asio::ssl;
using tcp = asio::ip::tcp;

// A request is a request line and a few headers; browsers send < 4 KiB.
constexpr uint32_t kMaxHeaderBytes = 16 * 1024;
// Files of the app bigger than this are not served (the bundle is ~1 MB).
constexpr int64_t kMaxStaticFileBytes = int64_t{64} << 20;
// The slowest client a write waits for, on top of the idle timeout.
constexpr double kMinClientBytesPerSecond = 64.0 * 1024;

constexpr char kServerName[] = "reenact-server";
// With TLS: browsers that have seen the app over HTTPS never try it in
// plain text for a year.
constexpr char kStrictTransportSecurity[] = "max-age=31536000";
// TLS 1.2 suites with forward secrecy and authenticated encryption only (TLS
// 1.3's are all AEAD): no CBC, no RSA key exchange; the gRPC port's choice.
constexpr char kTls12Ciphers[] =
    "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:ECDHE-ECDSA-AES256-GCM-SHA384:"
    "ECDHE-RSA-AES256-GCM-SHA384:ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305";
// The app's files: its own scripts and styles only; textures decode from
// blob: URLs; the API and the follow socket are this origin's ('self' covers
// ws: and wss: to the same host).
constexpr char kContentSecurityPolicy[] =
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' blob: data:; connect-src 'self' blob: data:; "
    "worker-src 'self' blob:; frame-ancestors 'none'; base-uri 'none'";

int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string ContentTypeOf(const std::string& path) {
  static const std::map<std::string, std::string> kTypes = {
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".webmanifest", "application/manifest+json"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".svg", "image/svg+xml"},
      {".ico", "image/x-icon"},
      {".wasm", "application/wasm"},
      {".txt", "text/plain; charset=utf-8"},
      {".glb", "model/gltf-binary"},
  };
  const std::string extension =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
  const auto it = kTypes.find(extension);
  return it == kTypes.end() ? "application/octet-stream" : it->second;
}

// The bearer token of a request: "Authorization: Bearer X", else the
// access_token query parameter.
std::string TokenOf(const bhttp::request<bhttp::empty_body>& request,
                    const std::map<std::string, std::string>& query) {
  const auto header = request.find(bhttp::field::authorization);
  if (header != request.end()) {
    const absl::string_view value(header->value().data(), header->value().size());
    constexpr absl::string_view kBearer = "Bearer ";
    if (absl::StartsWithIgnoreCase(value, kBearer)) {
      return std::string(absl::StripAsciiWhitespace(value.substr(kBearer.size())));
    }
  }
  const auto it = query.find("access_token");
  return it == query.end() ? std::string() : it->second;
}

std::string HeaderOf(const bhttp::request<bhttp::empty_body>& request, bhttp::field field) {
  const auto it = request.find(field);
  return it == request.end() ? std::string() : std::string(it->value());
}

// The host of a Host header or of an origin's authority: "[::1]:8080" ->
// "::1", "Example.org:80" -> "example.org".
std::string HostOf(absl::string_view authority) {
  absl::string_view host = authority;
  if (absl::ConsumePrefix(&host, "[")) {
    host = host.substr(0, host.find(']'));
  } else if (const size_t colon = host.rfind(':'); colon != absl::string_view::npos) {
    host = host.substr(0, colon);
  }
  return absl::AsciiStrToLower(host);
}

bool IsLoopbackHost(const std::string& host) {
  return host == "localhost" || host == "::1" || absl::StartsWith(host, "127.");
}

// An address written as such ("192.168.1.20", "fe80::1"): no name that an
// attacker's DNS could point at this machine.
bool IsAddressLiteral(const std::string& host) {
  beast::error_code error;
  (void)asio::ip::make_address(host, error);
  return !error;
}

// "https://host:port" -> "host:port" (lower case); "" when not a URL.
std::string AuthorityOfOrigin(absl::string_view origin) {
  const size_t scheme = origin.find("://");
  if (scheme == absl::string_view::npos) return "";
  return absl::AsciiStrToLower(origin.substr(scheme + 3));
}

}  // namespace

absl::Status HttpFrontOptions::Validate() const {
  if (address.empty()) return absl::InvalidArgumentError("--http needs HOST:PORT");
  if (max_connections < 1) {
    return absl::InvalidArgumentError("--http-max-connections must be >= 1");
  }
  if (max_connections_per_client < 1) {
    return absl::InvalidArgumentError("--http-max-connections-per-client must be >= 1");
  }
  if (!(idle_timeout_s > 0)) return absl::InvalidArgumentError("the idle timeout must be > 0");
  return tls.Validate();
}

std::string FindWebRoot(const std::string& program_path) {
  std::error_code error;
  const std::filesystem::path program = std::filesystem::canonical(program_path, error);
  if (error) return "";
  const std::filesystem::path bin = program.parent_path();
  for (const std::filesystem::path& candidate :
       {bin.parent_path() / "share" / "reenact" / "web", bin.parent_path() / "web"}) {
    if (std::filesystem::is_regular_file(candidate / "index.html", error)) {
      return candidate.string();
    }
  }
  return "";
}

struct HttpFront::Impl {
  HttpFrontOptions options;
  bool auth = false;
  std::unique_ptr<WebApi> api;
  std::string web_root;  // Canonical; empty: no app.
  // The --http host in lower case when it names one address (not 0.0.0.0
  // or ::): requests addressed to it pass the Host check.
  std::string bound_host;
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::optional<ssl::context> tls;
  std::thread accept_thread;
  std::thread reaper_thread;

  // Open connections: their socket (shut down to end them) and the time
  // by which their current read or write must be done (steady ns;
  // max: none, e.g. between the frames of a follow).
  struct Connection {
    int fd = -1;
    std::string client;  // The peer's IP address.
    std::atomic<int64_t> deadline_ns{std::numeric_limits<int64_t>::max()};
  };
  std::mutex mutex;
  std::condition_variable changed;
  std::map<uint64_t, std::shared_ptr<Connection>> connections;
  std::map<std::string, int> per_client;  // Open connections by peer address.
  uint64_t next_connection = 0;
  bool stopping = false;
  // Refusals by limit since its last log line, and when that was (steady ns).
  struct Refusals {
    int64_t count = 0;
    int64_t logged_ns = std::numeric_limits<int64_t>::min();
  };
  std::map<std::string, Refusals> refusals;

  // Logs a refusal by `limit` unless one was logged in the last
  // kRefusalLogPeriodS; the line counts those not logged. Under `mutex`.
  void LogRefusalLocked(const std::string& limit, int max, const std::string& client);

  void AcceptLoop();
  void ReaperLoop();
  void Serve(tcp::socket socket, const std::shared_ptr<Connection>& connection);
  template <class Stream>
  void Session(Stream& stream, Connection& connection);
  template <class Stream>
  void FollowSocket(Stream& stream, Connection& connection,
                    const bhttp::request<bhttp::empty_body>& request, const std::string& job_id,
                    const std::string& token);
  // `client`: the connection's address (WebRequest::client).
  bhttp::response<bhttp::string_body> Respond(const bhttp::request<bhttp::empty_body>& request,
                                              const std::string& client);
  // A refusal when the request may not be served before anything else is
  // looked at: without tokens, a Host that names another site (a page
  // elsewhere reaching us through DNS rebinding: only a name can be
  // rebound, so IP addresses, loopback names and the --http host pass);
  // nullopt to go on.
  std::optional<WebResponse> RefuseHost(const bhttp::request<bhttp::empty_body>& request) const;
  // An answer as an HTTP response to `request`.
  bhttp::response<bhttp::string_body> ToResponse(const bhttp::request<bhttp::empty_body>& request,
                                                 const std::string& method,
                                                 WebResponse answer) const;
  WebResponse StaticFile(const WebRequest& request) const;

  void ExpireAfter(Connection& connection, double seconds) const {
    connection.deadline_ns = SteadyNowNs() + static_cast<int64_t>(seconds * 1e9);
  }
  double WriteSeconds(size_t bytes) const {
    return options.idle_timeout_s + static_cast<double>(bytes) / kMinClientBytesPerSecond;
  }
};

void HttpFront::Impl::LogRefusalLocked(const std::string& limit, int max,
                                       const std::string& client) {
  Refusals& r = refusals[limit];
  ++r.count;
  const int64_t now = SteadyNowNs();
  if (r.logged_ns != std::numeric_limits<int64_t>::min() &&
      now - r.logged_ns < static_cast<int64_t>(kRefusalLogPeriodS * 1e9)) {
    return;
  }
  log::Warn("limit_hit", {{"limit", limit}, {"max", max}, {"client", client}, {"refused", r.count}},
            limit == "http_connections_per_client"
                ? "HTTP connections refused: one client holds --http-max-connections-per-client"
                : "HTTP connections refused: --http-max-connections are open");
  r.count = 0;
  r.logged_ns = now;
}

void HttpFront::Impl::AcceptLoop() {
  for (;;) {
    beast::error_code error;
    tcp::socket socket(io);
    acceptor.accept(socket, error);
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (stopping) return;
    }
    if (error) {
      // Out of descriptors and the like: the client's loss; don't spin.
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    auto connection = std::make_shared<Connection>();
    connection->fd = socket.native_handle();
    const tcp::endpoint peer = socket.remote_endpoint(error);
    connection->client = error ? std::string("?") : peer.address().to_string();
    bool refused = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (stopping) return;  // The socket closes with this frame.
      int& from_client = per_client[connection->client];
      if (static_cast<int>(connections.size()) >= options.max_connections) {
        refused = true;
        LogRefusalLocked("http_connections", options.max_connections, connection->client);
      } else if (from_client >= options.max_connections_per_client) {
        refused = true;
        LogRefusalLocked("http_connections_per_client", options.max_connections_per_client,
                         connection->client);
      } else {
        ++from_client;
        connections.emplace(next_connection++, connection);
      }
      if (from_client == 0) per_client.erase(connection->client);
    }
    if (refused) {
      // Plain text even on a TLS port would be noise; just close.
      socket.close(error);
      continue;
    }
    std::thread([this, socket = std::move(socket), connection]() mutable {
      try {
        Serve(std::move(socket), connection);
      } catch (const std::exception& e) {
        // A defect of ours, never the client's to trigger: the connection
        // ends; the server and every other connection go on.
        log::Error("http_connection_failed", {{"what", e.what()}},
                   "an HTTP connection ended on an exception");
      }
      std::lock_guard<std::mutex> lock(mutex);
      for (auto it = connections.begin(); it != connections.end(); ++it) {
        if (it->second == connection) {
          connections.erase(it);
          break;
        }
      }
      if (auto it = per_client.find(connection->client); it != per_client.end()) {
        if (--it->second <= 0) per_client.erase(it);
      }
      changed.notify_all();
    }).detach();
  }
}

void HttpFront::Impl::ReaperLoop() {
  std::unique_lock<std::mutex> lock(mutex);
  while (!stopping) {
    changed.wait_for(lock, std::chrono::milliseconds(500));
    const int64_t now = SteadyNowNs();
    for (const auto& [id, connection] : connections) {
      if (connection->deadline_ns.load() < now) {
        // Unblocks the connection's read or write; its thread ends.
        ::shutdown(connection->fd, SHUT_RDWR);
        connection->deadline_ns = std::numeric_limits<int64_t>::max();
      }
    }
  }
}

void HttpFront::Impl::Serve(tcp::socket socket, const std::shared_ptr<Connection>& connection) {
  beast::error_code error;
  socket.set_option(tcp::no_delay(true), error);
  if (tls.has_value()) {
    beast::ssl_stream<tcp::socket> stream(std::move(socket), *tls);
    ExpireAfter(*connection, options.idle_timeout_s);
    stream.handshake(ssl::stream_base::server, error);
    if (error) return;  // A client that does not speak TLS, or timed out.
    Session(stream, *connection);
    ExpireAfter(*connection, 1.0);
    stream.shutdown(error);
  } else {
    Session(socket, *connection);
    socket.shutdown(tcp::socket::shutdown_send, error);
  }
}

template <class Stream>
void HttpFront::Impl::Session(Stream& stream, Connection& connection) {
  beast::flat_buffer buffer;
  for (;;) {
    bhttp::request_parser<bhttp::empty_body> parser;
    parser.header_limit(kMaxHeaderBytes);
    beast::error_code error;
    ExpireAfter(connection, options.idle_timeout_s);
    bhttp::read(stream, buffer, parser, error);
    if (error) {
      if (error == bhttp::error::header_limit || error == bhttp::error::unexpected_body ||
          error == bhttp::error::body_limit) {
        bhttp::response<bhttp::string_body> refused{
            error == bhttp::error::header_limit ? bhttp::status::request_header_fields_too_large
                                                : bhttp::status::payload_too_large,
            11};
        refused.set(bhttp::field::server, kServerName);
        refused.set(bhttp::field::content_type, "text/plain; charset=utf-8");
        refused.body() = error.message() + "\n";
        refused.keep_alive(false);
        refused.prepare_payload();
        ExpireAfter(connection, options.idle_timeout_s);
        bhttp::write(stream, refused, error);
      }
      return;  // End of stream, timeout, a malformed request.
    }
    bhttp::request<bhttp::empty_body> request = parser.release();
    std::optional<WebResponse> refused = RefuseHost(request);
    if (!refused.has_value() && websocket::is_upgrade(request)) {
      std::string path;
      std::map<std::string, std::string> query;
      const bool parsed = ParseTarget(
          absl::string_view(request.target().data(), request.target().size()), &path, &query);
      const std::string job_id = parsed ? WebApi::FollowJobId(path) : "";
      if (!job_id.empty()) {
        // A page of another origin may not open the follow (browsers send
        // Origin with every WebSocket); then the token and the job are
        // checked before the socket is accepted.
        const std::string origin = HeaderOf(request, bhttp::field::origin);
        const std::string host = absl::AsciiStrToLower(HeaderOf(request, bhttp::field::host));
        if (!origin.empty() && AuthorityOfOrigin(origin) != host) {
          refused = ErrorResponse(absl::PermissionDeniedError(
              "a follow must come from a page of this server (the Origin is another)"));
        } else if (absl::Status allowed =
                       api->CheckFollow(job_id, TokenOf(request, query), connection.client);
                   !allowed.ok()) {
          refused = ErrorResponse(allowed);
        } else {
          FollowSocket(stream, connection, request, job_id, TokenOf(request, query));
          return;
        }
      }
    }
    bhttp::response<bhttp::string_body> response =
        refused.has_value()
            ? ToResponse(request, std::string(request.method_string()), *std::move(refused))
            : Respond(request, connection.client);
    ExpireAfter(connection, WriteSeconds(response.body().size()));
    bhttp::write(stream, response, error);
    if (error || !response.keep_alive()) return;
  }
}

template <class Stream>
void HttpFront::Impl::FollowSocket(Stream& stream, Connection& connection,
                                   const bhttp::request<bhttp::empty_body>& request,
                                   const std::string& job_id, const std::string& token) {
  websocket::stream<Stream&> socket(stream);
  socket.set_option(websocket::stream_base::decorator(
      [](websocket::response_type& response) { response.set(bhttp::field::server, kServerName); }));
  // The client only listens; what it may send (a close, a ping) is small.
  socket.read_message_max(64 * 1024);
  beast::error_code error;
  ExpireAfter(connection, options.idle_timeout_s);
  socket.accept(request, error);
  if (error) return;
  connection.deadline_ns = std::numeric_limits<int64_t>::max();
  log::Info("follow_opened", {{"job_id", job_id}}, "a web client follows a job");
  const int code =
      api->Follow(job_id, token, connection.client, [&](bool binary, const std::string& payload) {
        socket.binary(binary);
        ExpireAfter(connection, WriteSeconds(payload.size()));
        beast::error_code write_error;
        socket.write(asio::buffer(payload), write_error);
        connection.deadline_ns = std::numeric_limits<int64_t>::max();
        return !write_error;
      });
  log::Info("follow_closed", {{"job_id", job_id}, {"close_code", code}},
            "a web client's follow ended");
  if (code == 1001) return;  // The client is gone.
  ExpireAfter(connection, 2.0);
  socket.close(websocket::close_reason(static_cast<uint16_t>(code)), error);
}

std::optional<WebResponse> HttpFront::Impl::RefuseHost(
    const bhttp::request<bhttp::empty_body>& request) const {
  if (auth) return std::nullopt;  // Tokens decide.
  const std::string host = HostOf(HeaderOf(request, bhttp::field::host));
  if (IsLoopbackHost(host) || IsAddressLiteral(host) ||
      (!bound_host.empty() && host == bound_host)) {
    return std::nullopt;
  }
  WebResponse refused = ErrorResponse(absl::PermissionDeniedError(absl::StrCat(
      "this server has no tokens and answers only requests addressed to it (an IP address, a "
      "loopback name",
      bound_host.empty() ? "" : " or " + bound_host, "); the Host was \"", host, "\"")));
  refused.status = 421;  // Misdirected Request.
  return refused;
}

bhttp::response<bhttp::string_body> HttpFront::Impl::Respond(
    const bhttp::request<bhttp::empty_body>& request, const std::string& client) {
  WebRequest web;
  web.client = client;
  web.method = std::string(request.method_string());
  WebResponse answer;
  if (!ParseTarget(absl::string_view(request.target().data(), request.target().size()), &web.path,
                   &web.query)) {
    answer = ErrorResponse(absl::InvalidArgumentError("the request target is malformed"));
  } else {
    web.token = TokenOf(request, web.query);
    web.if_none_match = HeaderOf(request, bhttp::field::if_none_match);
    web.range = HeaderOf(request, bhttp::field::range);
    web.if_range = HeaderOf(request, bhttp::field::if_range);
    if (WebApi::IsApiPath(web.path)) {
      answer = api->Handle(web);
    } else if (web.method != "GET" && web.method != "HEAD") {
      answer = ErrorResponse(absl::UnimplementedError("only GET and HEAD are served"));
      answer.status = 405;
      answer.headers.emplace_back("Allow", "GET, HEAD");
    } else {
      answer = StaticFile(web);
    }
  }
  return ToResponse(request, web.method, std::move(answer));
}

bhttp::response<bhttp::string_body> HttpFront::Impl::ToResponse(
    const bhttp::request<bhttp::empty_body>& request, const std::string& method,
    WebResponse answer) const {
  bhttp::response<bhttp::string_body> response{static_cast<bhttp::status>(answer.status),
                                               request.version()};
  response.set(bhttp::field::server, kServerName);
  response.set(bhttp::field::content_type, answer.content_type);
  response.set("X-Content-Type-Options", "nosniff");
  response.set("Referrer-Policy", "no-referrer");
  if (tls.has_value())
    response.set(bhttp::field::strict_transport_security, kStrictTransportSecurity);
  bool has_length = false;
  for (const auto& [name, value] : answer.headers) {
    response.set(name, value);
    has_length |= absl::EqualsIgnoreCase(name, "Content-Length");
  }
  response.keep_alive(request.keep_alive());
  if (has_length) {
    // HEAD of a file: the length of what GET would send.
    return response;
  }
  response.body() = std::move(answer.body);
  response.prepare_payload();
  if (method == "HEAD") response.body().clear();
  return response;
}

WebResponse HttpFront::Impl::StaticFile(const WebRequest& request) const {
  if (web_root.empty()) {
    WebResponse response;
    response.status = 503;
    response.content_type = "text/plain; charset=utf-8";
    response.body =
        "The web app is not built: deploy/build.sh builds it (it needs node and `npm ci "
        "--prefix clients/web`, which deploy/setup-debian.sh runs), or pass --web DIR.\n";
    return response;
  }
  const std::string relative = request.path == "/" ? "index.html" : request.path.substr(1);
  const std::filesystem::path wanted = std::filesystem::path(web_root) / relative;
  std::error_code error;
  const std::filesystem::path resolved = std::filesystem::weakly_canonical(wanted, error);
  const std::string resolved_text = resolved.string();
  const bool inside = !error && absl::StartsWith(resolved_text, web_root + "/");
  struct stat info {};
  if (!inside || ::stat(resolved_text.c_str(), &info) != 0 || !S_ISREG(info.st_mode) ||
      info.st_size > kMaxStaticFileBytes) {
    return ErrorResponse(absl::NotFoundError(absl::StrCat("no such file: ", request.path)));
  }
  WebResponse response;
  response.content_type = ContentTypeOf(resolved_text);
  const std::string etag =
      absl::StrCat("\"", info.st_size, "-", info.st_mtim.tv_sec, "-", info.st_mtim.tv_nsec, "\"");
  response.headers.emplace_back("ETag", etag);
  response.headers.emplace_back("Cache-Control", "no-cache");
  if (absl::EndsWith(resolved_text, ".html")) {
    response.headers.emplace_back("Content-Security-Policy", kContentSecurityPolicy);
  }
  if (request.if_none_match == etag) {
    response.status = 304;
    return response;
  }
  absl::StatusOr<std::string> bytes = ReadFileToString(resolved_text, kMaxStaticFileBytes);
  if (!bytes.ok()) return ErrorResponse(bytes.status());
  response.body = *std::move(bytes);
  return response;
}

absl::StatusOr<std::unique_ptr<HttpFront>> HttpFront::Start(const HttpFrontOptions& options,
                                                            HttpBackend backend) {
  RETURN_IF_ERROR(options.Validate());
  std::string host;
  int port = 0;
  RETURN_IF_ERROR(SplitHostPort("--http", options.address, &host, &port));
  std::unique_ptr<HttpFront> front(new HttpFront());
  front->impl_ = std::make_unique<Impl>();
  Impl& impl = *front->impl_;
  impl.options = options;
  impl.auth = backend.auth;
  if (!options.web_root.empty()) {
    std::error_code error;
    const std::filesystem::path root = std::filesystem::canonical(options.web_root, error);
    if (error || !std::filesystem::is_regular_file(root / "index.html", error)) {
      return absl::InvalidArgumentError(
          absl::StrCat("--web ", options.web_root, " holds no index.html (a built web app)"));
    }
    impl.web_root = root.string();
  }
  if (options.tls.enabled()) {
    impl.tls.emplace(ssl::context::tls_server);
    impl.tls->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 |
                          ssl::context::no_sslv3 | ssl::context::no_tlsv1 |
                          ssl::context::no_tlsv1_1);
    if (SSL_CTX_set_cipher_list(impl.tls->native_handle(), kTls12Ciphers) != 1) {
      return absl::InternalError("OpenSSL knows none of the TLS 1.2 AEAD suites");
    }
    beast::error_code error;
    impl.tls->use_certificate_chain_file(options.tls.cert_file, error);
    if (error) {
      return absl::InvalidArgumentError(
          absl::StrCat("--tls-cert ", options.tls.cert_file, ": ", error.message()));
    }
    impl.tls->use_private_key_file(options.tls.key_file, ssl::context::pem, error);
    if (error) {
      return absl::InvalidArgumentError(
          absl::StrCat("--tls-key ", options.tls.key_file, ": ", error.message()));
    }
    if (!options.tls.client_ca_file.empty()) {
      impl.tls->load_verify_file(options.tls.client_ca_file, error);
      if (error) {
        return absl::InvalidArgumentError(
            absl::StrCat("--tls-client-ca ", options.tls.client_ca_file, ": ", error.message()));
      }
      impl.tls->set_verify_mode(ssl::verify_peer | ssl::verify_fail_if_no_peer_cert);
    }
  }
  WebApiOptions api_options;
  api_options.auth = backend.auth;
  api_options.tls = options.tls.enabled();
  api_options.derived_path = std::move(backend.derived_path);
  api_options.still_stored = std::move(backend.still_stored);
  impl.api = std::make_unique<WebApi>(std::move(api_options), std::move(backend.channel));

  beast::error_code error;
  tcp::resolver resolver(impl.io);
  const tcp::resolver::results_type endpoints =
      resolver.resolve(host, std::to_string(port), tcp::resolver::numeric_service, error);
  if (error || endpoints.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("--http ", options.address, ": cannot resolve ",
                                                   host, ": ",
                                                   error ? error.message() : "no address"));
  }
  const tcp::endpoint endpoint = endpoints.begin()->endpoint();
  impl.acceptor.open(endpoint.protocol(), error);
  if (!error) impl.acceptor.set_option(asio::socket_base::reuse_address(true), error);
  if (!error) impl.acceptor.bind(endpoint, error);
  if (!error) impl.acceptor.listen(asio::socket_base::max_listen_connections, error);
  if (error) {
    return absl::UnavailableError(
        absl::StrCat("cannot listen on --http ", options.address, ": ", error.message()));
  }
  front->port_ = impl.acceptor.local_endpoint().port();
  if (!endpoint.address().is_unspecified()) impl.bound_host = absl::AsciiStrToLower(host);
  front->address_ = JoinHostPort(host, front->port_);
  impl.accept_thread = std::thread([&impl] { impl.AcceptLoop(); });
  impl.reaper_thread = std::thread([&impl] { impl.ReaperLoop(); });
  return front;
}

HttpFront::~HttpFront() { Stop(); }

std::string HttpFront::url() const {
  return absl::StrCat(impl_ != nullptr && impl_->tls.has_value() ? "https" : "http", "://",
                      address_, "/");
}

const std::string& HttpFront::web_root() const {
  static const std::string kNone;
  return impl_ != nullptr ? impl_->web_root : kNone;
}

void HttpFront::Stop() {
  if (impl_ == nullptr) return;
  Impl& impl = *impl_;
  {
    std::lock_guard<std::mutex> lock(impl.mutex);
    impl.stopping = true;
    for (const auto& [id, connection] : impl.connections) ::shutdown(connection->fd, SHUT_RDWR);
  }
  impl.changed.notify_all();
  // Wakes the blocked accept (Linux: shutdown of a listening socket).
  ::shutdown(impl.acceptor.native_handle(), SHUT_RDWR);
  if (impl.accept_thread.joinable()) impl.accept_thread.join();
  if (impl.reaper_thread.joinable()) impl.reaper_thread.join();
  {
    std::unique_lock<std::mutex> lock(impl.mutex);
    impl.changed.wait(lock, [&impl] { return impl.connections.empty(); });
  }
  beast::error_code ignored;
  impl.acceptor.close(ignored);
  impl_.reset();
}

}  // namespace reenact::server::http
