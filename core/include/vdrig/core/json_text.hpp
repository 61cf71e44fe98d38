// Parsing JSON text without losing what it says: nlohmann::json keeps the last value of a key repeated within one
// object and drops the others without a word, so a config that sets a thing twice would silently mean the second.
// These parsers list every repeated key with the path of its object instead, for the caller to reject or report.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig {

/// A parsed JSON document and the keys its text repeats within one object, each as
/// "duplicate key \"port\" in stage.pan" ("at the top level" for the outermost object; array elements as
/// "views[2]"). The value holds the last of each repeated key.
struct JsonText {
  nlohmann::json value;
  std::vector<std::string> duplicate_keys;
};

/// Parses `text` (any JSON value). A syntax error is kCorrupt "WHAT: not valid JSON: <line, column, reason>".
Result<JsonText> parse_json_text(std::string_view text, const std::string& what);

/// parse_json_text() that refuses repeated keys: kCorrupt "WHAT: duplicate key \"x\" in a.b; duplicate key ...",
/// naming every one.
Result<nlohmann::json> parse_json_strict(std::string_view text, const std::string& what);

}  // namespace vdrig
