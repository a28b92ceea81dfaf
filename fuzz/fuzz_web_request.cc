// What an HTTP client sends the server's HTTP front, on arbitrary bytes: the
// request target (path and query, percent-decoded) and the Range header of a
// glTF download. The input's first line is the target, the rest the Range
// header; the resource size comes from the target's length. Checks: a
// decoded path starts with '/' and holds no NUL, a parsed range lies within
// the resource, decoding never grows the text, and the error answer that
// quotes the path or a query value (which need not be UTF-8) is JSON that
// reads back, without throwing, and IsUtf8 agrees with the JSON library.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_util.h"
#include "server/http/web_request.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes = reenact::fuzz::AsView(data, size);
  const size_t newline = bytes.find('\n');
  const std::string_view target = bytes.substr(0, newline);
  const std::string_view range =
      newline == std::string_view::npos ? std::string_view() : bytes.substr(newline + 1);
  std::string path;
  std::map<std::string, std::string> query;
  if (reenact::server::http::ParseTarget(absl::string_view(target.data(), target.size()), &path,
                                         &query)) {
    if (path.empty() || path.front() != '/') reenact::fuzz::Fail("a parsed path must start with /");
    if (path.find('\0') != std::string::npos) reenact::fuzz::Fail("a parsed path holds a NUL");
    if (path.size() > target.size()) reenact::fuzz::Fail("decoding grew the path");
    std::string quoted = "no such file: " + path;
    for (const auto& [key, value] : query) quoted += " " + key + "=" + value;
    const std::string body = reenact::server::http::ErrorBody("NOT_FOUND", quoted);
    const nlohmann::json read = nlohmann::json::parse(body, nullptr, /*allow_exceptions=*/false);
    if (!read.is_object() || !read["error"]["message"].is_string()) {
      reenact::fuzz::Fail("an error answer is not JSON");
    }
    // IsUtf8 against nlohmann's own UTF-8 decoder, which throws on what is
    // not UTF-8 when asked to.
    bool strict_ok = true;
    try {
      (void)nlohmann::json(quoted).dump();
    } catch (const nlohmann::json::exception&) {
      strict_ok = false;
    }
    if (strict_ok != reenact::server::http::IsUtf8(quoted)) {
      reenact::fuzz::Fail("IsUtf8 disagrees with the JSON library");
    }
    if (strict_ok && read["error"]["message"].get<std::string>() != quoted) {
      reenact::fuzz::Fail("an error answer changed a UTF-8 message");
    }
  }
  for (const int64_t resource :
       {int64_t{0}, int64_t{1}, static_cast<int64_t>(target.size()), int64_t{1} << 40}) {
    int64_t first = -1, last = -1;
    bool ignore = false;
    if (reenact::server::http::ParseByteRange(absl::string_view(range.data(), range.size()),
                                              resource, &first, &last, &ignore)) {
      if (ignore || first < 0 || first > last || last >= resource) {
        reenact::fuzz::Fail("a range outside the resource was accepted");
      }
    }
  }
  return 0;
}
