// A bounded Levenberg-Marquardt minimiser for small dense least-squares problems (one texel's model fit), private
// to fitting/. The cost accumulates the normal equations itself, so the Jacobian (residuals x parameters) is never
// stored.
//
// Contract of `Cost` (PhongTexelCost in phong.cpp is the user):
//   static constexpr int kParams;                         // P, the number of parameters (fixed at compile time)
//   using Vec = Eigen::Matrix<double, kParams, 1>;
//   using Mat = Eigen::Matrix<double, kParams, kParams>;
//   double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const;
//     returns 0.5 sum_i r_i(p)^2; when jtj and jtr are non-null it also overwrites them with J^T J and J^T r at p
//     (J = dr/dp). It may return a non-finite cost: such a trial step is rejected.
//
// minimise_bounded(cost, p, lo, hi, fixed, max_iterations, &final_cost):
//  - p is the start on entry (first projected onto [lo, hi]) and the minimiser on return; lo/hi may hold -inf/+inf;
//  - coordinates flagged in `fixed` are constants: their rows and columns are dropped from the normal equations;
//  - each step solves (J^T J + lambda diag(J^T J)) dx = -J^T r and projects p + dx onto the box; coordinates at a
//    bound whose gradient points out of the box are frozen for that step; lambda adapts to the ratio of actual to
//    predicted decrease (Nielsen's rule);
//  - stops when the relative cost decrease is below 1e-10, the step is below 1e-10 (|p| + 1e-10), the projected
//    gradient's max norm is below 1e-14, no step length decreases the cost (lambda > 1e16), or after
//    max_iterations iterations;
//  - returns true when one of the convergence tests (not the iteration limit) ended it; false as well when a step
//    was not finite (p then holds the last accepted point and final_cost is left unchanged);
//  - final_cost gets the cost at the returned p.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace vdrig::fitting {

template <class Cost>
bool minimise_bounded(const Cost& cost_fn, typename Cost::Vec& p, const typename Cost::Vec& lo,
                      const typename Cost::Vec& hi, const Eigen::Matrix<bool, Cost::kParams, 1>& fixed,
                      int max_iterations, double* final_cost) {
  using Vec = typename Cost::Vec;
  using Mat = typename Cost::Mat;
  constexpr double kFunctionTolerance = 1e-10, kParameterTolerance = 1e-10, kGradientTolerance = 1e-14;
  p = p.cwiseMax(lo).cwiseMin(hi);
  Mat jtj;
  Vec g;
  double cost = cost_fn.evaluate(p, &jtj, &g);
  double lambda = 1e-4, nu = 2.0;
  bool converged = false;
  for (int it = 0; it < max_iterations && !converged; ++it) {
    // Coordinates at a bound whose descent direction points out of the box stay where they are.
    Eigen::Matrix<bool, Cost::kParams, 1> frozen;
    double proj_grad = 0.0;
    for (int j = 0; j < Cost::kParams; ++j) {
      frozen[j] = fixed[j] || (p[j] <= lo[j] && g[j] > 0.0) || (p[j] >= hi[j] && g[j] < 0.0);
      if (!frozen[j]) proj_grad = std::max(proj_grad, std::abs(g[j]));
    }
    if (proj_grad < kGradientTolerance) {
      converged = true;
      break;
    }
    bool stepped = false;
    while (!stepped) {
      Mat a = jtj;
      Vec rhs = -g;
      const double diag_floor = 1e-12 * std::max(1.0, jtj.diagonal().maxCoeff());
      for (int j = 0; j < Cost::kParams; ++j) {
        a(j, j) += lambda * std::max(jtj(j, j), diag_floor);
        if (frozen[j]) {
          a.row(j).setZero();
          a.col(j).setZero();
          a(j, j) = 1.0;
          rhs[j] = 0.0;
        }
      }
      const Vec p_new = (p + a.ldlt().solve(rhs)).cwiseMax(lo).cwiseMin(hi);
      const Vec step = p_new - p;
      if (!step.allFinite()) return false;
      if (step.norm() <= kParameterTolerance * (p.norm() + kParameterTolerance)) {
        converged = true;
        break;
      }
      const double predicted = -(g.dot(step) + 0.5 * step.dot(jtj * step));
      const double new_cost = cost_fn.evaluate(p_new, nullptr, nullptr);
      if (std::isfinite(new_cost) && new_cost < cost) {
        const double rho = predicted > 0 ? (cost - new_cost) / predicted : 0.5;
        converged = (cost - new_cost) <= kFunctionTolerance * cost;
        p = p_new;
        cost = cost_fn.evaluate(p, &jtj, &g);
        lambda *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
        nu = 2.0;
        stepped = true;
      } else {
        lambda *= nu;
        nu *= 2.0;
        if (lambda > 1e16) {  // no descent left at any step length: a minimum to working precision
          converged = true;
          break;
        }
      }
    }
  }
  *final_cost = cost;
  return converged;
}

}  // namespace vdrig::fitting
