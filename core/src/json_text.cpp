#include "vdrig/core/json_text.hpp"

#include <set>

namespace vdrig {
namespace {
using nlohmann::json;

/// One open object or array while parsing, and where the parser is in it.
struct OpenContainer {
  bool is_object = false;
  std::set<std::string> keys;  // an object's keys so far
  std::string key;             // an object's current key
  std::size_t index = 0;       // an array's current element
  std::size_t next_index = 0;
};

/// "stage.pan", "views[2]": the path of the innermost open container (empty: the outermost).
std::string path_of(const std::vector<OpenContainer>& open) {
  std::string path;
  for (std::size_t i = 0; i + 1 < open.size(); ++i) {
    if (open[i].is_object)
      path += (path.empty() ? "" : ".") + open[i].key;
    else
      path += "[" + std::to_string(open[i].index) + "]";
  }
  return path;
}

}  // namespace

Result<JsonText> parse_json_text(std::string_view text, const std::string& what) {
  JsonText parsed;
  std::vector<OpenContainer> open;
  // Every element of an array, whatever its type, advances the array's index (for the paths of later elements).
  const auto element_starts = [&open] {
    if (!open.empty() && !open.back().is_object) open.back().index = open.back().next_index++;
  };
  const json::parser_callback_t track = [&](int, json::parse_event_t event, json& value) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        element_starts();
        open.push_back({});
        open.back().is_object = event == json::parse_event_t::object_start;
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!open.empty()) open.pop_back();
        break;
      case json::parse_event_t::key: {
        OpenContainer& object = open.back();
        object.key = value.get<std::string>();
        if (!object.keys.insert(object.key).second) {
          const std::string path = path_of(open);
          parsed.duplicate_keys.push_back("duplicate key \"" + object.key + "\" " +
                                          (path.empty() ? "at the top level" : "in " + path));
        }
        break;
      }
      case json::parse_event_t::value:
        element_starts();
        break;
    }
    return true;  // keep everything: a repeated key is reported, not dropped here
  };
  try {
    parsed.value = json::parse(text.begin(), text.end(), track);
  } catch (const json::exception& e) {
    // Syntax errors are parse_error ("[json.exception.parse_error.101] parse error at line L, column C: ..."), but a
    // number too large for a double ("1e999") is out_of_range.406: both are text that is not a JSON document.
    return make_error(ErrorCode::kCorrupt, what + ": not valid JSON: " + e.what());
  }
  return parsed;
}

Result<json> parse_json_strict(std::string_view text, const std::string& what) {
  auto parsed = parse_json_text(text, what);
  if (!parsed) return parsed.error();
  if (parsed->duplicate_keys.empty()) return std::move(parsed->value);
  std::string reasons;
  for (const auto& d : parsed->duplicate_keys) reasons += (reasons.empty() ? "" : "; ") + d;
  return make_error(ErrorCode::kCorrupt, what + ": " + reasons);
}

}  // namespace vdrig
