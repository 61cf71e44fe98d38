// Phong-K fitting against the simulator's ground truth (noise-free radiance straight from the scene).
#include <gtest/gtest.h>

#include <random>

#include "rig_observations.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::fitting {
namespace {

/// Observations of surface point p from a latitude-longitude set of nominal directions (zenith 0..80 deg in
/// `zenith_step_deg` steps, about as many azimuths per ring as its circumference allows), as a rig at `distance_mm`
/// sees it (test_support::observe_texel).
TexelObservations observe(const sim::Scene& scene, const Vec3d& p, double distance_mm, double zenith_step_deg) {
  std::vector<Vec3d> nominal;
  for (double zen = 0; zen <= 80.0 + 1e-9; zen += zenith_step_deg) {
    const int count =
        zen == 0 ? 1 : std::max(1, static_cast<int>(std::round(360.0 / zenith_step_deg * std::sin(deg_to_rad(zen)))));
    for (int a = 0; a < count; ++a) nominal.push_back(direction_from_spherical(2 * kPi * a / count, deg_to_rad(zen)));
  }
  return test_support::observe_texel(scene, p, nominal, distance_mm);
}

using test_support::rel;

class PhongSolvers : public ::testing::TestWithParam<PhongSolver> {};

TEST_P(PhongSolvers, RecoverGlossyTexelOfTheSimulator) {
  auto scene = sim::make_scene("patchwork");
  ASSERT_TRUE(scene) << scene.error().describe();
  const Vec3d p(225, -225, 0);  // inside the glossy patch
  ASSERT_EQ(scene->materials[scene->material_at(p.x(), p.y())].name, "glossy plastic");
  const auto truth = scene->phong_truth(p);
  ASSERT_TRUE(truth.has_value());

  const TexelObservations obs = observe(*scene, p, 2500.0, 5.0);
  ASSERT_GT(obs.size(), 200u);
  PhongFitOptions options;
  options.solver = GetParam();
  const PhongFit fit = fit_phong(obs, options);
  ASSERT_EQ(fit.params.lobes.size(), 1u);
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(rel(fit.params.kd[c], truth->kd[c]), 0.02) << "Kd channel " << c;
    EXPECT_LT(rel(fit.params.lobes[0].ks[c], truth->ks[c]), 0.02) << "Ks channel " << c;
  }
  EXPECT_LT(rad_to_deg(angle_between(fit.params.lobes[0].direction, truth->mirror_dir)), 1.0);
  EXPECT_LT(rel(fit.params.lobes[0].shininess, truth->shininess), 0.05);
  for (int c = 0; c < 3; ++c) EXPECT_LT(fit.quality.mean_percent[c], 0.5);
}

INSTANTIATE_TEST_SUITE_P(DirectAndCeres, PhongSolvers, ::testing::Values(PhongSolver::kDirect, PhongSolver::kCeres));

TEST(PhongFit, DiffuseTexelHasNoSpecularEnergy) {
  auto scene = sim::make_scene("patchwork");
  ASSERT_TRUE(scene);
  const Vec3d p(-225, -225, 0);  // red cloth, Lambertian
  const auto truth = scene->phong_truth(p);
  const PhongFit fit = fit_phong(observe(*scene, p, 2500.0, 10.0), {});
  EXPECT_TRUE(fit.params.lobes.empty());  // no lobe lowers the BIC of an exactly constant texel
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit.params.kd[c], truth->kd[c], 1e-3 * truth->kd.maxCoeff() + 1e-6);
    EXPECT_LT(fit.quality.rms[c], 1e-3 * truth->kd.maxCoeff());
  }
}

