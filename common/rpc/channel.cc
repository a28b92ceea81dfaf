#include "common/rpc/channel.h"

#include <sys/stat.h>

#include <cstdlib>
#include <utility>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/support/client_interceptor.h>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/strip.h"
#include "common/base/files.h"
#include "common/log/log.h"

namespace reenact::rpc {
namespace {

// PEM files are small; a certificate chain of more than this is not one.
constexpr uint64_t kMaxPemBytes = uint64_t{1} << 20;
constexpr uint64_t kMaxTokenBytes = 4096;

// The PEM file's text, checked to hold a PEM block; `what` names it in
// errors ("--tls-cert").
absl::StatusOr<std::string> ReadPem(absl::string_view path, absl::string_view what) {
  auto text = ReadFileToString(std::string(path), kMaxPemBytes);
  if (!text.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, " ", path, ": cannot be read: ", text.status().message()));
  }
  if (!absl::StrContains(*text, "-----BEGIN ")) {
    return absl::InvalidArgumentError(absl::StrCat(what, " ", path, " holds no PEM block"));
  }
  return text;
}

std::string FlagOrEnv(absl::string_view flag, const char* env) {
  if (!flag.empty()) return std::string(flag);
  const char* value = std::getenv(env);
  return value != nullptr ? std::string(value) : std::string();
}

}  // namespace

namespace {

// Adds fixed (key, value) pairs to every call's initial metadata.
class MetadataInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit MetadataInterceptor(const std::vector<std::pair<std::string, std::string>>* entries)
      : entries_(entries) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      for (const auto& [key, value] : *entries_) {
        methods->GetSendInitialMetadata()->emplace(key, value);
      }
    }
    methods->Proceed();
  }

 private:
  const std::vector<std::pair<std::string, std::string>>* entries_;
};

class MetadataInterceptorFactory final
    : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit MetadataInterceptorFactory(std::vector<std::pair<std::string, std::string>> entries)
      : entries_(std::move(entries)) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(
      grpc::experimental::ClientRpcInfo* /*info*/) override {
    return new MetadataInterceptor(&entries_);
  }

 private:
  const std::vector<std::pair<std::string, std::string>> entries_;
};

}  // namespace

std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>
MakeMetadataInterceptorFactory(std::vector<std::pair<std::string, std::string>> entries) {
  return std::make_unique<MetadataInterceptorFactory>(std::move(entries));
}

std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface> MakeTokenInterceptorFactory(
    const std::string& token) {
  return MakeMetadataInterceptorFactory({{"authorization", absl::StrCat("Bearer ", token)}});
}

