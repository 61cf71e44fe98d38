// SH-9 irradiance (Ramamoorthi & Hanrahan 2001): the local basis against fitting's, exactness on band-limited
// radiance, and the error on the three real probes against brute-force integration.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "probe_support.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/probe/sh_irradiance.hpp"

namespace vdrig::probe {
namespace {

using testing::load_real_probe;
using testing::synthetic_probe;

TEST(Sh9, BasisIsFittingsRealSh) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  for (int k = 0; k < 200; ++k) {
    const Vec3d d = Vec3d(g(rng), g(rng), g(rng)).normalized();
    const auto ours = sh9_basis(d);
    const Eigen::VectorXd ref = fitting::sh_basis(3, d);
    for (int i = 0; i < kSh9Count; ++i) EXPECT_NEAR(ours[i], ref[i], 1e-12) << "y_" << i;
  }
}

TEST(Sh9, BasisIsOrthonormalUnderTheMapQuadrature) {
  // Projecting the map of y_k must give the unit vector e_k: checks the solid-angle weighting of project_sh9.
  double worst = 0;
  for (int k = 0; k < kSh9Count; ++k) {
    const Probe p = synthetic_probe(256, [k](const Vec3d& d) { return Rgb::Constant(sh9_basis(d)[k]); });
    const Sh9 c = project_sh9(p);
    for (int i = 0; i < kSh9Count; ++i) worst = std::max(worst, std::abs(c.coeffs[i].x() - (i == k ? 1.0 : 0.0)));
  }
  std::printf("SH-9 Gram matrix on a 512 x 256 map: max deviation from identity %.2e\n", worst);
  EXPECT_LT(worst, 5e-5);
}

TEST(Sh9, ExactOnBandLimitedRadiance) {
  // Radiance that is itself a band <= 2 polynomial: E(n) = sum A_l c_i y_i(n) exactly (Funk-Hecke); the projection
  // recovers c up to the map's quadrature error and brute-force integration agrees to its own quadrature error.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  Sh9 truth;
  for (int i = 0; i < kSh9Count; ++i) truth.coeffs[i] = Rgb(u(rng), u(rng), u(rng));
  truth.coeffs[0] = Rgb(3.0, 2.5, 2.0);  // keeps the radiance positive
  const Probe p = synthetic_probe(512, [&](const Vec3d& d) { return sh9_radiance(truth, d); });
  const Sh9 got = project_sh9(p);
  double coeff_err = 0;
  for (int i = 0; i < kSh9Count; ++i) coeff_err = std::max(coeff_err, (got.coeffs[i] - truth.coeffs[i]).norm());
  const auto normals = fibonacci_directions(100);
  const auto brute = reference_irradiance(p, normals);
  double vs_analytic = 0, brute_vs_analytic = 0;
  for (size_t k = 0; k < normals.size(); ++k) {
    const Rgb exact = sh9_irradiance(truth, normals[k]);
    vs_analytic = std::max(vs_analytic, (sh9_irradiance(got, normals[k]) - exact).norm() / exact.norm());
    brute_vs_analytic = std::max(brute_vs_analytic, (brute[k] - exact).norm() / exact.norm());
  }
  std::printf(
      "band-2 radiance, 1024 x 512: coefficients within %.2e; SH E vs analytic max %.2e, brute force vs "
      "analytic max %.2e\n",
      coeff_err, vs_analytic, brute_vs_analytic);
  // Measured 1.6e-5 and 2.2e-6: pixel-centre sampling within each row (the row solid angle itself is exact).
  EXPECT_LT(coeff_err, 3e-5);
  EXPECT_LT(vs_analytic, 5e-6);
  EXPECT_LT(brute_vs_analytic, 2e-4);  // checks A_l against an independent integral
}

TEST(Sh9, RealProbesAgainstBruteForce) {
  // Measured (128 normals, relative to brute force on the full 1024 x 512 map): per-normal mean 4.6 / 5.0 / 8.8 %,
  // max 28 / 36 / 56 %, mean |dE| / mean E 3.5 / 3.0 / 6.8 % (courtyard / interior / studio). RH's "~1-3 %" holds
  // for the broad courtyard and interior maps by the last measure; studio's small softboxes leave more energy in
  // bands >= 3, and the worst normals are the dim ones facing away from every light.
  struct Bound {
    double mean, max, of_mean;
  };
  const Bound bounds[] = {{0.06, 0.36, 0.045}, {0.06, 0.50, 0.04}, {0.105, 0.65, 0.08}};
  const auto normals = fibonacci_directions(128);
  for (int probe_index = 0; probe_index < 3; ++probe_index) {
    const char* name = testing::kRealProbes[probe_index];
    const Bound& bound = bounds[probe_index];
    Probe p;
    ASSERT_TRUE(load_real_probe(name, &p));
    const auto reference = reference_irradiance(p, normals);
    const Sh9 sh = project_sh9(p);
    const auto err = irradiance_error(
        normals, [&](const Vec3d& n) { return sh9_irradiance(sh, n); }, reference);
    const Sh9 wrong_sh = project_sh9(testing::without_solid_angle_weighting(p));
    const auto wrong = irradiance_error(
        normals, [&](const Vec3d& n) { return sh9_irradiance(wrong_sh, n); }, reference);
    std::printf(
        "%-9s SH-9 E error mean %.2f %%, max %.2f %%, mean |dE| / mean E %.2f %%  (without solid angle: mean "
        "%.1f %%, max %.1f %%)\n",
        name, 100 * err.mean, 100 * err.max, 100 * err.of_mean, 100 * wrong.mean, 100 * wrong.max);
    EXPECT_LT(err.mean, bound.mean) << name;
    EXPECT_LT(err.max, bound.max) << name;
    EXPECT_LT(err.of_mean, bound.of_mean) << name;
    EXPECT_GT(wrong.mean, 2 * bound.mean) << name << ": the error bound must catch a missing solid angle";
  }
}

}  // namespace
}  // namespace vdrig::probe