TEST(PhongFit, TwoLobesFindBothHighlights) {
  sim::Scene scene = sim::make_scene("patchwork").value();
  scene.lights.push_back({Vec3d(-1500, 1000, 2000), scene.lights[0].intensity * 0.4});
  const Vec3d p(225, -225, 0);
  const TexelObservations obs = observe(scene, p, 2500.0, 4.0);
  PhongFitOptions opt;
  opt.lobes = 2;
  const PhongFit fit = fit_phong(obs, opt);
  ASSERT_EQ(fit.params.lobes.size(), 2u);
  std::vector<Vec3d> mirrors;
  for (const auto& light : scene.lights)
    mirrors.push_back(mirror_direction((light.position_mm - p).normalized(), Vec3d::UnitZ()));
  for (const Vec3d& m : mirrors) {
    double best = 1e9;
    for (const auto& lobe : fit.params.lobes) best = std::min(best, rad_to_deg(angle_between(lobe.direction, m)));
    EXPECT_LT(best, 1.0);
  }
  const PhongFit one = fit_phong(obs, {});
  EXPECT_LT(fit.quality.rms.sum(), 0.2 * one.quality.rms.sum());
}

// Relative residuals weigh every sample alike; on noise-free data they must reach the same parameters.
TEST(PhongFit, RelativeResidualsRecoverTheGlossyTexel) {
  auto scene = sim::make_scene("patchwork");
  ASSERT_TRUE(scene);
  const Vec3d p(225, -225, 0);
  const auto truth = scene->phong_truth(p);
  PhongFitOptions opt;
  opt.residual = ResidualMode::kRelative;
  const PhongFit fit = fit_phong(observe(*scene, p, 2500.0, 5.0), opt);
  ASSERT_EQ(fit.params.lobes.size(), 1u);
  EXPECT_TRUE(fit.converged);
  EXPECT_LT(rad_to_deg(angle_between(fit.params.lobes[0].direction, truth->mirror_dir)), 1.0);
  EXPECT_LT(rel(fit.params.lobes[0].shininess, truth->shininess), 0.05);
  for (int c = 0; c < 3; ++c) EXPECT_LT(rel(fit.params.kd[c], truth->kd[c]), 0.02);
}

// phong:auto on the simulator's two-light scene: the BIC keeps two lobes, and they sit on both mirror directions.
TEST(PhongAuto, ChoosesTwoLobesForTwoLights) {
  sim::Scene scene = sim::make_scene("patchwork").value();
  scene.lights.push_back({Vec3d(-1500, 1000, 2000), scene.lights[0].intensity * 0.4});
  const Vec3d p(225, -225, 0);
  const TexelObservations obs = observe(scene, p, 2500.0, 4.0);
  const PhongFit fit = fit_phong_auto(obs, {});
  ASSERT_EQ(fit.params.lobes.size(), 2u);
  for (const auto& light : scene.lights) {
    const Vec3d m = mirror_direction((light.position_mm - p).normalized(), Vec3d::UnitZ());
    double best = 1e9;
    for (const auto& lobe : fit.params.lobes) best = std::min(best, rad_to_deg(angle_between(lobe.direction, m)));
    EXPECT_LT(best, 1.0);
  }
}

// A single-light glossy texel gets one lobe (the BIC does not buy more), a diffuse one none (and one when every
// fit must keep a lobe, as before the lobe count started at 0).
TEST(PhongAuto, ChoosesOneLobeForOneLight) {
  auto scene = sim::make_scene("patchwork");
  ASSERT_TRUE(scene);
  const Vec3d glossy(225, -225, 0), diffuse(-225, -225, 0);
  EXPECT_EQ(fit_phong_auto(observe(*scene, glossy, 2500.0, 5.0), {}).params.lobes.size(), 1u);
  EXPECT_EQ(fit_phong_auto(observe(*scene, diffuse, 2500.0, 5.0), {}).params.lobes.size(), 0u);
  PhongFitOptions keep;
  keep.significant_lobes_only = false;
  EXPECT_EQ(fit_phong_auto(observe(*scene, diffuse, 2500.0, 5.0), keep).params.lobes.size(), 1u);
  const auto truth = scene->phong_truth(Vec3d(225, -225, 0));
  const PhongFit fit = fit_phong_auto(observe(*scene, Vec3d(225, -225, 0), 2500.0, 5.0), {});
  ASSERT_FALSE(fit.params.lobes.empty());
  EXPECT_LT(rad_to_deg(angle_between(fit.params.lobes[0].direction, truth->mirror_dir)), 1.0);
}

