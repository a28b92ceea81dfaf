// Transport security shared by every Reenact server and client: TLS
// credentials from PEM files, and the bearer token clients attach to each
// call (common/rpc/auth.h checks it).
//
// Servers: --tls-cert PEM --tls-key PEM [--tls-client-ca PEM] (with a client
// CA, clients must present a certificate it signed). Clients: --tls-ca PEM
// (or REENACT_TLS_CA) to trust the server's certificate, and --token-file
// FILE (or REENACT_TOKEN, the token itself).
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>
#include "absl/strings/string_view.h"

#include <grpcpp/channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/support/channel_arguments.h>
#include <grpcpp/support/client_interceptor.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact::rpc {

struct ServerTlsFiles {
  std::string cert_file{};
  std::string key_file{};
  // Optional: require client certificates signed by this CA.
  std::string client_ca_file{};

  bool enabled() const { return !cert_file.empty(); }
  // InvalidArgument: a key without a certificate or the reverse, or a client
  // CA without both.
  absl::Status Validate() const;
};

// TLS credentials from the files (insecure ones when `files` is not
// enabled). InvalidArgument naming a file that cannot be read or holds no
// PEM block; the private key's contents are never echoed.
absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> MakeServerCredentials(
    const ServerTlsFiles& files);

// True for addresses only this machine reaches: 127.0.0.0/8, [::1],
// localhost, unix sockets.
bool IsLoopbackAddress(absl::string_view host_port);

// FailedPrecondition when a server would listen on `address` (not
// loopback, not empty) without both TLS and tokens and without `insecure`;
// `what` names the port ("--listen 0.0.0.0:50051") and `risk` says what an
// outsider could do there.
absl::Status CheckExposure(absl::string_view what, absl::string_view address, bool tls, bool tokens,
                           bool insecure, absl::string_view risk);

// How a client reaches a server.
struct ClientSecurity {
  // PEM of the CA that signed the server's certificate; empty: no TLS.
  std::string ca_pem{};
  // The bearer token; empty: none is sent.
  std::string token{};
  // Optional PEM of a client certificate and its key (servers started with
  // --tls-client-ca).
  std::string cert_pem{};
  std::string key_pem{};
};

// From the flags' values, each falling back to its environment variable:
// `tls_ca_file` else $REENACT_TLS_CA, `token_file` else $REENACT_TOKEN (the
// token itself), `cert_file`/`key_file` else $REENACT_TLS_CERT and
// $REENACT_TLS_KEY. InvalidArgument naming a file that cannot be read, is
// not PEM, a token file that is empty or holds more than one line, or a
// token file that other users may read (like ssh with a private key: the
// message says to chmod 600 it).
absl::StatusOr<ClientSecurity> LoadClientSecurity(absl::string_view tls_ca_file,
                                                  absl::string_view token_file,
                                                  absl::string_view cert_file = {},
                                                  absl::string_view key_file = {});

// Whether the token may go to `address` with `security`: there is none,
// the channel has TLS, or the address is loopback (only this machine sees
// the bytes).
bool TokenMayTravel(absl::string_view address, const ClientSecurity& security);

// A channel to `address` with `args`: TLS when security.ca_pem is set, and
// the token on every call when security.token is set and TokenMayTravel.
// A token that may not travel (plain text off this machine) is not sent:
// a warning (event token_withheld) says why, and the server refuses the
// calls as it would without one.
std::shared_ptr<grpc::Channel> MakeClientChannel(const std::string& address,
                                                 const grpc::ChannelArguments& args,
                                                 const ClientSecurity& security);

// Adds "authorization: Bearer <token>" to the initial metadata of every call
// of the channels it is given to (MakeClientChannel's way of sending the
// token, for channels made elsewhere, e.g. a server's in-process channel).
std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface> MakeTokenInterceptorFactory(
    const std::string& token);

// Adds the (key, value) pairs to the initial metadata of every call of the
// channels it is given to (keys in lower case, as gRPC wants them).
std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>
MakeMetadataInterceptorFactory(std::vector<std::pair<std::string, std::string>> entries);

}  // namespace reenact::rpc
