// Irradiance environment maps with 9 spherical-harmonic coefficients (Ramamoorthi & Hanrahan 2001, "An efficient
// representation for irradiance environment maps").
//
// The radiance is projected onto the real SH of bands 0..2, L_i = integral of L(w) y_i(w) dw (a sum over the map's
// pixels with the row solid angle), and the irradiance is E(n) = sum_i A_l(i) L_i y_i(n) with the clamped-cosine
// factors A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4 (Funk-Hecke). E is exact for radiance of band <= 2; for real
// maps the dropped bands 3.. carry little of the cosine kernel (A_3 = 0, A_4 = -pi / 24), which is RH's
// "~1-3 % average error" (bench_probe_lights and test_sh_irradiance measure it on the three real probes).
//
// Basis: real SH (docs/conventions.md), index i = l (l + 1) + m, K_l^m normalisation and the Condon-Shortley phase,
// identical to fitting::sh_basis (test_sh_irradiance checks it), written out for bands 0..2 so that probe does not
// link the fitting module (and its Ceres/zstd dependencies):
//   y0 = 0.282095; y1 = -0.488603 y; y2 = 0.488603 z; y3 = -0.488603 x; y4 = 1.092548 x y; y5 = -1.092548 y z;
//   y6 = 0.315392 (3 z^2 - 1); y7 = -1.092548 x z; y8 = 0.546274 (x^2 - y^2).
#pragma once

#include <array>

#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

inline constexpr int kSh9Count = 9;

/// The 9 basis values y_0..y_8 at a unit direction.
std::array<double, kSh9Count> sh9_basis(const Vec3d& dir);

/// Band l of coefficient index i (0 for i = 0, 1 for 1..3, 2 for 4..8).
constexpr int sh9_band(int i) { return i == 0 ? 0 : (i < 4 ? 1 : 2); }

/// Clamped-cosine convolution factor A_l of band l (pi, 2 pi / 3, pi / 4).
double sh9_cosine_factor(int band);

/// Radiance projected onto the 9 basis functions, one RGB triple per coefficient.
struct Sh9 {
  std::array<Rgb, kSh9Count> coeffs{};
};

/// L_i = sum over pixels of L y_i(pixel centre) * pixel solid angle.
Sh9 project_sh9(const Probe& probe);

/// E(n) = sum_i A_l(i) L_i y_i(n) for a unit normal n (probe frame).
Rgb sh9_irradiance(const Sh9& radiance, const Vec3d& normal);

/// The band-limited radiance itself, sum_i L_i y_i(dir) (what the 9 coefficients keep of the map).
Rgb sh9_radiance(const Sh9& radiance, const Vec3d& dir);

}  // namespace vdrig::probe
