// Reading a JSON object with up-front validation: a rig backend's settings, the simulator's "sim" section, a vdrigd
// request. Every problem is collected (not just the first) so a bad config file is fixed in one round; the result is
// one kInvalidArgument naming the section and each reason. Units are whatever the caller's keys say (the rig's
// edges are degrees, millimetres and seconds); converting is the caller's job.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig {

class Settings {
 public:
  /// `where` names the section in messages ("stage modbus-tcp", "stage modbus-tcp.pan", "sim.camera").
  /// `envelope` lists keys that belong to the enclosing format rather than to this section (a rig section's
  /// "backend", a request's "cmd" and "id"): reject_unknown() accepts them. A non-object section is a problem.
  Settings(const nlohmann::json& section, std::string where, std::initializer_list<const char*> envelope = {});

  /// A number in [min, max]; `fallback` when absent. A non-number, non-finite or out-of-range value is an error.
  double number(const std::string& key, double fallback, double min = -std::numeric_limits<double>::max(),
                double max = std::numeric_limits<double>::max());
  /// A required number in [min, max] (0 and an error when absent).
  double required_number(const std::string& key, double min = -std::numeric_limits<double>::max(),
                         double max = std::numeric_limits<double>::max());
  /// An integer in [min, max] (a JSON number with a fractional part is an error).
  long long integer(const std::string& key, long long fallback, long long min, long long max);
  long long required_integer(const std::string& key, long long min, long long max);
  /// An unsigned integer up to `max` (counters, seeds).
  std::uint64_t unsigned_integer(const std::string& key, std::uint64_t fallback,
                                 std::uint64_t max = std::numeric_limits<std::uint64_t>::max());
  bool boolean(const std::string& key, bool fallback);
  /// A string; when `allowed` is not empty it must be one of them.
  std::string string(const std::string& key, const std::string& fallback,
                     std::initializer_list<const char*> allowed = {});
  /// A required, non-empty string.
  std::string required_string(const std::string& key);
  /// An array of finite numbers; when `size` is not 0 it must have exactly that many. `fallback` when absent.
  std::vector<double> number_list(const std::string& key, std::vector<double> fallback, std::size_t size = 0);
  /// An array of unsigned integers (call numbers, indices); `fallback` when absent.
  std::vector<std::uint64_t> unsigned_list(const std::string& key, std::vector<std::uint64_t> fallback);
  /// A sub-object (for nested settings); an empty object and an error when absent and `required`.
  nlohmann::json object(const std::string& key, bool required);
  bool has(const std::string& key) const { return find(key) != nullptr; }

  /// Records a reason of your own (cross-field checks such as min < max).
  void fail(const std::string& reason);
  /// Rejects keys neither in `known` nor in the envelope: a typo would otherwise silently use a default.
  /// `noun` names a key in the message ("unknown setting \"x\"", "unknown field \"x\"").
  void reject_unknown(std::initializer_list<const char*> known);
  void reject_unknown(const std::vector<std::string>& known, const std::string& noun = "setting");
  /// Merges the problems of a nested Settings into this one (each prefixed with the nested `where`).
  void absorb(const Settings& nested);

  bool is_valid(std::string* why) const;
  /// The collected problems as one kInvalidArgument error, "WHERE: invalid settings; REASON; REASON" (call only
  /// when !is_valid()).
  Error error() const;
  /// The collected problems alone, joined by "; " (for callers that frame the message themselves).
  std::string reasons() const;
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  const nlohmann::json* find(const std::string& key) const;
  bool is_known(const std::string& key, const std::vector<std::string>& known) const;

  nlohmann::json section_;
  std::string where_;
  std::vector<std::string> envelope_;
  std::vector<std::string> problems_;
};

}  // namespace vdrig
