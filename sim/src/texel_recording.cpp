#include "vdrig/sim/texel_recording.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace vdrig::sim {

double record_texel(std::span<Eigen::Vector3f> radiance, const TexelRecording& recording, uint64_t seed) {
  float brightest = 0.0f;
  for (const auto& rgb : radiance) brightest = std::max(brightest, rgb.maxCoeff());
  if (!(brightest > 0.0f)) return 0.0;
  const double gain = recording.peak_code / brightest;
  const double electrons_per_code = recording.full_well_e / recording.saturated_code;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (auto& rgb : radiance)
    for (int c = 0; c < 3; ++c) {
      const double code = rgb[c] * gain;
      const double sigma =
          std::sqrt(std::max(code, 0.0) / electrons_per_code + recording.read_noise_codes * recording.read_noise_codes);
      rgb[c] =
          static_cast<float>(std::clamp(std::round(code + sigma * unit(rng)), 0.0, recording.saturated_code) / gain);
    }
  return gain;
}

}  // namespace vdrig::sim