// Camera noise is multiplicative (shot noise grows with the signal), so the highlight's residuals are far larger
// than the rest: the worry is that the BIC, which assumes one noise level, reads them as structure and buys lobes.
// Measured: with 5 % Gaussian multiplicative noise (and up to 15 %) both residual modes keep one lobe for one light
// and two for two, 20 of 20 times; the lobes stay within 1 deg of the mirror directions at 5 % (the weaker one
// drifts to ~2.5 deg at 15 %).
TEST(PhongAuto, KeepsTheLobeCountUnderMultiplicativeNoise) {
  const sim::Scene one = sim::make_scene("patchwork").value();
  const sim::Scene two = [&] {
    sim::Scene scene = one;
    scene.lights.push_back({Vec3d(-1500, 1000, 2000), one.lights[0].intensity * 0.4});
    return scene;
  }();
  const Vec3d p(225, -225, 0);
  PhongFitOptions relative;
  relative.residual = ResidualMode::kRelative;
  int absolute_right = 0, relative_right = 0, runs = 0;
  for (unsigned seed = 1; seed <= 10; ++seed)
    for (const sim::Scene* scene : {&one, &two}) {
      TexelObservations obs = observe(*scene, p, 2500.0, 5.0);
      std::mt19937 rng(seed);
      std::normal_distribution<float> noise(0.0f, 0.05f);
      for (auto& rgb : obs.radiance)
        for (int c = 0; c < 3; ++c) rgb[c] *= 1.0f + noise(rng);
      const size_t lights = scene->lights.size();
      absolute_right += fit_phong_auto(obs, {}).params.lobes.size() == lights;
      const PhongFit fit = fit_phong_auto(obs, relative);
      relative_right += fit.params.lobes.size() == lights;
      ++runs;
      if (fit.params.lobes.size() != lights) continue;
      for (const auto& light : scene->lights) {
        const Vec3d m = mirror_direction((light.position_mm - p).normalized(), Vec3d::UnitZ());
        double best = 1e9;
        for (const auto& lobe : fit.params.lobes) best = std::min(best, rad_to_deg(angle_between(lobe.direction, m)));
        EXPECT_LT(best, 1.0) << "seed " << seed << ", " << lights << " light(s)";
      }
    }
  std::printf("phong:auto under 5 %% multiplicative noise: right lobe count %d/%d absolute, %d/%d relative\n",
              absolute_right, runs, relative_right, runs);
  EXPECT_EQ(absolute_right, runs);
  EXPECT_EQ(relative_right, runs);
}

// BIC arithmetic: n ln(RSS / n) + p ln n, with the round-off floor.
TEST(PhongAuto, BicFormula) {
  EXPECT_NEAR(phong_bic(2.0, 100, 10, 1.0), 100 * std::log(0.02) + 10 * std::log(100.0), 1e-9);
  EXPECT_EQ(phong_parameter_count(1, true), 9);  // Kd 3, Ks 3, direction 2 (unit), m 1
  EXPECT_EQ(phong_parameter_count(2, true), 14);
  EXPECT_EQ(phong_parameter_count(2, false), 15);
  EXPECT_EQ(phong_parameter_count(0, true), 3);  // Kd only: no shininess without a lobe
  // Below the floor (1e-6 of the observed RMS) RSS differences do not count.
  EXPECT_EQ(phong_bic(1e-20, 100, 10, 1.0), phong_bic(1e-30, 100, 10, 1.0));
}

}  // namespace
}  // namespace vdrig::fitting
