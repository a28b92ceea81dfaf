// The --metrics endpoint of reenact-server and reenactd: a small HTTP/1.1
// server (Boost.Beast) that answers GET /metrics with the Prometheus text
// exposition (common/metrics/metrics.h) and every other request with 404.
//
// It serves figures only and has neither TLS nor tokens: callers keep it on
// loopback unless the operator says otherwise (rpc::CheckExposure, the rule
// of --listen). One thread serves every connection; a scrape builds its text
// on that thread, so a slow collector delays only other scrapes. Idle or
// slow connections are closed after a timeout, and request headers are
// bounded, so a client cannot hold the thread.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"

namespace reenact::metrics {

class HttpExposer {
 public:
  // The body of a GET /metrics answer, built per request.
  using BodyFunction = std::function<std::string()>;

  // Listens on `address` ("HOST:PORT"; HOST a name, an IPv4 address or a
  // bracketed IPv6 address; port 0 picks a free one). InvalidArgument for a
  // malformed address, Unavailable when it cannot be bound.
  static absl::StatusOr<std::unique_ptr<HttpExposer>> Start(const std::string& address,
                                                            BodyFunction body);
  // Stop().
  ~HttpExposer();
  HttpExposer(const HttpExposer&) = delete;
  HttpExposer& operator=(const HttpExposer&) = delete;

  // "HOST:PORT" actually bound (the port resolved when 0 was asked).
  const std::string& address() const { return address_; }
  int port() const { return port_; }

  // Closes the listening socket and every connection; `body` is not called
  // once it returns. Idempotent.
  void Stop();

 private:
  struct Impl;
  HttpExposer() = default;

  std::unique_ptr<Impl> impl_;
  std::string address_;
  int port_ = 0;
};

}  // namespace reenact::metrics
