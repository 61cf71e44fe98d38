// Soft lights (soft_lights.hpp): powers sum to the map's, the SH-9 band limit of the clamped cosine, accuracy on a
// real probe, and no flicker on a sliding source where median cut flickers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "probe_support.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/soft_lights.hpp"

namespace vdrig::probe {
namespace {

using testing::load_real_probe;
using testing::synthetic_probe;

TEST(SoftLights, ClampedCosineBandLimitIsItsSh9Projection) {
  // One light of power 1 at d: its SH-9 irradiance (project a delta) must be sh9_clamped_cosine(n . d).
  const Vec3d d = Vec3d(0.2, -0.4, 0.7).normalized();
  Sh9 delta;
  const auto y = sh9_basis(d);
  for (int k = 0; k < kSh9Count; ++k) delta.coeffs[k] = Rgb::Constant(y[k]);
  for (const Vec3d& n : fibonacci_directions(50))
    EXPECT_NEAR(sh9_irradiance(delta, n).x(), sh9_clamped_cosine(n.dot(d)), 1e-12);
}

TEST(SoftLights, PowersSumToTheMapsAndTheInteriorIsLitAccurately) {
  Probe p;
  ASSERT_TRUE(load_real_probe("interior", &p, 256));
  const SoftLights soft = soft_lights(p, {64, 40.0});
  ASSERT_EQ(soft.lights.size(), 64u);
  Rgb sum = Rgb::Zero();
  double sr = 0;
  for (const DirectionalLight& l : soft.lights) sum += l.power, sr += l.solid_angle_sr;
  EXPECT_LT((sum - total_power(p)).norm(), 1e-6 * total_power(p).norm());
  EXPECT_NEAR(sr, 4 * kPi, 1e-6);
  const auto normals = fibonacci_directions(256);
  const IrradianceErrorStats s = irradiance_error(
      normals, [&](const Vec3d& n) { return soft.irradiance(n); }, reference_irradiance(p, normals));
  std::printf("interior 256 x 128, SH-9 + 64 soft lights: mean %.2f %%, max %.2f %%\n", 100 * s.mean, 100 * s.max);
  EXPECT_LT(s.mean, 0.03);
}

TEST(SoftLights, ASlidingSourceDoesNotFlickerAsMedianCutDoes) {
  // A smooth bright patch slides by a tenth of a pixel per frame over 20 frames. Excess flicker: mean over normals
  // of |dE - dE_exact| / mean E_exact per frame, averaged; soft lights must stay 5x below median cut (64 lights).
  auto map = [](int frame) {
    const Vec3d sun = direction_from_spherical(1.0 + frame * 0.1 * 2 * kPi / 128, 0.8);
    return synthetic_probe(64,
                           [&](const Vec3d& d) { return Rgb::Constant(0.2 + 50 * std::exp(-300 * (1 - d.dot(sun)))); });
  };
  const auto normals = fibonacci_directions(128);
  std::vector<std::vector<double>> exact, soft, cut;
  for (int f = 0; f < 20; ++f) {
    const Probe p = map(f);
    const IrradianceIntegrator brute(p);
    const SoftLights s = soft_lights(p);
    const auto lights = median_cut(p, 64);
    exact.emplace_back(), soft.emplace_back(), cut.emplace_back();
    for (const Vec3d& n : normals) {
      exact.back().push_back(luminance(brute.irradiance(n)));
      soft.back().push_back(luminance(s.irradiance(n)));
      cut.back().push_back(luminance(irradiance_from_lights(lights, n)));
    }
  }
  auto excess = [&](const std::vector<std::vector<double>>& e) {
    double sum = 0;
    for (size_t f = 1; f < e.size(); ++f) {
      double d = 0, mean = 0;
      for (size_t n = 0; n < normals.size(); ++n) {
        d += std::abs((e[f][n] - e[f - 1][n]) - (exact[f][n] - exact[f - 1][n]));
        mean += exact[f][n];
      }
      sum += d / mean / (e.size() - 1);
    }
    return sum;
  };
  const double fs = excess(soft), fc = excess(cut);
  std::printf("sliding source, excess flicker: soft lights %.4f %%, median cut %.4f %%\n", 100 * fs, 100 * fc);
  EXPECT_LT(fs, fc / 5);
}

// On a cube map: shrinking keeps the power exactly, and soft lights of the cube (texels with their exact solid angles)
// light the interior nearly as accurately as those of the lat-long map it came from. Its lamp is a point source of
// 3.2e4: on 16^2 faces (5.6 deg texels) SH-9 sees it at a texel centre, up to 2.8 deg off, which costs accuracy that
// 32^2 faces recover (measured 1.25 % and 0.585 %, lat-long 0.581 %).
TEST(SoftLights, OnACubeMapTheyMatchTheExactIrradianceAsOnTheLatLongMap) {
  Probe p;
  ASSERT_TRUE(load_real_probe("interior", &p, 256));
  const CubeMap cube = latlong_to_cube(p, 64);
  std::vector<Vec3d> dirs;
  std::vector<Rgb> weighted;
  cube_quadrature(cube, &dirs, &weighted);
  const IrradianceIntegrator exact(dirs, weighted);
  auto error_of = [&](const SoftLights& s) {
    double err = 0, mean = 0;
    for (const Vec3d& n : fibonacci_directions(256)) {
      const double e = luminance(exact.irradiance(n));
      err += std::abs(luminance(s.irradiance(n)) - e);
      mean += e;
    }
    return err / mean;
  };
  const double err_latlong = error_of(soft_lights(p));
  for (const auto& [factor, bound] : {std::pair{4, 0.02}, {2, 0.01}}) {
    const CubeMap small = downsample_cube(cube, factor);
    EXPECT_EQ(small.size, 64 / factor);
    EXPECT_NEAR(luminance(total_power(small)) / luminance(total_power(cube)), 1.0, 1e-7);  // float texels
    const SoftLights from_cube = soft_lights(small);
    Rgb power = Rgb::Zero();
    for (const DirectionalLight& l : from_cube.lights) power += l.power;
    EXPECT_NEAR(luminance(power) / luminance(total_power(small)), 1.0, 1e-9);
    const double err = error_of(from_cube);
    std::printf(
        "interior, soft:64 vs exact over the 64^2 cube: from the %d^2 cube %.3f %% (from the lat-long %.3f %%)\n",
        small.size, 100 * err, 100 * err_latlong);
    EXPECT_LT(err, bound) << small.size;
  }
}

}  // namespace
}  // namespace vdrig::probe
