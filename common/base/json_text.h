// JSON as text when some of its strings may not be UTF-8.
//
// nlohmann::json::dump() throws on a string that is not UTF-8, and a file
// path, a request target or a name can be anything its sender chose. Every
// place that dumps JSON holding such a string uses JsonText instead: the
// bytes that are not UTF-8 become U+FFFD and nothing throws.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace reenact {

// `value` as JSON text; `indent` as for dump() (-1: one line).
inline std::string JsonText(const nlohmann::json& value, int indent = -1) {
  return value.dump(indent, ' ', /*ensure_ascii=*/false, nlohmann::json::error_handler_t::replace);
}

}  // namespace reenact
