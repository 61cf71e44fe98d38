#include "vdrig/fitting/hsh.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

void hsh_basis(int bands, const Vec3d& dir, double* out) {
  VDRIG_CHECK(bands >= 1 && bands <= kMaxHshBands, "hsh_basis: bands out of range");
  const double z = std::clamp(dir.z(), 0.0, 1.0);
  // Same azimuth, cos(zenith') = 2 z - 1; sin(zenith') / sin(zenith) = 2 sqrt(z / (1 + z)).
  const double k = 2.0 * std::sqrt(z / (1.0 + z));
  sh_basis(bands, Vec3d(k * dir.x(), k * dir.y(), 2.0 * z - 1.0), out);
  constexpr double kSqrt2 = 1.41421356237309504880;
  for (int i = 0; i < sh_coeff_count(bands); ++i) out[i] *= kSqrt2;
}

Eigen::VectorXd hsh_basis(int bands, const Vec3d& dir) {
  Eigen::VectorXd out(sh_coeff_count(bands));
  hsh_basis(bands, dir, out.data());
  return out;
}

Eigen::MatrixXd hsh_basis_matrix(int bands, const std::vector<Vec3d>& directions) {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> m(directions.size(), sh_coeff_count(bands));
  for (std::size_t j = 0; j < directions.size(); ++j) hsh_basis(bands, directions[j].normalized(), m.row(j).data());
  return m;
}

const char* to_string(HshFitMethod method) {
  switch (method) {
    case HshFitMethod::kLeastSquares:
      return "ls";
    case HshFitMethod::kProjection:
      return "projection";
  }
  return "?";
}

std::string HshFitOptions::fingerprint() const {
  return fmt::format("bands:{},method:{},window:{},smoothing:{}", bands, static_cast<int>(method),
                     static_cast<int>(window), smoothing);
}

bool HshFitOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (bands < 1 || bands > kMaxHshBands)
    return fail("hsh bands must be in [1, " + std::to_string(kMaxHshBands) + "], got " + std::to_string(bands));
  if (!(smoothing >= 0.0) || !std::isfinite(smoothing)) return fail("hsh smoothing must be finite and >= 0");
  return true;
}

LinearFitOperator make_hsh_fit_operator(const HshFitOptions& options, const std::vector<Vec3d>& directions,
                                        const std::vector<double>& weights) {
  std::string why;
  VDRIG_CHECK(options.is_valid(&why), why);
  VDRIG_CHECK(weights.empty() || weights.size() == directions.size(), "make_hsh_fit_operator: weights size mismatch");
  const Eigen::MatrixXd basis = hsh_basis_matrix(options.bands, directions);
  const Eigen::VectorXd penalty = options.smoothing * laplacian_penalty(options.bands);
  Eigen::MatrixXd op;
  if (options.method == HshFitMethod::kLeastSquares) {
    op = least_squares_operator(basis, weights, penalty);
  } else {
    const std::vector<double> areas = masked_voronoi_areas(directions, weights);
    const Eigen::Map<const Eigen::VectorXd> da(areas.data(), static_cast<Eigen::Index>(areas.size()));
    op = (Eigen::VectorXd::Ones(penalty.size()) + penalty).cwiseInverse().asDiagonal() *
         (basis.transpose() * da.asDiagonal());
  }
  if (options.window != RingingWindow::kNone)
    op = ringing_window_vector(options.window, options.bands).asDiagonal() * op;
  return LinearFitOperator(std::move(op));
}

Eigen::MatrixXd fit_hsh(const HshFitOptions& options, const std::vector<Vec3d>& directions,
                        const Eigen::Ref<const Eigen::MatrixXd>& values, const std::vector<double>& weights) {
  VDRIG_CHECK(values.rows() == static_cast<Eigen::Index>(directions.size()), "fit_hsh: size mismatch");
  return make_hsh_fit_operator(options, directions, weights).apply(values);
}

Eigen::VectorXd eval_hsh(const Eigen::Ref<const Eigen::MatrixXd>& coeffs, const Vec3d& dir) {
  const int bands = static_cast<int>(std::lround(std::sqrt(static_cast<double>(coeffs.rows()))));
  VDRIG_CHECK(sh_coeff_count(bands) == coeffs.rows(), "eval_hsh: coefficient count is not a square");
  const Eigen::VectorXd h = hsh_basis(bands, dir.normalized());
  return coeffs.transpose() * h;
}

}  // namespace vdrig::fitting
