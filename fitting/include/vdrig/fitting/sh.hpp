// Real spherical harmonics (SH) for per-texel view-dependent radiance, and the linear fitters of the source
// (zero-hemisphere projection, least-squares optimal projection) plus plain weighted least squares.
//
// Basis: the real SH of core/sh_basis.hpp (index i = l (l + 1) + m, K_l^m normalisation, Condon-Shortley phase).
//
// Fitting. All three methods are linear in the sample values: for a fixed set of N directions (and weights) the
// K = n^2 coefficients of a channel are c = P f with a K x N operator P. `LinearFitOperator` holds P and applies it
// to any number of channels/texels at once as one matrix product, which is how a whole map is fitted:
//
//   auto op = make_sh_fit_operator(options, directions);   // once per distinct direction set (+ mask)
//   // values: N x (3 * texels), column 3 t + c = channel c of texel t, i.e. memory [texel][channel][sample]
//   op.apply_batch(values, coeffs);                        // coeffs: K x (3 * texels), memory [texel][channel][k]
//
// Texels whose sample directions or masks differ need their own operator; `ShTexelFitter` fits such texels one at
// a time and shares what can be shared (the cached hemisphere Gram factorisation, scratch buffers). Callers with
// an observation map where most texels see the same views should group texels by mask and use apply_batch.
//
// Methods (f restricted to the upper hemisphere H; dA_j = spherical Voronoi area of sample j, voronoi.hpp):
//  - kZeroHemisphere (ZH, Sloan et al. 2002): c_i = sum_j f(s_j) y_i(s_j) dA_j, i.e. the projection of f extended
//    by zero below the horizon. Cheap but biased on H: the fitted function is the band-limited version of a
//    function with a jump at the horizon, so it is roughly halved near the horizon and rings.
//  - kLsop (least-squares optimal projection, Sloan et al. 2003): minimises int_H (f - sum c_i y_i)^2, giving
//    A c = b with A_ik = int_H y_i y_k (exact quadrature, cached per band count) and b the ZH coefficients.
//    A is symmetric positive definite for every n (the y_i are polynomials, linearly independent on any open
//    set), but ill-conditioned (even-in-z and odd-in-z combinations nearly coincide on H; cond(A) grows by ~30x
//    per band, docs/models.md). The solve is a Cholesky (LLT) factorisation of the exactly computed A; cond(A)
//    also amplifies the quadrature error of b (the Voronoi areas are exact, the rule sum f y dA is not), which
//    shows as large coefficients cancelling each other and as ringing near the horizon. Prefer kLeastSquares,
//    smoothing, or hemispherical harmonics (hsh.hpp) beyond n = 5 or where the horizon is barely sampled.
//  - kLeastSquares: min sum_j w_j (f(s_j) - sum c_i y_i(s_j))^2, by a column-pivoting QR of sqrt(W) Y (no normal
//    equations, so cond(A)^2 is avoided); rank-deficient sets (fewer samples than coefficients, coincident
//    samples) get the minimum-norm solution of a complete orthogonal decomposition.
//
// Weights: for kLeastSquares they are the least-squares weights (default 1). For ZH and LSOP they act as a mask:
// samples with weight <= 0 are left out of the Voronoi partition (their neighbours' cells grow to cover the
// hemisphere), positive weights take part with their Voronoi area (the quadrature needs a partition of H, so
// scaling areas by confidence would bias the integral).
//
// Ringing suppression, two kinds:
//  - `window`: per-band sigma factors multiplying the coefficients of band l after the fit (folded into P).
//    Hanning: (1 + cos(pi l / n)) / 2; Lanczos: sinc(pi l / n) (Sloan, "Stupid SH tricks"). Only valid for ZH:
//    LSOP and LS coefficients on the hemisphere are large and cancel each other (cond(A) above), and damping
//    some bands breaks the cancellation. ShFitOptions::is_valid rejects that combination.
//  - `smoothing` (lambda >= 0): Tikhonov penalty lambda sum_i (l_i (l_i + 1))^2 c_i^2 on the fitted function's
//    Laplacian, added to the hemisphere error int_H (f - sum c y)^2. LSOP solves (A + lambda D) c = b; LS solves
//    (Y^T W Y / s + lambda D) c = Y^T W f / s with s = sum w / (2 pi), so lambda means the same for both
//    (Y^T W Y / s approximates A); ZH divides c_i by (1 + lambda D_i). Typical values 1e-6 .. 1e-4.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/sh_basis.hpp"

namespace vdrig::fitting {

// The basis lives in core (probe/ uses it too); these names keep fitting's callers unqualified.
using vdrig::kMaxShBands;
using vdrig::sh_basis;
using vdrig::sh_coeff_count;
using vdrig::sh_index;

/// All n^2 real SH at a unit direction (core/sh_basis.hpp) as a vector.
Eigen::VectorXd sh_basis(int bands, const Vec3d& dir);

/// N x n^2 basis matrix: row j holds the basis at directions[j] (normalised here).
Eigen::MatrixXd sh_basis_matrix(int bands, const std::vector<Vec3d>& directions);

/// A product rule on the upper hemisphere: Gauss-Legendre in cos(zenith) over [0, 1] times a uniform rule in
/// azimuth. Exact for polynomials in (x, y, z) of total degree d when 2 zenith_nodes - 1 >= d and
/// azimuth_nodes > d. Weights sum to 2 pi.
struct HemisphereQuadrature {
  std::vector<Vec3d> directions;
  std::vector<double> weights;
};
HemisphereQuadrature hemisphere_quadrature(int zenith_nodes, int azimuth_nodes);

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the Legendre recurrence; accurate to ~1e-15).
void gauss_legendre(int count, std::vector<double>& nodes, std::vector<double>& weights);

