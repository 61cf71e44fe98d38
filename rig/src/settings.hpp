// Reading one backend's JSON settings with up-front validation. Every problem is collected (not just the first)
// so a bad config file is fixed in one round; the result is a kInvalidArgument naming the section and each reason.
// Units at this edge are degrees, millimetres and seconds (docs/conventions.md); converting to radians is the caller's.
#pragma once

#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

class Settings {
 public:
  /// `where` names the section in messages ("stage modbus-tcp", "stage modbus-tcp.pan").
  Settings(const nlohmann::json& section, std::string where);

  /// A number in [min, max]; `fallback` when absent. A non-number or out-of-range value is an error.
  double number(const std::string& key, double fallback, double min = -std::numeric_limits<double>::max(),
                double max = std::numeric_limits<double>::max());
  /// A required number in [min, max] (0 and an error when absent).
  double required_number(const std::string& key, double min = -std::numeric_limits<double>::max(),
                         double max = std::numeric_limits<double>::max());
  /// An integer in [min, max] (a JSON number with a fractional part is an error).
  long long integer(const std::string& key, long long fallback, long long min, long long max);
  long long required_integer(const std::string& key, long long min, long long max);
  bool boolean(const std::string& key, bool fallback);
  /// A string; when `allowed` is not empty it must be one of them.
  std::string string(const std::string& key, const std::string& fallback,
                     std::initializer_list<const char*> allowed = {});
  std::string required_string(const std::string& key);
  /// A sub-object (for nested settings); an empty object and an error when absent and `required`.
  nlohmann::json object(const std::string& key, bool required);
  bool has(const std::string& key) const { return section_.is_object() && section_.contains(key); }

  /// Records a reason of your own (cross-field checks such as min < max).
  void fail(const std::string& reason);
  /// Rejects keys not in `known` ("backend" is always known): a typo would otherwise silently use a default.
  void reject_unknown(std::initializer_list<const char*> known);
  /// Merges the problems of a nested Settings into this one.
  void absorb(const Settings& nested);

  bool is_valid(std::string* why) const;
  /// The collected problems as one kInvalidArgument error (call only when !is_valid()).
  Error error() const;
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  const nlohmann::json* find(const std::string& key) const;

  nlohmann::json section_;
  std::string where_;
  std::vector<std::string> problems_;
};

/// Reads the motion keys every axis section shares: min_deg < max_deg (default -180..180), max_speed_deg_s (30),
/// accel_deg_s2 (60), continuous (false); converted to radians.
AxisSpec read_axis_spec(Settings& s);

}  // namespace vdrig::rig
