// What a camera makes of one texel's radiance across views, for the fit-quality tests and benchmarks that work on a
// texel's observations directly (without rendering images): one exposure for all of the texel's views, shot noise,
// read noise, rounding and clipping to the camera's codes. The image path (renderer.hpp's `expose`) does the same per
// pixel; this is its texel-level shorthand, so fits are judged on the input a real capture gives them (quantised,
// noisy), not on noise-free radiance of exactly the fitted form.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>

namespace vdrig::sim {

struct TexelRecording {
  double peak_code = 220.0;       // the exposure puts the texel's brightest observation (any channel) at this code
  double saturated_code = 255.0;  // 8 bits
  double full_well_e = 20000.0;   // electrons at the saturated code: shot noise sigma = sqrt(code / (e per code))
  double read_noise_codes = 0.5;  // Gaussian read noise, in codes
};

/// Replaces each radiance by what the camera records of it, back in radiance units (code / gain); deterministic for
/// `seed`. Returns the gain in codes per radiance unit (0 when every radiance is black: nothing is changed).
double record_texel(std::span<Eigen::Vector3f> radiance, const TexelRecording& recording, uint64_t seed);

}  // namespace vdrig::sim
