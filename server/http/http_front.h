// reenact-server --http HOST:PORT: the tablet app (clients/web, built into
// a folder of static files) and its JSON API (server/http/web_api.h) over
// HTTP/1.1 with Boost.Beast, and the live preview of a job as a WebSocket.
// Over TLS with the server's certificate when the gRPC port has one; the API
// answers with the gRPC services' own authorisation (the token of
// "Authorization: Bearer" or ?access_token=), so viewer is enough to watch.
// The app's files need no token: they hold no data.
//
// Threads: one per connection (a request is a few gRPC calls in process, a
// follow lasts as long as its take), at most `max_connections` of them, and
// at most `max_connections_per_client` from one client address, so that one
// client holding idle connections cannot take every slot; a connection past
// either is closed at once. Refusals are logged at most once per
// kRefusalLogPeriodS per limit, with how many there were since. Requests are bounded (16 KiB
// of header, no body), and a connection idle for `idle_timeout_s` (or a
// client that does not take its answer) is closed, so a client cannot hold
// a thread for long; a WebSocket follow is held until its job's follow ends
// or the client goes.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <grpcpp/channel.h>

#include "absl/status/statusor.h"
#include "common/rpc/channel.h"

namespace reenact::server::http {

// At most one log line per this many seconds for each refusing limit.
inline constexpr double kRefusalLogPeriodS = 10.0;

struct HttpFrontOptions {
  // "HOST:PORT" (port 0 picks a free one).
  std::string address;
  // The built web app (index.html, app.js, ...); empty: FindWebRoot().
  std::string web_root;
  // TLS: the gRPC port's files (cert and key; a client CA makes browsers
  // present a certificate it signed). Off when empty.
  rpc::ServerTlsFiles tls{};
  int max_connections = 256;
  // Connections from one IP address at once (a browser opens ~6, and one
  // more per followed job).
  int max_connections_per_client = 32;
  double idle_timeout_s = 30.0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What the front needs of the server it serves (reenact-server fills it from
// its Server, server/server.h HttpBackendOf; the front includes nothing of
// the server above it).
struct HttpBackend {
  // The server wants tokens: requests are judged by them, not by their Host.
  bool auth = false;
  // An in-process channel to the services that carries `token`, for the web
  // client at address `client`.
  std::function<std::shared_ptr<grpc::Channel>(const std::string& token, const std::string& client)>
      channel;
  // Where a reenactment's derived file with `extension` is kept, and whether
  // the reenactment is still stored.
  std::function<std::string(const std::string& id, const std::string& extension)> derived_path;
  std::function<bool(const std::string& id)> still_stored;
};

// The web app's folder for a program at `program_path`: the first of
// PREFIX/share/reenact/web (installed: PREFIX/bin/reenact-server) and
// BUILD/web (the build tree: BUILD/bin/reenact-server) that holds an
// index.html; empty when neither does.
std::string FindWebRoot(const std::string& program_path);

class HttpFront {
 public:
  // Listens on options.address and serves `backend`'s server (which must
  // outlive it; Stop() before the server is destroyed). InvalidArgument for bad
  // options or unreadable TLS files, Unavailable when the address cannot be
  // bound. A missing web app is not an error: "/" then says how to build
  // it, and the API still answers.
  static absl::StatusOr<std::unique_ptr<HttpFront>> Start(const HttpFrontOptions& options,
                                                          HttpBackend backend);
  // Stop().
  ~HttpFront();
  HttpFront(const HttpFront&) = delete;
  HttpFront& operator=(const HttpFront&) = delete;

  // "HOST:PORT" bound; the URL of the app ("https://HOST:PORT/" with TLS).
  const std::string& address() const { return address_; }
  int port() const { return port_; }
  std::string url() const;
  const std::string& web_root() const;

  // Closes the listening socket and every connection, and waits for their
  // threads. Follows in progress end when their gRPC call does: call it
  // after Server::Shutdown() (which ends live follows), or their clients'
  // sockets closing ends them at the next frame. Idempotent.
  void Stop();

 private:
  struct Impl;
  HttpFront() = default;

  std::unique_ptr<Impl> impl_;
  std::string address_;
  int port_ = 0;
};

}  // namespace reenact::server::http
