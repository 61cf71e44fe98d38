#include "guard.hpp"

#include <algorithm>

namespace vdrig::web {

bool same_secret(const std::string& a, const std::string& b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i)
    diff |= static_cast<unsigned char>((i < a.size() ? a[i] : 0) ^ (i < b.size() ? b[i] : 0));
  return diff == 0;
}

std::string cookie_value(const std::string& header, const std::string& name) {
  std::size_t at = 0;
  while (at < header.size()) {
    std::size_t end = header.find(';', at);
    if (end == std::string::npos) end = header.size();
    std::size_t begin = header.find_first_not_of(' ', at);
    if (begin < end) {
      const std::string pair = header.substr(begin, end - begin);
      const std::size_t eq = pair.find('=');
      if (eq != std::string::npos && pair.compare(0, eq, name) == 0 && eq == name.size()) return pair.substr(eq + 1);
    }
    at = end + 1;
  }
  return "";
}

bool RateLimiter::allow(const std::string& address) {
  const auto now = Clock::now();
  std::lock_guard lock(mutex_);
  if (now - last_prune_ > std::chrono::seconds(10)) {
    last_prune_ = now;
    std::erase_if(buckets_, [&](const auto& entry) {
      const double elapsed_s = std::chrono::duration<double>(now - entry.second.updated).count();
      return entry.second.tokens + elapsed_s * rate_per_s_ >= burst_;
    });
  }
  auto [it, fresh] = buckets_.try_emplace(address, Bucket{burst_, now});
  Bucket& b = it->second;
  if (!fresh) {
    const double elapsed_s = std::chrono::duration<double>(now - b.updated).count();
    b.tokens = std::min(burst_, b.tokens + elapsed_s * rate_per_s_);
    b.updated = now;
  }
  if (b.tokens < 1) return false;
  b.tokens -= 1;
  return true;
}

}  // namespace vdrig::web
