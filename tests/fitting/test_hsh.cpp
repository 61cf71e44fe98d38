// Hemispherical harmonics: definition against the C++17 special functions, orthonormality on the hemisphere,
// exact recovery of band-limited data, and HSH vs SH-LSOP on Phong-like lobes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "hemisphere_support.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/sh.hpp"

namespace vdrig::fitting {
namespace {

using test_support::fibonacci_hemisphere;
using test_support::hemisphere_rms;
using test_support::lobe;

double factorial(int n) { return std::tgamma(n + 1.0); }

TEST(HshBasis, MatchesShiftedLegendreDefinition) {
  // Gautron et al.: Kh = sqrt((2l+1)(l-|m|)! / (2 pi (l+|m|)!)), Ph_l^m(x) = P_l^m(2x - 1); std::assoc_legendre
  // omits the Condon-Shortley phase, which this library includes.
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  for (int trial = 0; trial < 200; ++trial) {
    const double azimuth = 2.0 * kPi * u(rng), cos_zenith = u(rng);
    const Eigen::VectorXd h = hsh_basis(kMaxHshBands, direction_from_spherical(azimuth, std::acos(cos_zenith)));
    for (int l = 0; l < kMaxHshBands; ++l) {
      for (int m = -l; m <= l; ++m) {
        const int am = std::abs(m);
        const double kh = std::sqrt((2 * l + 1) * factorial(l - am) / (2.0 * kPi * factorial(l + am)));
        const double p = (am % 2 ? -1.0 : 1.0) * std::assoc_legendre(l, am, 2.0 * cos_zenith - 1.0);
        const double ref = m == 0  ? kh * p
                           : m > 0 ? std::sqrt(2.0) * kh * std::cos(m * azimuth) * p
                                   : std::sqrt(2.0) * kh * std::sin(-m * azimuth) * p;
        worst = std::max(worst, std::abs(h(sh_index(l, m)) - ref) / std::max(1.0, std::abs(ref)));
      }
    }
  }
  EXPECT_LT(worst, 1e-11);
  // At the zenith only the m = 0 functions survive, with value Kh_l^0 (P_l(1) = 1).
  const Eigen::VectorXd top = hsh_basis(4, Vec3d(0, 0, 1));
  for (int l = 0; l < 4; ++l) {
    for (int m = -l; m <= l; ++m) {
      EXPECT_NEAR(top(sh_index(l, m)), m == 0 ? std::sqrt((2 * l + 1) / (2.0 * kPi)) : 0.0, 1e-14);
    }
  }
}

TEST(HshBasis, OrthonormalOnTheHemisphere) {
  const HemisphereQuadrature q = hemisphere_quadrature(20, 48);
  const int bands = kMaxHshBands;
  const Eigen::MatrixXd h = hsh_basis_matrix(bands, q.directions);
  const Eigen::Map<const Eigen::VectorXd> w(q.weights.data(), static_cast<Eigen::Index>(q.weights.size()));
  const Eigen::MatrixXd gram = h.transpose() * w.asDiagonal() * h;
  const double err = (gram - Eigen::MatrixXd::Identity(bands * bands, bands * bands)).cwiseAbs().maxCoeff();
  std::printf("HSH %d bands: max |G - I| on the hemisphere = %.2e\n", bands, err);
  EXPECT_LT(err, 1e-10);
}

TEST(HshFit, RecoversBandLimitedFunction) {
  std::mt19937 rng(4);
  std::normal_distribution<double> normal;
  const std::vector<Vec3d> dirs = fibonacci_hemisphere(300, 8);
  for (int bands : {3, 5, 7}) {
    Eigen::VectorXd truth_c(bands * bands);
    for (auto& c : truth_c) c = normal(rng);
    Eigen::MatrixXd values(dirs.size(), 2);
    for (std::size_t j = 0; j < dirs.size(); ++j) {
      values(j, 0) = hsh_basis(bands, dirs[j]).dot(truth_c);
      values(j, 1) = 2.0 * values(j, 0);
    }
    HshFitOptions options;
    options.bands = bands;
    const Eigen::MatrixXd c = fit_hsh(options, dirs, values);
    EXPECT_LT((c.col(0) - truth_c).norm(), 1e-9 * truth_c.norm()) << bands;
    EXPECT_LT((c.col(1) - 2.0 * truth_c).norm(), 2e-9 * truth_c.norm()) << bands;
    const Vec3d probe = Vec3d(0.2, -0.4, 0.6).normalized();
    EXPECT_NEAR(eval_hsh(c, probe)(0), hsh_basis(bands, probe).dot(truth_c), 1e-9);
    // The Voronoi projection (LSOP for an orthonormal basis) is close but not exact: quadrature error only.
    options.method = HshFitMethod::kProjection;
    const Eigen::MatrixXd cp = fit_hsh(options, dirs, values);
    const double rel = (cp.col(0) - truth_c).norm() / truth_c.norm();
    std::printf("HSH %d bands, 300 samples: projection coefficient error %.2e (LS exact)\n", bands, rel);
    EXPECT_LT(rel, 0.05);
  }
}

TEST(HshFit, BeatsShLsopOnPhongLobes) {
  // Measured: HSH is clearly better for lobes at intermediate zenith angles, ties at the zenith (only m = 0
  // matters and both spans fit it equally) and at grazing reflection (70 deg, the lobe is cut by the horizon:
  // within a few percent either way). Over the set of lobes it wins at both coefficient counts.
  const std::vector<Vec3d> dirs = fibonacci_hemisphere(300, 6);
  for (int bands : {5, 6}) {
    double total_hsh = 0.0, total_sh = 0.0;
    for (double zenith_deg : {0.0, 25.0, 50.0, 70.0}) {
      const Vec3d r = direction_from_spherical(2.0, deg_to_rad(zenith_deg));
      auto truth = [&](const Vec3d& v) { return lobe(v, r, 0.15, 1.0, 20.0); };
      Eigen::MatrixXd values(dirs.size(), 1);
      for (std::size_t j = 0; j < dirs.size(); ++j) values(j, 0) = truth(dirs[j]);
      HshFitOptions hsh;
      hsh.bands = bands;
      const Eigen::MatrixXd ch = fit_hsh(hsh, dirs, values);
      ShFitOptions sh;
      sh.bands = bands;
      sh.method = ShFitMethod::kLsop;
      const Eigen::MatrixXd cs = fit_sh(sh, dirs, values);
      const double rms_hsh = hemisphere_rms([&](const Vec3d& v) { return eval_hsh(ch, v)(0); }, truth);
      const double rms_sh = hemisphere_rms([&](const Vec3d& v) { return eval_sh(cs, v)(0); }, truth);
      std::printf("lobe m=20 at %2.0f deg, %d coeffs, 300 dirs: RMS HSH-LS %.4f  SH-LSOP %.4f\n", zenith_deg,
                  bands * bands, rms_hsh, rms_sh);
      total_hsh += rms_hsh;
      total_sh += rms_sh;
      if (zenith_deg > 10.0 && zenith_deg < 60.0) {
        EXPECT_LT(rms_hsh, 0.9 * rms_sh) << zenith_deg << " deg, " << bands * bands << " coeffs";
      } else {
        EXPECT_LT(rms_hsh, 1.05 * rms_sh) << zenith_deg << " deg, " << bands * bands << " coeffs";
      }
    }
    EXPECT_LT(total_hsh, 0.9 * total_sh) << bands * bands << " coeffs";
  }
}

TEST(HshFit, BatchOperatorAndWindow) {
  const std::vector<Vec3d> dirs = fibonacci_hemisphere(289, 2);
  HshFitOptions options;
  options.bands = 3;
  options.window = RingingWindow::kHanning;
  const LinearFitOperator op = make_hsh_fit_operator(options, dirs);
  Eigen::MatrixXf values = Eigen::MatrixXf::Random(289, 3 * 4000);
  Eigen::MatrixXf coeffs(9, 3 * 4000);
  op.apply_batch(values, coeffs);
  const Eigen::MatrixXd ref = fit_hsh(options, dirs, values.middleCols(3 * 17, 3).cast<double>());
  EXPECT_LT((coeffs.middleCols(3 * 17, 3).cast<double>() - ref).cwiseAbs().maxCoeff(), 1e-4);
  // The window leaves band 0 alone and halves band 1 of a 3-band fit ((1 + cos(pi / 3)) / 2 = 0.75).
  HshFitOptions plain = options;
  plain.window = RingingWindow::kNone;
  const Eigen::MatrixXd raw = fit_hsh(plain, dirs, values.middleCols(0, 1).cast<double>());
  const Eigen::MatrixXd win = fit_hsh(options, dirs, values.middleCols(0, 1).cast<double>());
  EXPECT_NEAR(win(0, 0), raw(0, 0), 1e-12);
  EXPECT_NEAR(win(2, 0), 0.75 * raw(2, 0), 1e-12);
  std::string why;
  options.bands = 0;
  EXPECT_FALSE(options.is_valid(&why));
  EXPECT_NE(why.find("bands"), std::string::npos);
}

}  // namespace
}  // namespace vdrig::fitting
