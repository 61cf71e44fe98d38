#include "vdrig/core/response.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace vdrig {

ResponseCurve ResponseCurve::linear(int bits) {
  VDRIG_CHECK(bits >= 1 && bits <= 16, "response bits in [1, 16]");
  ResponseCurve r;
  r.bits_ = bits;
  const int n = 1 << bits;
  for (auto& ch : r.inverse_) {
    ch.resize(n);
    for (int k = 0; k < n; ++k) ch[k] = static_cast<double>(k) / (n - 1);
  }
  return r;
}

ResponseCurve ResponseCurve::s_curve(int bits, double gamma, double contrast) {
  VDRIG_CHECK(bits >= 1 && bits <= 16, "response bits in [1, 16]");
  VDRIG_CHECK(gamma > 0 && contrast > 0, "S-curve gamma and contrast must be positive");
  // Forward: y0 = X^(1/gamma), y = y0^c / (y0^c + (1 - y0)^c). Inverted in closed form per code:
  // y / (1 - y) = (y0 / (1 - y0))^c, so y0 = q / (1 + q) with q = (y / (1 - y))^(1/c), and X = y0^gamma.
  ResponseCurve r;
  r.bits_ = bits;
  const int n = 1 << bits;
  for (auto& ch : r.inverse_) {
    ch.resize(n);
    for (int k = 0; k < n; ++k) {
      const double y = static_cast<double>(k) / (n - 1);
      if (k == 0) {
        ch[k] = 0.0;
        continue;
      }
      if (k == n - 1) {
        ch[k] = 1.0;
        continue;
      }
      const double q = std::pow(y / (1.0 - y), 1.0 / contrast);
      ch[k] = std::pow(q / (1.0 + q), gamma);
    }
  }
  return r;
}

Result<ResponseCurve> ResponseCurve::from_inverse(int bits, std::array<std::vector<double>, 3> inverse) {
  if (bits < 1 || bits > 16) return make_error(ErrorCode::kInvalidArgument, "response bits must be in [1, 16]");
  const size_t n = size_t{1} << bits;
  for (int c = 0; c < 3; ++c) {
    if (inverse[c].size() != n)
      return make_error(ErrorCode::kInvalidArgument, "response table of channel " + std::to_string(c) + " has " +
                                                         std::to_string(inverse[c].size()) + " entries, want " +
                                                         std::to_string(n));
    for (size_t k = 1; k < n; ++k)
      if (!(inverse[c][k] >= inverse[c][k - 1]))
        return make_error(ErrorCode::kInvalidArgument, "response table of channel " + std::to_string(c) +
                                                           " is not monotonic at code " + std::to_string(k));
  }
  ResponseCurve r;
  r.bits_ = bits;
  r.inverse_ = std::move(inverse);
  return r;
}

double ResponseCurve::forward(int channel, double exposure) const {
  const auto& inv = inverse_[channel];
  if (exposure <= inv.front()) return 0.0;
  if (exposure >= inv.back()) return static_cast<double>(max_code());
  const auto it = std::upper_bound(inv.begin(), inv.end(), exposure);
  const size_t k = static_cast<size_t>(it - inv.begin());  // inv[k-1] <= exposure < inv[k]
  const double lo = inv[k - 1], hi = inv[k];
  const double f = hi > lo ? (exposure - lo) / (hi - lo) : 0.0;
  return static_cast<double>(k - 1) + f;
}

double ResponseCurve::inverse(int channel, double code) const {
  const auto& inv = inverse_[channel];
  if (code <= 0) return inv.front();
  if (code >= max_code()) return inv.back();
  const int k = static_cast<int>(code);
  const double f = code - k;
  return inv[k] * (1.0 - f) + inv[k + 1] * f;
}

nlohmann::json ResponseCurve::to_json() const {
  return {{"format_version", 1}, {"bits", bits_}, {"inverse", {inverse_[0], inverse_[1], inverse_[2]}}};
}

Result<ResponseCurve> ResponseCurve::from_json(const nlohmann::json& j) {
  try {
    std::array<std::vector<double>, 3> inv;
    for (int c = 0; c < 3; ++c) inv[c] = j.at("inverse").at(c).get<std::vector<double>>();
    return from_inverse(j.at("bits").get<int>(), std::move(inv));
  } catch (const nlohmann::json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("response curve JSON: ") + e.what());
  }
}

}  // namespace vdrig
