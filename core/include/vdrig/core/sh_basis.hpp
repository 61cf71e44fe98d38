// Real spherical harmonics: the one basis evaluation shared by fitting/ (SH and HSH reflectance models) and probe/
// (SH-9 irradiance).
//
// Conventions (docs/models.md, "The SH basis"):
//  - y_i with i = l (l + 1) + m, l in [0, bands), m in [-l, l]; `bands` = n gives n^2 functions, n <= kMaxShBands.
//  - K_l^m = sqrt((2l+1)(l-|m|)! / (4 pi (l+|m|)!));
//    m > 0: sqrt2 K cos(m azimuth) P_l^m(cos zenith); m < 0: sqrt2 K sin(-m azimuth) P_l^-m(cos zenith);
//    m = 0: K P_l^0(cos zenith).
//  - P_l^m INCLUDES the Condon-Shortley phase (-1)^m. The phase only flips the sign of whole basis functions, so
//    the basis is orthonormal on the sphere either way; it matters when exchanging coefficients with code using
//    the other convention.
//  - Evaluation is from the unit direction (x, y, z) without trigonometry: K P_l^m(z) = Q_l^m(z) sin^m(zenith)
//    and sin^m(zenith) (cos, sin)(m azimuth) = (Re, Im)((x + i y)^m); Q comes from the normalised three-term
//    recurrence of ShRecurrence, which never forms large factorials and is stable for every n <= kMaxShBands.
#pragma once

#include "vdrig/core/geometry.hpp"

namespace vdrig {

inline constexpr int kMaxShBands = 10;

/// Number of functions of an n-band expansion.
constexpr int sh_coeff_count(int bands) { return bands * bands; }
/// Flat index of (l, m).
constexpr int sh_index(int l, int m) { return l * (l + 1) + m; }

/// The normalised recurrence for Q_l^m = K_l^m P_l^m / sin^m(zenith):
///   Q_m^m = diag(m) (Condon-Shortley sign included),  Q_l^m = a(l, m) (z Q_{l-1}^m - b(l, m) Q_{l-2}^m), l > m.
/// Exposed so that code generating the same evaluation elsewhere (the viewer's GLSL) uses the same constants.
double sh_recurrence_diag(int m);
double sh_recurrence_a(int l, int m);
double sh_recurrence_b(int l, int m);

/// All n^2 real SH at a unit direction `dir` into out[0 .. n^2). Precondition (checked): 1 <= bands <=
/// kMaxShBands; |dir| = 1 is not checked (the result scales with |dir|^l otherwise).
void sh_basis(int bands, const Vec3d& dir, double* out);

}  // namespace vdrig
