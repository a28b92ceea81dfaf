// Test-only: a scrape of a --metrics endpoint over a real TCP connection
// (plain POSIX sockets, independent of the server's Beast code), and a
// strict reader of the text exposition format 0.0.4.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace reenact::metrics::testing {

struct HttpAnswer {
  int status = 0;
  // Header names lower-cased.
  std::map<std::string, std::string> headers;
  std::string body;
};

// Sends "`method` `target` HTTP/1.1" with Connection: close to
// 127.0.0.1:`port` and reads the answer to the end.
inline absl::StatusOr<HttpAnswer> HttpRequest(int port, const std::string& target,
                                              const std::string& method = "GET") {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return absl::InternalError(absl::StrCat("socket: ", std::strerror(errno)));
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
    const std::string error = std::strerror(errno);
    ::close(fd);
    return absl::UnavailableError(absl::StrCat("connect to port ", port, ": ", error));
  }
  const std::string request = absl::StrCat(method, " ", target,
                                           " HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                           "User-Agent: reenact-test\r\nConnection: close\r\n\r\n");
  if (::send(fd, request.data(), request.size(), MSG_NOSIGNAL) !=
      static_cast<ssize_t>(request.size())) {
    ::close(fd);
    return absl::UnavailableError("send failed");
  }
  std::string raw;
  char buffer[4096];
  while (true) {
    const ssize_t n = ::recv(fd, buffer, sizeof(buffer), 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    raw.append(buffer, static_cast<size_t>(n));
  }
  ::close(fd);
  const size_t header_end = raw.find("\r\n\r\n");
  if (header_end == std::string::npos) {
    return absl::DataLossError(absl::StrCat("no complete HTTP header in: ", raw));
  }
  HttpAnswer answer;
  std::istringstream head(raw.substr(0, header_end));
  std::string status_line;
  std::getline(head, status_line);
  std::smatch match;
  if (!std::regex_search(status_line, match, std::regex(R"(^HTTP/1\.[01] (\d{3}) )"))) {
    return absl::DataLossError(absl::StrCat("bad status line: ", status_line));
  }
  answer.status = std::stoi(match[1]);
  for (std::string line; std::getline(head, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    answer.headers[absl::AsciiStrToLower(line.substr(0, colon))] =
        std::string(absl::StripAsciiWhitespace(line.substr(colon + 1)));
  }
  answer.body = raw.substr(header_end + 4);
  if (auto it = answer.headers.find("content-length"); it != answer.headers.end()) {
    size_t length = 0;
    if (!absl::SimpleAtoi(it->second, &length) || length != answer.body.size()) {
      return absl::DataLossError(
          absl::StrCat("Content-Length ", it->second, " but ", answer.body.size(), " body bytes"));
    }
  }
  return answer;
}

// The samples of an exposition, keyed by `name{labels}` exactly as written
// ("reenact_jobs{state=\"queued\"}"). InvalidArgument naming the first line
// that is neither a comment (# HELP / # TYPE with a known type) nor
// `name{label="value",...} value`, or a sample whose family has no TYPE
// line before it.
inline absl::StatusOr<std::map<std::string, double>> ParseExposition(const std::string& text) {
  static const std::regex kSample(
      R"(([a-zA-Z_:][a-zA-Z0-9_:]*)(\{([a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*")(,[a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*")*\})? ([^ ]+))");
  static const std::regex kHelp(R"(# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) .*)");
  static const std::regex kType(
      R"(# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram|summary|untyped))");
  std::map<std::string, double> samples;
  std::map<std::string, std::string> types;
  std::istringstream in(text);
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    std::smatch match;
    if (line.empty()) continue;
    if (line[0] == '#') {
      if (std::regex_match(line, match, kType)) {
        types[match[1]] = match[2];
      } else if (!std::regex_match(line, kHelp)) {
        return absl::InvalidArgumentError(absl::StrCat("line ", number, ": bad comment: ", line));
      }
      continue;
    }
    if (!std::regex_match(line, match, kSample)) {
      return absl::InvalidArgumentError(absl::StrCat("line ", number, ": not a sample: ", line));
    }
    const std::string value_text = match[match.size() - 1];
    double value = 0;
    if (value_text == "+Inf") {
      value = HUGE_VAL;
    } else if (value_text == "-Inf") {
      value = -HUGE_VAL;
    } else if (value_text == "NaN") {
      value = std::nan("");
    } else if (!absl::SimpleAtod(value_text, &value)) {
      return absl::InvalidArgumentError(absl::StrCat("line ", number, ": bad value: ", line));
    }
    // A histogram's series are its name plus _bucket, _sum or _count.
    std::string family = match[1];
    for (const std::string suffix : {"_bucket", "_sum", "_count"}) {
      const std::string name = match[1];
      if (name.size() <= suffix.size() || !name.ends_with(suffix)) continue;
      const auto type = types.find(name.substr(0, name.size() - suffix.size()));
      if (type != types.end() && type->second == "histogram") family = type->first;
    }
    if (!types.contains(family)) {
      return absl::InvalidArgumentError(
          absl::StrCat("line ", number, ": no # TYPE line before: ", line));
    }
    const std::string series = line.substr(0, line.size() - value_text.size() - 1);
    if (!samples.emplace(series, value).second) {
      return absl::InvalidArgumentError(absl::StrCat("line ", number, ": series twice: ", line));
    }
  }
  return samples;
}

}  // namespace reenact::metrics::testing
