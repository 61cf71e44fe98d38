// The issue #5 targets that the source method's comparison tests (Mortensen & Andersen 2007, named in docs/results.md;
// chapters 11-13) set, checked on the simulator's ground truth. The full table with the source's
// figures beside ours is docs/results.md (bench/results_table.cpp); these tests hold the figures that must not
// regress. Texels are observed as the rig sees them: for each scheme direction the camera pose of rig::surface_pose
// (pan = pi/2 - azimuth, tilt = zenith) at 2500 mm, the view direction from the texel to the camera centre, and the
// scene's exact radiance toward it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "rig_observations.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/fitting/sh.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::fitting {
namespace {

const Vec3d kGlossyTexel(225, -225, 0);  // patchwork's glossy plastic patch, m = 60

std::vector<Vec3d> scheme(const std::string& spec) { return test_support::scheme_directions(spec); }
TexelObservations observe(const sim::Scene& scene, const Vec3d& p, const std::vector<Vec3d>& dirs) {
  return test_support::observe_texel(scene, p, dirs);
}
using test_support::observe_map;

/// The source's method: every lobe kept, as narrow as the observations allow. On noise-free data of exactly the
/// model's form (these tests') a lobe narrower than the sampling is still identified; on real data vdrig's defaults
/// cap it and drop insignificant lobes (docs/models.md, "Between the samples"; test_between_samples.cpp).
PhongFitOptions source_method(int lobes = 1) {
  PhongFitOptions o;
  o.lobes = lobes;
  o.lobe_support = 0;
  o.significant_lobes_only = false;
  return o;
}

using test_support::Errors;
using test_support::errors;
using test_support::rel;

/// RMS error of a linear fit against the true radiance over icosahedron:4 up to 80 deg zenith, relative to the
/// texel's maximum there.
template <typename Eval>
double relative_rms(const Eval& eval, const sim::Scene& scene, const Vec3d& p) {
  static const std::vector<Vec3d> dirs = scheme("icosahedron:4@80");
  double sq = 0, peak = 0;
  for (const Vec3d& d : dirs) {
    const Vec3d truth = scene.radiance(p, d);
    peak = std::max(peak, truth.maxCoeff());
    const Eigen::VectorXd f = eval(d);
    sq += (Vec3d(f[0], f[1], f[2]) - truth).squaredNorm();
  }
  return std::sqrt(sq / (3.0 * dirs.size())) / peak;
}

void split(const TexelObservations& obs, std::vector<Vec3d>& dirs, Eigen::MatrixXd& values) {
  dirs.clear();
  values.resize(static_cast<Eigen::Index>(obs.size()), 3);
  for (size_t i = 0; i < obs.size(); ++i) {
    dirs.push_back(obs.direction[i].cast<double>());
    values.row(static_cast<Eigen::Index>(i)) = obs.radiance[i].cast<double>().transpose();
  }
}

// Source 11.3.1 (one point light): the source reports mean percentage residuals of [0.94, 2.34, 2.34]. The issue's
// target on noise-free simulated data: Kd, Ks within 1 %, r within 0.5 deg, m within 3 %, mean percentage residual
// below 0.5 % per channel, on the glossy texel and on every shininess band (m = 2 .. 500), from 305 directions.
TEST(SourceComparisons, OnePointLightPhong1RecoversTheTruth) {
  const auto dirs = scheme("icosahedron:3");
  ASSERT_EQ(dirs.size(), 305u);
  std::vector<std::pair<std::string, Vec3d>> texels = {{"patchwork", kGlossyTexel}};
  for (int k = 0; k < 8; ++k) texels.push_back({"bands", Vec3d(-400 + 100 * (k + 0.5), 0, 0)});
  for (const auto& [name, p] : texels) {
    const sim::Scene scene = sim::make_scene(name).value();
    const auto truth = scene.phong_truth(p);
    ASSERT_TRUE(truth.has_value()) << name << " " << p.transpose();
    const PhongFit fit = fit_phong(observe(scene, p, dirs), source_method());
    const Errors e = errors(fit, *truth);
    SCOPED_TRACE(name + " m = " + std::to_string(truth->shininess));
    EXPECT_LT(e.kd, 0.01);
    EXPECT_LT(e.ks, 0.01);
    EXPECT_LT(e.r_deg, 0.5);
    EXPECT_LT(e.m, 0.03);
    for (int c = 0; c < 3; ++c) EXPECT_LT(fit.quality.mean_percent[c], 0.5) << "channel " << c;
  }
}

// Source 13.2: from only 17 icosahedron directions the source's Phong-1 parameters stayed within 15 % of the
// 305-direction fit (Kd, r within 1 %, m 5 %); the target is within 5 % of the truth. Measured here,
// noise-free: Kd holds everywhere; all parameters hold (errors ~0) on the bands up to m = 47, whose lobes reach
// enough of the ~30 deg-spaced samples. They do NOT hold for the glossy texel (m = 60: Ks 40 %, m 17 %, r 1.35 deg
// with a fit residual of 0.001 %, i.e. the 17 samples barely constrain the lobe) nor for m >= 103, where the
// highlight falls between samples and the fit is exact with Ks ~ 0 (the data do not contain the highlight). So the
// test asserts Kd everywhere and every parameter for m <= 47, and prints the rest. A single texel cannot do better;
// a map can: SeventeenDirectionsPhong1WithSharedLights below meets the 5 % target through the shared lights.
TEST(SourceComparisons, SeventeenDirectionsPhong1) {
  const auto dirs = scheme("icosahedron:1");
  ASSERT_EQ(dirs.size(), 17u);
  std::vector<std::pair<std::string, Vec3d>> texels = {{"patchwork", kGlossyTexel}};
  for (int k = 0; k < 8; ++k) texels.push_back({"bands", Vec3d(-400 + 100 * (k + 0.5), 0, 0)});
  for (const auto& [name, p] : texels) {
    const sim::Scene scene = sim::make_scene(name).value();
    const auto truth = scene.phong_truth(p);
    ASSERT_TRUE(truth.has_value());
    const PhongFit fit = fit_phong(observe(scene, p, dirs), source_method());
    const Errors e = errors(fit, *truth);
    std::printf("17 dirs %-9s m=%6.1f  Kd %.4f  Ks %.4f  r %.3f deg  m %.4f  fit mean%% %.4f\n", name.c_str(),
                truth->shininess, e.kd, e.ks, e.r_deg, e.m, fit.quality.mean_percent.maxCoeff());
    SCOPED_TRACE(name + " m = " + std::to_string(truth->shininess));
    EXPECT_LT(e.kd, 0.05);
    if (name == "bands" && truth->shininess < 50) {
      EXPECT_LT(e.ks, 0.05);
      EXPECT_LT(e.m, 0.05);
      EXPECT_LT(e.r_deg, 0.5);
    }
  }
}

// The same 17 directions over a whole map, as `vdrig fit --shared-lights` fits it: the per-texel fits give the light
// (fixed to the platform, the same for every texel), and every texel is refitted with its lobe at that light's mirror
// direction (MapFitOptions::shared_lights). Ks and m become identifiable: the 5 % holds for the glossy texel
// (measured: Ks 0.22 %, m 0.07 %, r 0.005 deg) and for every band texel whose highlight reaches 1 % of its peak at
// one of the 17 samples at least (up to m = 103 here; beyond, the data hold no highlight to fit). A wrongly placed
// light would show in r (asserted to 0.1 deg where the data hold the highlight, and on every refitted texel). Where
// they hold none (the two m = 227 texels: < 1e-3 of the peak seen) what the refit puts at its peak is not in the data
// and phong_refit_within_free_fit keeps the free fit, its lobe 10 and 16 deg off the mirror direction.
TEST(SourceComparisons, SeventeenDirectionsPhong1WithSharedLights) {
  const auto dirs = scheme("icosahedron:1");
  ASSERT_EQ(dirs.size(), 17u);
  MapFitOptions options;
  options.model = parse_model("phong:1").value();
  options.shared_lights = true;
  options.model_options.set(source_method());
  options.threads = 2;
  // patchwork on a 20 x 20 grid: texel (14, 5) is centred on the glossy texel (225, -225) mm.
  {
    const sim::Scene scene = sim::make_scene("patchwork").value();
    auto map = fit_parameter_map(observe_map(scene, dirs, 20, 20), options);
    ASSERT_TRUE(map) << map.error().describe();
    ASSERT_EQ(texel_centre_mm(14, 5, 20, 20, scene.width_mm, scene.height_mm), kGlossyTexel);
    const auto truth = scene.phong_truth(kGlossyTexel);
    ASSERT_TRUE(truth.has_value());
    PhongFit fit;
    fit.params = phong_texel(*map, 14, 5);
    const Errors e = errors(fit, *truth);
    std::printf("17 dirs, shared lights, glossy m=60: Kd %.4f  Ks %.4f  r %.4f deg  m %.4f\n", e.kd, e.ks, e.r_deg,
                e.m);
    EXPECT_EQ(map->at("shared_lights", 14, 5), 1.0f);
    EXPECT_LT(e.kd, 0.05);
    EXPECT_LT(e.ks, 0.05);
    EXPECT_LT(e.m, 0.05);
    EXPECT_LT(e.r_deg, 0.1);
  }
  // bands on a 16 x 4 grid: two texels per band (the bands are 100 mm wide, x from -400 to 400 mm).
  {
    const sim::Scene scene = sim::make_scene("bands").value();
    auto map = fit_parameter_map(observe_map(scene, dirs, 16, 4), options);
    ASSERT_TRUE(map) << map.error().describe();
    for (int s = 0; s < 16; ++s) {
      const Vec3d p = texel_centre_mm(s, 1, 16, 4, scene.width_mm, scene.height_mm);
      const auto truth = scene.phong_truth(p);
      if (!truth) continue;  // outside the bands
      PhongFit fit;
      fit.params = phong_texel(*map, s, 1);
      const Errors e = errors(fit, *truth);
      // How much of the highlight the 17 samples hold: the largest (v . r)^m over them (1 = a sample on the peak).
      double seen = 0;
      const TexelObservations obs = observe(scene, p, dirs);
      for (const auto& v : obs.direction)
        seen = std::max(seen, std::pow(std::max(0.0, v.cast<double>().dot(truth->mirror_dir)), truth->shininess));
      std::printf(
          "17 dirs, shared lights, bands m=%6.1f: Kd %.4f  Ks %.4f  r %.4f deg  m %.4f  (shared %g, peak seen %.3f)\n",
          truth->shininess, e.kd, e.ks, e.r_deg, e.m, map->at("shared_lights", s, 1), seen);
      SCOPED_TRACE("bands texel " + std::to_string(s) + " m = " + std::to_string(truth->shininess));
      EXPECT_LT(e.kd, 0.05);
      if (seen < 0.01) {  // the highlight is not in the data: nothing can recover Ks and m
        if (map->at("shared_lights", s, 1) == 1.0f) {
          EXPECT_LT(e.r_deg, 0.1);
        }
        continue;
      }
      EXPECT_LT(e.r_deg, 0.1);
      EXPECT_LT(e.ks, 0.05);
      EXPECT_LT(e.m, 0.05);
    }
  }
}

// Source 11.3.1, area light: one Phong lobe still fits a small area light's highlight closely, with a lower m than
// the material's (the highlight is wider). Measured: m = 54.9 (400 mm softbox), 36.5 (1000 mm), mean residual
// <= 0.2 %.
TEST(SourceComparisons, AreaLightLowersTheFittedShininess) {
  const auto dirs = scheme("icosahedron:3");
  double previous_m = 60.0;  // the glossy plastic's material shininess
  for (double scale : {1.0, 2.5}) {
    sim::Scene scene = sim::make_scene("softbox").value();
    ASSERT_EQ(scene.area_lights.size(), 1u);
    scene.area_lights[0].edge_u_mm *= scale;
    scene.area_lights[0].edge_v_mm *= scale;
    const PhongFit fit = fit_phong(observe(scene, kGlossyTexel, dirs), source_method());
    ASSERT_EQ(fit.params.lobes.size(), 1u);
    EXPECT_LT(fit.params.lobes[0].shininess, previous_m) << "panel scale " << scale;
    previous_m = fit.params.lobes[0].shininess;
    for (int c = 0; c < 3; ++c) EXPECT_LT(fit.quality.mean_percent[c], 0.5) << "panel scale " << scale;
  }
}

// Source 11.3.2: one lobe cannot represent two highlights (its residual grows with their separation); Phong-2 finds
// both mirror directions. Second light at 0.4 x intensity, mirror direction rotated in azimuth by 10..60 deg.
TEST(SourceComparisons, TwoLightsNeedTwoLobes) {
  const sim::Scene base = sim::make_scene("patchwork").value();
  const Vec3d p = kGlossyTexel;
  const Vec3d l1 = base.lights[0].position_mm;
  const Vec3d r1 = mirror_direction((l1 - p).normalized(), Vec3d::UnitZ());
  const SphericalDir s1 = spherical_from_direction(r1);
  const auto dirs = scheme("icosahedron:3");
  for (double sep_deg : {10.0, 20.0, 40.0, 60.0}) {
    const double z = s1.zenith_rad, c = std::cos(deg_to_rad(sep_deg));
    const double d_az = std::acos((c - std::cos(z) * std::cos(z)) / (std::sin(z) * std::sin(z)));
    const Vec3d r2 = direction_from_spherical(s1.azimuth_rad + d_az, z);
    ASSERT_NEAR(rad_to_deg(angle_between(r1, r2)), sep_deg, 1e-6);
    sim::Scene scene = base;
    scene.lights.push_back(
        {p + (l1 - p).norm() * mirror_direction(r2, Vec3d::UnitZ()), base.lights[0].intensity * 0.4});
    const TexelObservations obs = observe(scene, p, dirs);
    const PhongFit one = fit_phong(obs, source_method());
    const PhongFit two = fit_phong(obs, source_method(2));
    ASSERT_EQ(two.params.lobes.size(), 2u);
    for (const Vec3d& r : {r1, r2}) {
      double best = 1e9;
      for (const auto& lobe : two.params.lobes) best = std::min(best, rad_to_deg(angle_between(lobe.direction, r)));
      EXPECT_LT(best, 1.0) << "separation " << sep_deg;
    }
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_LT(two.quality.mean_percent[ch], 0.5) << "separation " << sep_deg;
      EXPECT_GT(one.quality.mean_percent[ch], 2 * two.quality.mean_percent[ch]) << "separation " << sep_deg;
    }
  }
}

