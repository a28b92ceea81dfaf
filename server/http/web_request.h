// Parsing of what an HTTP client sends the HTTP front (server/http/): the
// request target's path and query, and a Range header. Untrusted bytes: no
// input makes these allocate more than a few times its own size or throw, and
// fuzz/fuzz_web_request.cc runs them on arbitrary input.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "absl/strings/string_view.h"

namespace reenact::server::http {

// Decodes %XX escapes (and nothing else); false when one is malformed, or
// when the text holds a NUL, as is or escaped.
bool PercentDecode(absl::string_view in, std::string* out);

// Splits "a=1&b=x%20y" into decoded pairs ('+' is a space in values; a key
// given twice keeps its last value); false when an escape is malformed.
bool ParseQuery(absl::string_view query, std::map<std::string, std::string>* out);

// A request target ("/path?query") into its decoded path and query; false
// when an escape is malformed or the path does not start with '/'.
bool ParseTarget(absl::string_view target, std::string* path,
                 std::map<std::string, std::string>* query);

// One byte range of "bytes=A-B", "bytes=A-" or "bytes=-N" within a
// resource of `size` bytes (RFC 9110 14.1.2): true with [first, last] set;
// false when it is not satisfiable (416). `*ignore` is set for forms served
// whole instead (several ranges, other units, malformed), as RFC 9110
// allows.
bool ParseByteRange(absl::string_view header, int64_t size, int64_t* first, int64_t* last,
                    bool* ignore);

// Whether `text` is well-formed UTF-8 (RFC 3629: shortest forms only, no
// surrogates, nothing above U+10FFFF). Ids, names and page tokens reach the
// services as protobuf strings, which must be.
bool IsUtf8(absl::string_view text);

// The JSON body of an error answer: {"error": {"code": CODE, "message":
// MESSAGE}}. The message often quotes what the client sent (a path, a query
// value), which need not be UTF-8: such bytes become U+FFFD, so any request
// gets a well-formed answer.
std::string ErrorBody(absl::string_view code, absl::string_view message);

}  // namespace reenact::server::http
