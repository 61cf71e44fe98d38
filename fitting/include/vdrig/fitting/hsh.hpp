// Hemispherical harmonics (HSH, Gautron, Krivanek, Pattanaik & Bouatouch 2004): an orthonormal basis on the
// upper hemisphere, for view-dependent radiance that only exists above the surface.
//
//   H_l^m = sqrt2 Kh_l^m cos(m azimuth) Ph_l^m(cos zenith)      m > 0
//   H_l^m = sqrt2 Kh_l^m sin(-m azimuth) Ph_l^-m(cos zenith)    m < 0
//   H_l^0 = Kh_l^0 Ph_l^0(cos zenith)
// with the shifted associated Legendre functions Ph_l^m(x) = P_l^m(2x - 1) (x = cos zenith in [0, 1] mapped onto
// [-1, 1]) and Kh_l^m = sqrt((2l+1)(l-|m|)! / (2 pi (l+|m|)!)) = sqrt2 K_l^m, so that
// int over the upper hemisphere of H_i H_k = delta_ik. Same index i = l (l + 1) + m, n bands -> n^2 functions,
// same Condon-Shortley convention as sh.hpp.
//
// Implementation: H_i(d) = sqrt2 y_i(d') where d' is the direction with the same azimuth and cos(zenith') =
// 2 cos(zenith) - 1, i.e. d' = (k x, k y, 2z - 1) with k = 2 sqrt(z / (1 + z)) (smooth at the zenith), so the SH
// recurrence of sh.hpp is reused without trigonometry.
//
// Unlike SH, HSH have no unsampled lower hemisphere to handle: plain (weighted) least squares on the samples is
// the fit; the Voronoi projection c_i = sum_j f(s_j) H_i(s_j) dA_j is also offered (it is what LSOP reduces to
// for an orthonormal basis). Fitting many texels at once works as in sh.hpp (LinearFitOperator::apply_batch).
// Because the basis is orthonormal on the hemisphere, the fitted coefficients do not cancel each other and the
// post-fit ringing windows of sh.hpp are valid here (docs/models.md has what they cost). `smoothing` works as in
// sh.hpp: (Y^T W Y / s + lambda D) c = Y^T W f / s for least squares, c_i = b_i / (1 + lambda D_i) for projection.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/sh.hpp"

namespace vdrig::fitting {

inline constexpr int kMaxHshBands = kMaxShBands;

/// All n^2 HSH at a unit direction with z >= 0 into out[0 .. n^2). Directions slightly below the horizon are
/// treated as on it (z clamped to 0); HSH are not defined below.
void hsh_basis(int bands, const Vec3d& dir, double* out);
Eigen::VectorXd hsh_basis(int bands, const Vec3d& dir);

/// N x n^2 basis matrix, row j = basis at directions[j] (normalised here).
Eigen::MatrixXd hsh_basis_matrix(int bands, const std::vector<Vec3d>& directions);

enum class HshFitMethod { kLeastSquares, kProjection };
const char* to_string(HshFitMethod method);

/// Options of an HSH fit.
struct HshFitOptions {
  int bands = 3;  // n: n^2 coefficients per channel, 1..kMaxHshBands
  HshFitMethod method = HshFitMethod::kLeastSquares;
  RingingWindow window = RingingWindow::kNone;  // per-band damping after the fit (valid for both methods)
  double smoothing = 0.0;                       // Laplacian penalty lambda as in sh.hpp, >= 0

  bool is_valid(std::string* why = nullptr) const;
  /// Every field as text (model_options.hpp): equal text, equal options.
  std::string fingerprint() const;
};

/// Operator of an HSH fit on fixed directions. `weights` (empty = all 1): least-squares weights for
/// kLeastSquares, a mask (weight <= 0 leaves the sample out of the Voronoi partition) for kProjection.
LinearFitOperator make_hsh_fit_operator(const HshFitOptions& options, const std::vector<Vec3d>& directions,
                                        const std::vector<double>& weights = {});

/// One-shot fit of one texel: values N x C -> n^2 x C coefficients.
Eigen::MatrixXd fit_hsh(const HshFitOptions& options, const std::vector<Vec3d>& directions,
                        const Eigen::Ref<const Eigen::MatrixXd>& values, const std::vector<double>& weights = {});

/// Value of a fitted HSH expansion at a unit direction (z >= 0): coeffs n^2 x C, returns C values.
Eigen::VectorXd eval_hsh(const Eigen::Ref<const Eigen::MatrixXd>& coeffs, const Vec3d& dir);

}  // namespace vdrig::fitting