absl::Status ServerTlsFiles::Validate() const {
  if (cert_file.empty() != key_file.empty()) {
    return absl::InvalidArgumentError("--tls-cert and --tls-key go together");
  }
  if (!client_ca_file.empty() && cert_file.empty()) {
    return absl::InvalidArgumentError("--tls-client-ca needs --tls-cert and --tls-key");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> MakeServerCredentials(
    const ServerTlsFiles& files) {
  if (absl::Status valid = files.Validate(); !valid.ok()) return valid;
  if (!files.enabled()) return grpc::InsecureServerCredentials();
  grpc::SslServerCredentialsOptions options;
  grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
  auto cert = ReadPem(files.cert_file, "--tls-cert");
  if (!cert.ok()) return cert.status();
  auto key = ReadPem(files.key_file, "--tls-key");
  if (!key.ok()) return key.status();
  pair.cert_chain = std::move(*cert);
  pair.private_key = std::move(*key);
  options.pem_key_cert_pairs.push_back(std::move(pair));
  if (!files.client_ca_file.empty()) {
    auto ca = ReadPem(files.client_ca_file, "--tls-client-ca");
    if (!ca.ok()) return ca.status();
    options.pem_root_certs = std::move(*ca);
    options.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(options);
}

bool IsLoopbackAddress(absl::string_view host_port) {
  if (absl::StartsWith(host_port, "unix:")) return true;
  absl::string_view host = host_port;
  if (absl::ConsumePrefix(&host, "[")) {
    const size_t close = host.find(']');
    if (close == absl::string_view::npos) return false;
    host = host.substr(0, close);
  } else if (const size_t colon = host.rfind(':'); colon != absl::string_view::npos) {
    host = host.substr(0, colon);
  }
  const std::string lower = absl::AsciiStrToLower(host);
  return lower == "localhost" || lower == "::1" || absl::StartsWith(lower, "127.");
}

absl::Status CheckExposure(absl::string_view what, absl::string_view address, bool tls, bool tokens,
                           bool insecure, absl::string_view risk) {
  if (address.empty() || IsLoopbackAddress(address) || insecure || (tls && tokens)) {
    return absl::OkStatus();
  }
  return absl::FailedPreconditionError(absl::StrCat(
      "refusing to serve ", what, " without TLS and tokens: anyone reaching it could ", risk,
      ". Give --tls-cert, --tls-key and --auth, or --insecure on a network you trust"));
}

absl::StatusOr<ClientSecurity> LoadClientSecurity(absl::string_view tls_ca_file,
                                                  absl::string_view token_file,
                                                  absl::string_view cert_file,
                                                  absl::string_view key_file) {
  ClientSecurity security;
  if (const std::string ca = FlagOrEnv(tls_ca_file, "REENACT_TLS_CA"); !ca.empty()) {
    auto pem = ReadPem(ca, "--tls-ca");
    if (!pem.ok()) return pem.status();
    security.ca_pem = std::move(*pem);
  }
  const std::string cert = FlagOrEnv(cert_file, "REENACT_TLS_CERT");
  const std::string key = FlagOrEnv(key_file, "REENACT_TLS_KEY");
  if (cert.empty() != key.empty()) {
    return absl::InvalidArgumentError("a client certificate and its key go together");
  }
  if (!cert.empty()) {
    auto cert_pem = ReadPem(cert, "--tls-client-cert");
    if (!cert_pem.ok()) return cert_pem.status();
    auto key_pem = ReadPem(key, "--tls-client-key");
    if (!key_pem.ok()) return key_pem.status();
    security.cert_pem = std::move(*cert_pem);
    security.key_pem = std::move(*key_pem);
  }
  std::string token;
  if (!token_file.empty()) {
    auto text = ReadFileToString(std::string(token_file), kMaxTokenBytes);
    if (!text.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("--token-file ", token_file, ": cannot be read: ", text.status().message()));
    }
    struct stat info {};
    if (::stat(std::string(token_file).c_str(), &info) == 0 && (info.st_mode & 077) != 0) {
      return absl::InvalidArgumentError(absl::StrFormat(
          "--token-file %s can be read by other users (mode %04o); a token is a password: "
          "chmod 600 %s",
          token_file, info.st_mode & 07777, token_file));
    }
    token = std::string(absl::StripAsciiWhitespace(*text));
  } else if (const char* env = std::getenv("REENACT_TOKEN"); env != nullptr) {
    token = std::string(absl::StripAsciiWhitespace(env));
  }
  for (const char c : token) {
    if (c < 0x21 || c > 0x7e) {
      return absl::InvalidArgumentError(
          "the token (--token-file or REENACT_TOKEN) must be one word of printable ASCII");
    }
  }
  if (!token_file.empty() && token.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("--token-file ", token_file, " is empty"));
  }
  security.token = std::move(token);
  return security;
}

bool TokenMayTravel(absl::string_view address, const ClientSecurity& security) {
  return security.token.empty() || !security.ca_pem.empty() || IsLoopbackAddress(address);
}

std::shared_ptr<grpc::Channel> MakeClientChannel(const std::string& address,
                                                 const grpc::ChannelArguments& args,
                                                 const ClientSecurity& security) {
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (security.ca_pem.empty()) {
    credentials = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = security.ca_pem;
    options.pem_cert_chain = security.cert_pem;
    options.pem_private_key = security.key_pem;
    credentials = grpc::SslCredentials(options);
  }
  if (security.token.empty()) return grpc::CreateCustomChannel(address, credentials, args);
  if (!TokenMayTravel(address, security)) {
    log::Warn("token_withheld", {{"server", address}},
              absl::StrCat("not sending the token to ", address,
                           " in plain text, where others on the network could read it: give "
                           "--tls-ca (the CA of the server's certificate) to send it over TLS"));
    return grpc::CreateCustomChannel(address, credentials, args);
  }
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(MakeTokenInterceptorFactory(security.token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(address, credentials, args,
                                                                 std::move(interceptors));
}

}  // namespace reenact::rpc
