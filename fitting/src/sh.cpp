#include "vdrig/fitting/sh.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/voronoi.hpp"

namespace vdrig::fitting {
namespace {

struct GramEntry {
  Eigen::MatrixXd gram;
  Eigen::LLT<Eigen::MatrixXd> llt;
  double condition = 0.0;
};

const GramEntry& gram_entry(int bands) {
  VDRIG_CHECK(bands >= 1 && bands <= kMaxShBands, "sh_hemisphere_gram: bands out of range");
  static std::mutex mutex;
  static std::array<std::unique_ptr<GramEntry>, kMaxShBands + 1> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = cache[bands];
  if (!slot) {
    auto entry = std::make_unique<GramEntry>();
    // Products y_i y_k are polynomials of degree <= 2 (n - 1) <= 18: 16 Gauss nodes (exact to degree 31) and 40
    // azimuth nodes (exact to trigonometric degree 39) integrate them exactly.
    const HemisphereQuadrature quad = hemisphere_quadrature(16, 40);
    const Eigen::MatrixXd basis = sh_basis_matrix(bands, quad.directions);
    const Eigen::Map<const Eigen::VectorXd> w(quad.weights.data(), static_cast<Eigen::Index>(quad.weights.size()));
    entry->gram = basis.transpose() * w.asDiagonal() * basis;
    entry->gram = 0.5 * (entry->gram + entry->gram.transpose()).eval();
    entry->llt.compute(entry->gram);
    VDRIG_CHECK(entry->llt.info() == Eigen::Success, "sh_hemisphere_gram: Cholesky failed (not SPD?)");
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(entry->gram);
    const auto& sv = svd.singularValues();
    entry->condition = sv(0) / sv(sv.size() - 1);
    slot = std::move(entry);
  }
  return *slot;
}

// From the ZH projections b (K x M) to the coefficients of the configured method, smoothing included.
Eigen::MatrixXd solve_projection(const ShFitOptions& options, const Eigen::MatrixXd& b) {
  const Eigen::VectorXd penalty = options.smoothing * laplacian_penalty(options.bands);
  if (options.method == ShFitMethod::kZeroHemisphere) {
    return (Eigen::VectorXd::Ones(penalty.size()) + penalty).cwiseInverse().asDiagonal() * b;
  }
  const GramEntry& entry = gram_entry(options.bands);
  if (options.smoothing == 0.0) return entry.llt.solve(b);
  Eigen::MatrixXd a = entry.gram;
  a.diagonal() += penalty;
  return a.llt().solve(b);
}

}  // namespace

Eigen::VectorXd sh_basis(int bands, const Vec3d& dir) {
  Eigen::VectorXd out(sh_coeff_count(bands));
  sh_basis(bands, dir, out.data());
  return out;
}

Eigen::MatrixXd sh_basis_matrix(int bands, const std::vector<Vec3d>& directions) {
  const int k = sh_coeff_count(bands);
  // Row-major scratch so each direction writes a contiguous row.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> m(directions.size(), k);
  for (std::size_t j = 0; j < directions.size(); ++j) sh_basis(bands, directions[j].normalized(), m.row(j).data());
  return m;
}

void gauss_legendre(int count, std::vector<double>& nodes, std::vector<double>& weights) {
  VDRIG_CHECK(count >= 1, "gauss_legendre: count must be positive");
  nodes.assign(count, 0.0);
  weights.assign(count, 0.0);
  for (int i = 0; i < (count + 1) / 2; ++i) {
    double x = std::cos(kPi * (i + 0.75) / (count + 0.5));  // Tricomi's initial guess
    double dp = 0.0;
    for (int iter = 0; iter < 100; ++iter) {
      double p0 = 1.0, p1 = x;
      for (int k = 2; k <= count; ++k) {
        const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = count * (x * p1 - p0) / (x * x - 1.0);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    // Recompute the derivative at the converged node for the weight.
    double p0 = 1.0, p1 = x;
    for (int k = 2; k <= count; ++k) {
      const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    dp = count * (x * p1 - p0) / (x * x - 1.0);
    nodes[i] = -x;
    nodes[count - 1 - i] = x;
    weights[i] = weights[count - 1 - i] = 2.0 / ((1.0 - x * x) * dp * dp);
  }
  if (count % 2 == 1) nodes[count / 2] = 0.0;
}

HemisphereQuadrature hemisphere_quadrature(int zenith_nodes, int azimuth_nodes) {
  VDRIG_CHECK(zenith_nodes >= 1 && azimuth_nodes >= 1, "hemisphere_quadrature: node counts must be positive");
  std::vector<double> x, w;
  gauss_legendre(zenith_nodes, x, w);
  HemisphereQuadrature q;
  for (int i = 0; i < zenith_nodes; ++i) {
    const double cos_zenith = 0.5 * (x[i] + 1.0);  // [-1, 1] -> [0, 1]
    const double zenith = std::acos(cos_zenith);
    for (int k = 0; k < azimuth_nodes; ++k) {
      q.directions.push_back(direction_from_spherical(2.0 * kPi * (k + 0.5) / azimuth_nodes, zenith));
      q.weights.push_back(0.5 * w[i] * 2.0 * kPi / azimuth_nodes);
    }
  }
  return q;
}

const Eigen::MatrixXd& sh_hemisphere_gram(int bands) { return gram_entry(bands).gram; }
double sh_hemisphere_gram_condition(int bands) { return gram_entry(bands).condition; }

const char* to_string(ShFitMethod method) {
  switch (method) {
    case ShFitMethod::kZeroHemisphere:
      return "zh";
    case ShFitMethod::kLsop:
      return "lsop";
    case ShFitMethod::kLeastSquares:
      return "ls";
  }
  return "?";
}

const char* to_string(RingingWindow window) {
  switch (window) {
    case RingingWindow::kNone:
      return "none";
    case RingingWindow::kHanning:
      return "hanning";
    case RingingWindow::kLanczos:
      return "lanczos";
  }
  return "?";
}

double ringing_window_factor(RingingWindow window, int l, int bands) {
  const double t = kPi * l / bands;
  switch (window) {
    case RingingWindow::kNone:
      return 1.0;
    case RingingWindow::kHanning:
      return 0.5 * (1.0 + std::cos(t));
    case RingingWindow::kLanczos:
      return l == 0 ? 1.0 : std::sin(t) / t;
  }
  return 1.0;
}

std::string ShFitOptions::fingerprint() const {
  // {} formats doubles as the shortest text that reads back to the same value.
  return fmt::format("bands:{},method:{},window:{},smoothing:{}", bands, static_cast<int>(method),
                     static_cast<int>(window), smoothing);
}

bool ShFitOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (bands < 1 || bands > kMaxShBands)
    return fail("sh bands must be in [1, " + std::to_string(kMaxShBands) + "], got " + std::to_string(bands));
  if (!(smoothing >= 0.0) || !std::isfinite(smoothing)) return fail("sh smoothing must be finite and >= 0");
  if (window != RingingWindow::kNone && method != ShFitMethod::kZeroHemisphere)
    return fail(std::string("sh ringing window '") + to_string(window) + "' is only valid with the zh method (" +
                to_string(method) + " coefficients cancel each other on the hemisphere; use smoothing instead)");
  return true;
}

LinearFitOperator::LinearFitOperator(Eigen::MatrixXd matrix)
    : matrix_(std::move(matrix)), matrix_f_(matrix_.cast<float>()) {}

Eigen::MatrixXd LinearFitOperator::apply(const Eigen::Ref<const Eigen::MatrixXd>& values) const {
  VDRIG_CHECK(values.rows() == matrix_.cols(), "LinearFitOperator::apply: sample count mismatch");
  return matrix_ * values;
}

void LinearFitOperator::apply_batch(const Eigen::Ref<const Eigen::MatrixXf>& values, Eigen::Ref<Eigen::MatrixXf> coeffs,
                                    int threads) const {
  VDRIG_CHECK(values.rows() == matrix_f_.cols(), "LinearFitOperator::apply_batch: sample count mismatch");
  VDRIG_CHECK(coeffs.rows() == matrix_f_.rows() && coeffs.cols() == values.cols(),
              "LinearFitOperator::apply_batch: coefficient matrix has the wrong shape");
  const Eigen::Index cols = values.cols();
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // Below a few thousand columns a second thread costs more than it saves.
  threads = static_cast<int>(std::min<Eigen::Index>(threads, std::max<Eigen::Index>(1, cols / 2048)));
  auto run = [&](Eigen::Index begin, Eigen::Index end) {
    coeffs.middleCols(begin, end - begin).noalias() = matrix_f_ * values.middleCols(begin, end - begin);
  };
  if (threads == 1) {
    run(0, cols);
    return;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    const Eigen::Index begin = cols * t / threads, end = cols * (t + 1) / threads;
    pool.emplace_back(run, begin, end);
  }
  for (auto& th : pool) th.join();
}

Eigen::VectorXd ringing_window_vector(RingingWindow window, int bands) {
  Eigen::VectorXd w(sh_coeff_count(bands));
  for (int l = 0; l < bands; ++l) {
    for (int m = -l; m <= l; ++m) w(sh_index(l, m)) = ringing_window_factor(window, l, bands);
  }
  return w;
}

Eigen::VectorXd laplacian_penalty(int bands) {
  Eigen::VectorXd d(sh_coeff_count(bands));
  for (int l = 0; l < bands; ++l) {
    for (int m = -l; m <= l; ++m) d(sh_index(l, m)) = std::pow(double(l) * (l + 1), 2);
  }
  return d;
}

Eigen::MatrixXd least_squares_operator(const Eigen::MatrixXd& basis, const std::vector<double>& weights,
                                       const Eigen::VectorXd& penalty) {
  const Eigen::Index n = basis.rows(), k = basis.cols();
  VDRIG_CHECK(weights.empty() || static_cast<Eigen::Index>(weights.size()) == n,
              "least_squares_operator: weights size mismatch");
  VDRIG_CHECK(penalty.size() == 0 || penalty.size() == k, "least_squares_operator: penalty size mismatch");
  Eigen::VectorXd sqrt_w = Eigen::VectorXd::Ones(n);
  for (Eigen::Index j = 0; j < static_cast<Eigen::Index>(weights.size()); ++j)
    sqrt_w(j) = weights[j] > 0.0 ? std::sqrt(weights[j]) : 0.0;
  const Eigen::MatrixXd weighted = sqrt_w.asDiagonal() * basis;
  Eigen::MatrixXd op;
  if (penalty.size() > 0 && penalty.maxCoeff() > 0.0) {
    // (Y^T W Y / s + diag(penalty)) c = Y^T W f / s; SPD as soon as one sample is present (penalty_0 = 0 but
    // y_0 is a non-zero constant).
    const double s = std::max(sqrt_w.squaredNorm(), 1e-300) / (2.0 * kPi);
    Eigen::MatrixXd normal = weighted.transpose() * weighted / s;
    normal.diagonal() += penalty;
    op = normal.ldlt().solve(weighted.transpose() / s);
  } else {
    // Full column rank (the usual case): pinv = P R^-1 Q_thin^T from a column-pivoting QR, O(N K^2). Otherwise
    // (fewer samples than coefficients, coincident samples) the complete orthogonal decomposition's
    // minimum-norm pseudo-inverse, which costs O(N^2 K) but only arises for small or degenerate sets.
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(weighted);
    if (n >= k && qr.rank() == k) {
      const Eigen::MatrixXd q_thin = qr.householderQ() * Eigen::MatrixXd::Identity(n, k);
      const Eigen::MatrixXd r_inv_qt =
          qr.matrixR().topLeftCorner(k, k).triangularView<Eigen::Upper>().solve(q_thin.transpose());
      op = qr.colsPermutation() * r_inv_qt;
    } else {
      op = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(weighted).pseudoInverse();
    }
  }
  return op * sqrt_w.asDiagonal();
}

std::vector<double> masked_voronoi_areas(const std::vector<Vec3d>& directions, const std::vector<double>& weights) {
  VDRIG_CHECK(weights.empty() || weights.size() == directions.size(), "masked_voronoi_areas: weights size mismatch");
  if (weights.empty()) return hemisphere_voronoi_areas(directions);
  std::vector<Vec3d> present;
  std::vector<std::size_t> index;
  for (std::size_t j = 0; j < directions.size(); ++j) {
    if (weights[j] > 0.0) {
      present.push_back(directions[j]);
      index.push_back(j);
    }
  }
  const std::vector<double> sub = hemisphere_voronoi_areas(present);
  std::vector<double> areas(directions.size(), 0.0);
  for (std::size_t i = 0; i < index.size(); ++i) areas[index[i]] = sub[i];
  return areas;
}

LinearFitOperator make_sh_fit_operator(const ShFitOptions& options, const std::vector<Vec3d>& directions,
                                       const std::vector<double>& weights) {
  std::string why;
  VDRIG_CHECK(options.is_valid(&why), why);
  VDRIG_CHECK(weights.empty() || weights.size() == directions.size(), "make_sh_fit_operator: weights size mismatch");
  const Eigen::MatrixXd basis = sh_basis_matrix(options.bands, directions);
  Eigen::MatrixXd op;
  if (options.method == ShFitMethod::kLeastSquares) {
    op = least_squares_operator(basis, weights, options.smoothing * laplacian_penalty(options.bands));
  } else {
    const std::vector<double> areas = masked_voronoi_areas(directions, weights);
    const Eigen::Map<const Eigen::VectorXd> da(areas.data(), static_cast<Eigen::Index>(areas.size()));
    op = basis.transpose() * da.asDiagonal();  // ZH: c = Y^T diag(dA) f
    op = solve_projection(options, op);
  }
  if (options.window != RingingWindow::kNone)
    op = ringing_window_vector(options.window, options.bands).asDiagonal() * op;
  return LinearFitOperator(std::move(op));
}

Eigen::MatrixXd fit_sh(const ShFitOptions& options, const std::vector<Vec3d>& directions,
                       const Eigen::Ref<const Eigen::MatrixXd>& values, const std::vector<double>& weights) {
  ShTexelFitter fitter(options);
  return fitter.fit(directions, values, weights);
}

ShTexelFitter::ShTexelFitter(const ShFitOptions& options) : options_(options) {
  std::string why;
  VDRIG_CHECK(options_.is_valid(&why), why);
  window_ = ringing_window_vector(options_.window, options_.bands);
  if (options_.method == ShFitMethod::kLsop) (void)gram_entry(options_.bands);  // build the cache up front
}

Eigen::MatrixXd ShTexelFitter::fit(const std::vector<Vec3d>& directions,
                                   const Eigen::Ref<const Eigen::MatrixXd>& values,
                                   const std::vector<double>& weights) {
  VDRIG_CHECK(values.rows() == static_cast<Eigen::Index>(directions.size()), "ShTexelFitter::fit: size mismatch");
  VDRIG_CHECK(weights.empty() || weights.size() == directions.size(), "ShTexelFitter::fit: weights size mismatch");
  basis_ = sh_basis_matrix(options_.bands, directions);
  Eigen::MatrixXd coeffs;
  if (options_.method == ShFitMethod::kLeastSquares) {
    coeffs = least_squares_operator(basis_, weights, options_.smoothing * laplacian_penalty(options_.bands)) * values;
  } else {
    const std::vector<double> areas = masked_voronoi_areas(directions, weights);
    const Eigen::Map<const Eigen::VectorXd> da(areas.data(), static_cast<Eigen::Index>(areas.size()));
    coeffs = solve_projection(options_, basis_.transpose() * (da.asDiagonal() * values));
  }
  return window_.asDiagonal() * coeffs;
}

Eigen::VectorXd eval_sh(const Eigen::Ref<const Eigen::MatrixXd>& coeffs, const Vec3d& dir) {
  const int bands = static_cast<int>(std::lround(std::sqrt(static_cast<double>(coeffs.rows()))));
  VDRIG_CHECK(sh_coeff_count(bands) == coeffs.rows(), "eval_sh: coefficient count is not a square");
  const Eigen::VectorXd y = sh_basis(bands, dir.normalized());
  return coeffs.transpose() * y;
}

}  // namespace vdrig::fitting
