// Irradiance environment maps with 9 spherical-harmonic coefficients (Ramamoorthi & Hanrahan 2001, "An efficient
// representation for irradiance environment maps").
//
// The radiance is projected onto the real SH of bands 0..2, L_i = integral of L(w) y_i(w) dw (a sum over the map's
// pixels with the row solid angle), and the irradiance is E(n) = sum_i A_l(i) L_i y_i(n) with the clamped-cosine
// factors A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4 (Funk-Hecke). E is exact for radiance of band <= 2; for real
// maps the error is what the dropped bands 3.. carry through the cosine kernel (A_3 = 0, A_4 = -pi / 24); docs/probe.md
// gives it for the real probes.
//
// Basis: bands 0..2 of the real SH of core/sh_basis.hpp (index i = l (l + 1) + m, K_l^m normalisation,
// Condon-Shortley phase), the same basis fitting/ uses.
#pragma once

#include <array>
#include <vector>

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
/// The same over any quadrature of the sphere: unit directions and radiance x solid angle, paired.
Sh9 project_sh9(const std::vector<Vec3d>& directions, const std::vector<Rgb>& radiance_times_sr);

/// E(n) = sum_i A_l(i) L_i y_i(n) for a unit normal n (probe frame).
Rgb sh9_irradiance(const Sh9& radiance, const Vec3d& normal);

/// The band-limited radiance itself, sum_i L_i y_i(dir) (what the 9 coefficients keep of the map).
Rgb sh9_radiance(const Sh9& radiance, const Vec3d& dir);

}  // namespace vdrig::probe
