// The checks every request of the web console passes before it is routed (docs/web.md, "Threat model").
#pragma once

#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>
#include <unordered_map>

namespace vdrig::web {

/// a == b in a time that does not depend on where they first differ (no timing oracle on the token).
bool same_secret(const std::string& a, const std::string& b);

/// The value of cookie `name` in a Cookie header ("a=1; b=2"), or "".
std::string cookie_value(const std::string& header, const std::string& name);

/// A token bucket per client address: `burst` requests at once, refilled at `rate_per_s`. Addresses whose bucket
/// is full again are forgotten, so the table stays small whatever the clients.
class RateLimiter {
 public:
  RateLimiter(double rate_per_s, double burst) : rate_per_s_(rate_per_s), burst_(burst) {}
  /// Takes one request from `address`'s bucket; false when it is empty.
  bool allow(const std::string& address);

 private:
  using Clock = std::chrono::steady_clock;
  struct Bucket {
    double tokens = 0;
    Clock::time_point updated;
  };
  double rate_per_s_, burst_;
  std::mutex mutex_;
  std::unordered_map<std::string, Bucket> buckets_;
  Clock::time_point last_prune_{};
};

}  // namespace vdrig::web
