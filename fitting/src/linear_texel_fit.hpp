// Fitting texels whose model is linear in its parameters for fixed directions (PTM, SH, HSH) with one operator per
// direction set: in RTI every texel sees the same light directions, so the operator, the basis and the hat
// matrix's diagonal are computed once for the first texel and reused for every texel with the same directions
// (bitwise: a texel with a clipped or held-out sample gets its own). Private to fitting/.
//
// Leave-one-out: for a linear smoother c = P f with prediction y = Y c = H f (H = Y P), the residual at sample j of
// the fit without sample j is r_j / (1 - H_jj) (exact for least squares, with or without a fixed ridge penalty), so
// LOO costs one pass over the residuals instead of N refits.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/fit_quality.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

class SharedDirectionLinearFit {
 public:
  using Basis = std::function<Eigen::MatrixXd(const std::vector<Vec3d>& directions)>;     // N x K
  using Operator = std::function<Eigen::MatrixXd(const std::vector<Vec3d>& directions)>;  // K x N

  SharedDirectionLinearFit(Basis basis, Operator fit_operator)
      : basis_(std::move(basis)), operator_(std::move(fit_operator)) {}

  /// Coefficients K x C of `values` (N x C, row j = sample j of obs) on obs's directions.
  Eigen::MatrixXd fit(const TexelObservations& obs, const Eigen::Ref<const Eigen::MatrixXd>& values) {
    prepare(obs);
    return columnwise_product(operator_matrix_, values);
  }

  /// Residual statistics of `coeffs` (from fit() on the same obs) per channel: RMS and mean percentage error as
  /// measure_quality, and the leave-one-out RMS. Channels beyond the third are ignored.
  void quality(const Eigen::Ref<const Eigen::MatrixXd>& values, const Eigen::Ref<const Eigen::MatrixXd>& coeffs,
               FitQuality* q, Vec3d* loo_rms) const {
    const Eigen::MatrixXd predicted = columnwise_product(basis_matrix_, coeffs);
    residual_quality(values, predicted, leave_one_out(values, predicted), q, loo_rms);
  }

  /// The leave-one-out predictions of a fit whose predictions on the current direction set are `predicted`:
  /// f_j + (predicted_j - f_j) / (1 - H_jj) per sample j.
  Eigen::MatrixXd leave_one_out(const Eigen::Ref<const Eigen::MatrixXd>& values,
                                const Eigen::Ref<const Eigen::MatrixXd>& predicted) const {
    Eigen::MatrixXd loo = predicted;
    for (Eigen::Index j = 0; j < values.rows(); ++j) {
      const double denom = 1.0 - hat_diagonal_[j];
      if (denom > 1e-9) loo.row(j) = values.row(j) + (predicted.row(j) - values.row(j)) / denom;
    }
    return loo;
  }

  /// RMS and mean percentage error of `predicted` against `values` (N x C, C >= 3), as measure_quality, and the RMS
  /// of `loo_predicted` against them.
  static void residual_quality(const Eigen::Ref<const Eigen::MatrixXd>& values,
                               const Eigen::Ref<const Eigen::MatrixXd>& predicted,
                               const Eigen::Ref<const Eigen::MatrixXd>& loo_predicted, FitQuality* q, Vec3d* loo_rms) {
    const auto n = values.rows();
    q->samples = static_cast<int>(n);
    for (int c = 0; c < 3; ++c) {
      double sq = 0, loo = 0, pct = 0;
      int pct_n = 0;
      for (Eigen::Index j = 0; j < n; ++j) {
        const double o = values(j, c), r = predicted(j, c) - o, rl = loo_predicted(j, c) - o;
        sq += r * r;
        loo += rl * rl;
        if (o > 0) {
          pct += std::abs(r) / o * 100.0;
          ++pct_n;
        }
      }
      q->rms[c] = n ? std::sqrt(sq / static_cast<double>(n)) : 0.0;
      q->mean_percent[c] = pct_n ? pct / pct_n : 0.0;
      (*loo_rms)[c] = n ? std::sqrt(loo / static_cast<double>(n)) : 0.0;
    }
  }

  /// The basis matrix of the current direction set (N x K).
  const Eigen::MatrixXd& basis_matrix() const { return basis_matrix_; }
  /// H_jj of the current direction set.
  const Eigen::VectorXd& hat_diagonal() const { return hat_diagonal_; }

 private:
  /// a * b one column of b at a time: matrix-vector products, which unlike Eigen's matrix-matrix product do not
  /// repack `a` on every call (with 3 columns the packing cost as much as the arithmetic).
  static Eigen::MatrixXd columnwise_product(const Eigen::MatrixXd& a, const Eigen::Ref<const Eigen::MatrixXd>& b) {
    Eigen::MatrixXd out(a.rows(), b.cols());
    for (Eigen::Index c = 0; c < b.cols(); ++c) out.col(c).noalias() = a * b.col(c);
    return out;
  }

  void prepare(const TexelObservations& obs) {
    if (obs.direction == directions_ && basis_matrix_.rows() == static_cast<Eigen::Index>(obs.size())) return;
    directions_ = obs.direction;
    std::vector<Vec3d> dirs(obs.size());
    for (size_t i = 0; i < obs.size(); ++i) dirs[i] = obs.direction[i].cast<double>();
    basis_matrix_ = basis_(dirs);
    operator_matrix_ = operator_(dirs);
    hat_diagonal_ = (basis_matrix_.array() * operator_matrix_.transpose().array()).rowwise().sum();
  }

  Basis basis_;
  Operator operator_;
  std::vector<Eigen::Vector3f> directions_;
  Eigen::MatrixXd basis_matrix_, operator_matrix_;
  Eigen::VectorXd hat_diagonal_;
};

}  // namespace vdrig::fitting
