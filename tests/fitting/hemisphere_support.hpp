// Helpers shared by the SH and HSH tests: sample directions, a Phong-like lobe, and an RMS over the hemisphere.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "vdrig/fitting/sh.hpp"

namespace vdrig::fitting::test_support {

// Roughly uniform directions on the upper hemisphere (Fibonacci spiral in cos zenith), jittered when seed != 0.
inline std::vector<Vec3d> fibonacci_hemisphere(int count, unsigned seed = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  std::vector<Vec3d> dirs;
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - (i + 0.5 + (seed ? jitter(rng) : 0.0)) / count;
    const double r = std::sqrt(1.0 - z * z);
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return dirs;
}

// Phong-like lobe Kd + Ks max(0, v.r)^m.
inline double lobe(const Vec3d& v, const Vec3d& r, double kd, double ks, double exponent) {
  return kd + ks * std::pow(std::max(0.0, v.dot(r)), exponent);
}

// RMS over the upper hemisphere (area-weighted, by quadrature) of fitted(v) - truth(v).
template <typename Fitted, typename Truth>
double hemisphere_rms(const Fitted& fitted, const Truth& truth) {
  static const HemisphereQuadrature quad = hemisphere_quadrature(48, 96);
  double sum = 0.0;
  for (std::size_t j = 0; j < quad.directions.size(); ++j) {
    const double d = fitted(quad.directions[j]) - truth(quad.directions[j]);
    sum += quad.weights[j] * d * d;
  }
  return std::sqrt(sum / (2.0 * kPi));
}

}  // namespace vdrig::fitting::test_support