// The issue: HSH (orthonormal on the hemisphere) fits the shininess bands better than SH-LSOP at the same number of
// coefficients (25 and 36), 305 directions, judged against the true radiance. Measured: it holds on all eight
// bands, e.g. 36 coefficients: m = 2: 0.34 % vs 6.2 %; m = 21: 1.9 % vs 5.4 %; m = 500: 2.2 % vs 5.9 %.
TEST(SourceComparisons, HshBeatsShLsopOnTheBands) {
  const sim::Scene scene = sim::make_scene("bands").value();
  const auto dirs = scheme("icosahedron:3");
  for (int k = 0; k < 8; ++k) {
    const Vec3d p(-400 + 100 * (k + 0.5), 0, 0);
    std::vector<Vec3d> d;
    Eigen::MatrixXd values;
    split(observe(scene, p, dirs), d, values);
    for (int bands : {5, 6}) {
      const Eigen::MatrixXd sh = fit_sh({.bands = bands, .method = ShFitMethod::kLsop}, d, values);
      const Eigen::MatrixXd hsh = fit_hsh({.bands = bands}, d, values);
      const double sh_rms = relative_rms([&](const Vec3d& v) { return eval_sh(sh, v); }, scene, p);
      const double hsh_rms = relative_rms([&](const Vec3d& v) { return eval_hsh(hsh, v); }, scene, p);
      std::printf("band %d m=%6.1f  %d coeffs: SH-LSOP %.4f  HSH %.4f\n", k + 1, sim::band_shininess(k), bands * bands,
                  sh_rms, hsh_rms);
      EXPECT_LT(hsh_rms, sh_rms) << "band " << k + 1 << ", " << bands * bands << " coefficients";
    }
  }
}

}  // namespace
}  // namespace vdrig::fitting
