// Camera response: the map from exposure X = radiance * exposure_s * gain to the stored pixel code.
// Stored as its inverse per channel (code -> relative exposure), as Debevec-Malik recover it.
// Channels are indexed R, G, B (0, 1, 2); images are stored B, G, R, so image channel c uses curve channel 2 - c.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "vdrig/core/result.hpp"

namespace vdrig {

class ResponseCurve {
 public:
  ResponseCurve() = default;
  /// Linear response of a raw camera with `bits` bits: code = round(X * max_code), X = 1 is saturation.
  static ResponseCurve linear(int bits);
  /// Filmic S-curve, a realistic default: f(X) = X^g / (X^g + c (1 - X)^g') ... normalised so f(0)=0, f(1)=1.
  /// `contrast` > 1 steepens the mid-tones. X = 1 saturates.
  static ResponseCurve s_curve(int bits, double gamma = 2.2, double contrast = 1.3);
  /// From an inverse table per channel (size 2^bits each, strictly increasing over unclipped codes).
  static Result<ResponseCurve> from_inverse(int bits, std::array<std::vector<double>, 3> inverse);

  int bits() const { return bits_; }
  int max_code() const { return (1 << bits_) - 1; }
  bool empty() const { return bits_ == 0; }

  /// Forward response: exposure X (>= 0) -> continuous code in [0, max_code] (before quantisation/noise).
  double forward(int channel, double exposure) const;
  /// Inverse response: code -> relative exposure X (interpolates between integer codes).
  double inverse(int channel, double code) const;
  const std::vector<double>& inverse_table(int channel) const { return inverse_[channel]; }

  nlohmann::json to_json() const;
  static Result<ResponseCurve> from_json(const nlohmann::json& j);

 private:
  int bits_ = 0;
  std::array<std::vector<double>, 3> inverse_;  // per channel, indexed by code
};

}  // namespace vdrig