/// A_ik = int over the upper hemisphere of y_i y_k (n^2 x n^2), computed once per band count with an exact
/// quadrature and cached for the life of the process (thread-safe).
const Eigen::MatrixXd& sh_hemisphere_gram(int bands);

/// 2-norm condition number of sh_hemisphere_gram(bands) (cached).
double sh_hemisphere_gram_condition(int bands);

enum class ShFitMethod { kZeroHemisphere, kLsop, kLeastSquares };
enum class RingingWindow { kNone, kHanning, kLanczos };

const char* to_string(ShFitMethod method);
const char* to_string(RingingWindow window);

/// sigma_l of the window for band l of an n-band fit (1 for kNone).
double ringing_window_factor(RingingWindow window, int l, int bands);

/// Options of an SH fit.
struct ShFitOptions {
  int bands = 4;                                // n: n^2 coefficients per channel, 1..kMaxShBands
  ShFitMethod method = ShFitMethod::kLsop;      // see the file comment
  RingingWindow window = RingingWindow::kNone;  // kZeroHemisphere only (see the file comment)
  double smoothing = 0.0;                       // lambda of the Laplacian penalty, >= 0

  /// False with the reason for bands out of range, a negative/non-finite smoothing, or a window on LSOP/LS.
  bool is_valid(std::string* why = nullptr) const;
  /// Every field as text (model_options.hpp): equal text, equal options.
  std::string fingerprint() const;
};

/// c = P f for a fixed set of N sample directions: maps N sample values of one channel to K coefficients.
class LinearFitOperator {
 public:
  LinearFitOperator() = default;
  explicit LinearFitOperator(Eigen::MatrixXd matrix);

  int coeff_count() const { return static_cast<int>(matrix_.rows()); }
  int sample_count() const { return static_cast<int>(matrix_.cols()); }
  const Eigen::MatrixXd& matrix() const { return matrix_; }

  /// values: N x C (a column per channel) -> K x C coefficients.
  Eigen::MatrixXd apply(const Eigen::Ref<const Eigen::MatrixXd>& values) const;

  /// Many texels at once, single precision: values is N x M (any M; column = one channel of one texel),
  /// coeffs must be K x M. Work is split by columns over `threads` std::threads (0: hardware concurrency).
  /// Both may be Eigen::Map views of caller memory (column-major, i.e. [column][sample] and [column][k]).
  void apply_batch(const Eigen::Ref<const Eigen::MatrixXf>& values, Eigen::Ref<Eigen::MatrixXf> coeffs,
                   int threads = 0) const;

 private:
  Eigen::MatrixXd matrix_;
  Eigen::MatrixXf matrix_f_;
};

/// The K x N operator of a weighted least-squares fit on basis matrix `basis` (N x K, row = sample):
/// min sum_j w_j (f_j - basis_j c)^2 / s + c^T diag(penalty) c with s = sum_j w_j / (2 pi) (see `smoothing`).
/// `weights` may be empty (all 1); samples with w_j <= 0 get a zero column. An empty or all-zero `penalty`
/// gives the plain (minimum-norm) least-squares solution.
Eigen::MatrixXd least_squares_operator(const Eigen::MatrixXd& basis, const std::vector<double>& weights,
                                       const Eigen::VectorXd& penalty = {});

/// Diagonal of the Laplacian penalty: (l_i (l_i + 1))^2 for the n^2 coefficients (shared by SH and HSH).
Eigen::VectorXd laplacian_penalty(int bands);

/// The window sigma_l expanded to the n^2 coefficients.
Eigen::VectorXd ringing_window_vector(RingingWindow window, int bands);

/// Voronoi areas of the samples with weight > 0 (all if `weights` is empty); others get 0. See voronoi.hpp.
std::vector<double> masked_voronoi_areas(const std::vector<Vec3d>& directions, const std::vector<double>& weights);

/// Operator of an SH fit on fixed directions (see the file comment for the meaning of `weights`, which may be
/// empty). Precondition: options.is_valid(); weights empty or of the same size as directions.
LinearFitOperator make_sh_fit_operator(const ShFitOptions& options, const std::vector<Vec3d>& directions,
                                       const std::vector<double>& weights = {});

/// One-shot fit of one texel: values N x C (e.g. RGB) -> n^2 x C coefficients.
Eigen::MatrixXd fit_sh(const ShFitOptions& options, const std::vector<Vec3d>& directions,
                       const Eigen::Ref<const Eigen::MatrixXd>& values, const std::vector<double>& weights = {});

/// Fits texels with individual direction sets one at a time, reusing the cached Gram factorisation (LSOP) and
/// scratch memory; no operator matrix is formed (O(N K) per channel for ZH/LSOP after the Voronoi areas).
class ShTexelFitter {
 public:
  explicit ShTexelFitter(const ShFitOptions& options);
  /// values N x C -> n^2 x C.
  Eigen::MatrixXd fit(const std::vector<Vec3d>& directions, const Eigen::Ref<const Eigen::MatrixXd>& values,
                      const std::vector<double>& weights = {});

 private:
  ShFitOptions options_;
  Eigen::MatrixXd basis_;
  Eigen::VectorXd window_;
};

/// Value of a fitted expansion at a unit direction: coeffs is n^2 x C (n inferred), returns C values.
Eigen::VectorXd eval_sh(const Eigen::Ref<const Eigen::MatrixXd>& coeffs, const Vec3d& dir);

}  // namespace vdrig::fitting
