#include "settings.hpp"

#include "vdrig/core/geometry.hpp"

#include <cmath>

namespace vdrig::rig {

Settings::Settings(const nlohmann::json& section, std::string where) : section_(section), where_(std::move(where)) {
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
  if (!std::isfinite(x) || x < min || x > max) {
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

void Settings::reject_unknown(std::initializer_list<const char*> known) {
  if (!section_.is_object()) return;
  for (const auto& [k, v] : section_.items()) {
    if (k == "backend") continue;
    bool found = false;
    for (const char* name : known) found = found || k == name;
    if (!found) fail("unknown setting \"" + k + "\"");
  }
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
  std::string msg = where_ + ": invalid settings";
  for (const auto& p : problems_) msg += "; " + p;
  return make_error(ErrorCode::kInvalidArgument, msg);
}

AxisSpec read_axis_spec(Settings& s) {
  constexpr double kDegPerRad = 180.0 / kPi;
  AxisSpec axis;
  const double min_deg = s.number("min_deg", -180.0, -1e6, 1e6);
  const double max_deg = s.number("max_deg", 180.0, -1e6, 1e6);
  if (min_deg >= max_deg) s.fail("\"min_deg\" must be below \"max_deg\"");
  axis.min_rad = min_deg / kDegPerRad;
  axis.max_rad = max_deg / kDegPerRad;
  axis.max_speed_rad_s = s.number("max_speed_deg_s", 30.0, 1e-6, 1e6) / kDegPerRad;
  axis.accel_rad_s2 = s.number("accel_deg_s2", 60.0, 1e-6, 1e7) / kDegPerRad;
  axis.continuous = s.boolean("continuous", false);
  return axis;
}

}  // namespace vdrig::rig
