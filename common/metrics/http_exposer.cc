#include "common/metrics/http_exposer.h"

#include <chrono>
#include <optional>
#include <thread>
#include <utility>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/flags.h"
#include "common/metrics/metrics.h"

namespace reenact::metrics {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

// A scraper sends a handful of header lines; anything bigger is not one.
constexpr uint32_t kMaxHeaderBytes = 8 * 1024;
constexpr uint64_t kMaxBodyBytes = 1024;
// Longest wait for a request (also between keep-alive requests) or for the
// client to take the answer.
constexpr auto kIoTimeout = std::chrono::seconds(10);

// One connection: read a request, answer it, again while the client keeps
// the connection alive.
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket socket, const HttpExposer::BodyFunction* body)
      : stream_(std::move(socket)), body_(body) {}

  void Read() {
    parser_.emplace();
    parser_->header_limit(kMaxHeaderBytes);
    parser_->body_limit(kMaxBodyBytes);
    stream_.expires_after(kIoTimeout);
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code error, size_t) { self->OnRead(error); });
  }

 private:
  void OnRead(beast::error_code error) {
    if (error) {
      // End of stream, timeout, a malformed or oversized request: close.
      Close();
      return;
    }
    const http::request<http::string_body>& request = parser_->get();
    auto response = std::make_shared<http::response<http::string_body>>();
    response->version(request.version());
    response->keep_alive(request.keep_alive());
    std::string_view target(request.target().data(), request.target().size());
    target = target.substr(0, target.find('?'));  // Scrapers may add parameters.
    const bool get = request.method() == http::verb::get || request.method() == http::verb::head;
    if (get && target == "/metrics") {
      response->result(http::status::ok);
      response->set(http::field::content_type, kContentType);
      if (request.method() == http::verb::get) response->body() = (*body_)();
    } else {
      response->result(http::status::not_found);
      response->set(http::field::content_type, "text/plain; charset=utf-8");
      if (request.method() != http::verb::head) response->body() = "not found; try /metrics\n";
    }
    response->prepare_payload();
    if (request.method() == http::verb::head) response->body().clear();
    stream_.expires_after(kIoTimeout);
    http::async_write(stream_, *response,
                      [self = shared_from_this(), response](beast::error_code error, size_t) {
                        if (error || !response->keep_alive()) {
                          self->Close();
                        } else {
                          self->Read();
                        }
                      });
  }

  void Close() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    stream_.socket().close(ignored);
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  const HttpExposer::BodyFunction* body_;
};

}  // namespace

struct HttpExposer::Impl {
  BodyFunction body;
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::thread thread;

  void Accept() {
    acceptor.async_accept([this](beast::error_code error, tcp::socket socket) {
      if (error == asio::error::operation_aborted || !acceptor.is_open()) return;
      if (!error) std::make_shared<Session>(std::move(socket), &body)->Read();
      Accept();  // A failed accept (e.g. out of descriptors) is the client's loss only.
    });
  }
};

absl::StatusOr<std::unique_ptr<HttpExposer>> HttpExposer::Start(const std::string& address,
                                                                BodyFunction body) {
  std::string host;
  int port = 0;
  if (absl::Status split = SplitHostPort("metrics address", address, &host, &port); !split.ok())
    return split;
  std::unique_ptr<HttpExposer> exposer(new HttpExposer());
  exposer->impl_ = std::make_unique<Impl>();
  Impl& impl = *exposer->impl_;
  impl.body = std::move(body);
  beast::error_code error;
  tcp::resolver resolver(impl.io);
  const tcp::resolver::results_type endpoints =
      resolver.resolve(host, std::to_string(port), tcp::resolver::numeric_service, error);
  if (error || endpoints.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("metrics address ", address, ": cannot resolve ",
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
        absl::StrCat("cannot listen on --metrics ", address, ": ", error.message()));
  }
  exposer->port_ = impl.acceptor.local_endpoint().port();
  exposer->address_ = JoinHostPort(host, exposer->port_);
  impl.Accept();
  impl.thread = std::thread([&impl] { impl.io.run(); });
  return exposer;
}

HttpExposer::~HttpExposer() { Stop(); }

void HttpExposer::Stop() {
  if (impl_ == nullptr) return;
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
  // The thread is gone: closing here races with nothing. Destroying the
  // io_context drops the pending handlers, and with them the sessions and
  // their sockets.
  beast::error_code ignored;
  impl_->acceptor.close(ignored);
  impl_.reset();
}

}  // namespace reenact::metrics
