#include "vdrig/core/settings.hpp"

#include <cmath>

namespace vdrig {
namespace {

/// A JSON integer >= 0 (nlohmann stores non-negative literals from C++ as signed integers).
bool is_non_negative_integer(const nlohmann::json& v) {
  return v.is_number_unsigned() || (v.is_number_integer() && v.get<long long>() >= 0);
}

}  // namespace

Settings::Settings(const nlohmann::json& section, std::string where, std::initializer_list<const char*> envelope)
    : section_(section), where_(std::move(where)), envelope_(envelope.begin(), envelope.end()) {
  if (!section_.is_object()) problems_.push_back("settings must be a JSON object");
}

const nlohmann::json* Settings::find(const std::string& key) const {
  if (!section_.is_object()) return nullptr;
  const auto it = section_.find(key);
  return it == section_.end() ? nullptr : &*it;
}

void Settings::fail(const std::string& reason) { problems_.push_back(reason); }

double Settings::number(const std::string& key, double fallback, double min, double max) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  if (!v->is_number()) {
    fail("\"" + key + "\" must be a number, got " + v->dump());
    return fallback;
  }
  const double x = v->get<double>();
  if (!std::isfinite(x)) {
    fail("\"" + key + "\" must be finite");
    return fallback;
  }
  if (x < min || x > max) {
    fail("\"" + key + "\" = " + v->dump() + " is outside [" + nlohmann::json(min).dump() + ", " +
         nlohmann::json(max).dump() + "]");
    return fallback;
  }
  return x;
}

double Settings::required_number(const std::string& key, double min, double max) {
  if (!find(key)) {
    fail("\"" + key + "\" is required");
    return 0.0;
  }
  return number(key, 0.0, min, max);
}

long long Settings::integer(const std::string& key, long long fallback, long long min, long long max) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  if (!v->is_number_integer()) {
    fail("\"" + key + "\" must be an integer, got " + v->dump());
    return fallback;
  }
  const long long x = v->get<long long>();
  if (x < min || x > max) {
    fail("\"" + key + "\" = " + std::to_string(x) + " is outside [" + std::to_string(min) + ", " + std::to_string(max) +
         "]");
    return fallback;
  }
  return x;
}

long long Settings::required_integer(const std::string& key, long long min, long long max) {
  if (!find(key)) {
    fail("\"" + key + "\" is required");
    return min;
  }
  return integer(key, min, min, max);
}

bool Settings::boolean(const std::string& key, bool fallback) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  if (!v->is_boolean()) {
    fail("\"" + key + "\" must be true or false, got " + v->dump());
    return fallback;
  }
  return v->get<bool>();
}

std::uint64_t Settings::unsigned_integer(const std::string& key, std::uint64_t fallback, std::uint64_t max) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  if (!is_non_negative_integer(*v) || v->get<std::uint64_t>() > max) {
    fail("\"" + key + "\" must be an integer in [0, " + std::to_string(max) + "], got " + v->dump());
    return fallback;
  }
  return v->get<std::uint64_t>();
}

std::string Settings::string(const std::string& key, const std::string& fallback,
                             std::initializer_list<const char*> allowed) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  if (!v->is_string()) {
    fail("\"" + key + "\" must be a string, got " + v->dump());
    return fallback;
  }
  std::string s = v->get<std::string>();
  if (allowed.size() == 0) return s;
  std::string list;
  for (const char* a : allowed) {
    if (s == a) return s;
    list += (list.empty() ? "" : ", ") + std::string(a);
  }
  fail("\"" + key + "\" = \"" + s + "\" is not one of: " + list);
  return fallback;
}

std::string Settings::required_string(const std::string& key) {
  if (!find(key)) {
    fail("\"" + key + "\" is required");
    return {};
  }
  std::string s = string(key, "");
  if (s.empty()) fail("\"" + key + "\" must not be empty");
  return s;
}

std::vector<double> Settings::number_list(const std::string& key, std::vector<double> fallback, std::size_t size) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  const auto all_finite = [&] {
    for (const auto& x : *v)
      if (!x.is_number() || !std::isfinite(x.get<double>())) return false;
    return true;
  };
  if (!v->is_array() || !all_finite() || (size != 0 && v->size() != size)) {
    fail("\"" + key + "\" must be an array of " + (size ? std::to_string(size) + " " : std::string()) +
         "finite numbers, got " + v->dump());
    return fallback;
  }
  return v->get<std::vector<double>>();
}

std::vector<std::uint64_t> Settings::unsigned_list(const std::string& key, std::vector<std::uint64_t> fallback) {
  const nlohmann::json* v = find(key);
  if (!v) return fallback;
  const auto all_unsigned = [&] {
    for (const auto& x : *v)
      if (!is_non_negative_integer(x)) return false;
    return true;
  };
  if (!v->is_array() || !all_unsigned()) {
    fail("\"" + key + "\" must be an array of non-negative integers, got " + v->dump());
    return fallback;
  }
  return v->get<std::vector<std::uint64_t>>();
}

nlohmann::json Settings::object(const std::string& key, bool required) {
  const nlohmann::json* v = find(key);
  if (!v) {
    if (required) fail("\"" + key + "\" (an object) is required");
    return nlohmann::json::object();
  }
  if (!v->is_object()) {
    fail("\"" + key + "\" must be an object, got " + v->dump());
    return nlohmann::json::object();
  }
  return *v;
}

bool Settings::is_known(const std::string& key, const std::vector<std::string>& known) const {
  for (const auto& name : envelope_)
    if (key == name) return true;
  for (const auto& name : known)
    if (key == name) return true;
  return false;
}

void Settings::reject_unknown(std::initializer_list<const char*> known) {
  reject_unknown(std::vector<std::string>(known.begin(), known.end()));
}

void Settings::reject_unknown(const std::vector<std::string>& known, const std::string& noun) {
  if (!section_.is_object()) return;
  for (const auto& [k, v] : section_.items())
    if (!is_known(k, known)) fail("unknown " + noun + " \"" + k + "\"");
}

void Settings::absorb(const Settings& nested) {
  for (const auto& p : nested.problems_) problems_.push_back(nested.where_ + ": " + p);
}

bool Settings::is_valid(std::string* why) const {
  if (problems_.empty()) return true;
  if (why) *why = error().message;
  return false;
}

Error Settings::error() const {
  return make_error(ErrorCode::kInvalidArgument, where_ + ": invalid settings; " + reasons());
}

std::string Settings::reasons() const {
  std::string joined;
  for (const auto& p : problems_) joined += (joined.empty() ? "" : "; ") + p;
  return joined;
}

}  // namespace vdrig
