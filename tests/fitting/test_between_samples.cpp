// Phong maps judged where the viewer looks: between the photographed directions, on observations as an 8-bit camera
// records them (quantised, with shot and read noise), not on the noise-free radiance of exactly the fitted form.
// The figures are those of dense directions over the whole upper hemisphere against the simulator's truth
// (docs/models.md, "Between the samples").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "hemisphere_support.hpp"
#include "rig_observations.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/texel_recording.hpp"

namespace vdrig::fitting {
namespace {

using test_support::fibonacci_hemisphere;
using test_support::observe_texel;
using test_support::scheme_directions;

/// What an 8-bit camera makes of a texel's radiance (sim::TexelRecording's defaults: the brightest observation at 220
/// codes, shot noise of a 20000-electron well, read noise of 0.5 codes, rounding, clipping at 255), back in radiance
/// units. Returns the codes-per-radiance gain.
double record_8bit(TexelObservations& obs, unsigned seed) { return sim::record_texel(obs.radiance, {}, seed); }

/// n x n texel centres of the named material, evenly picked among the points of a 10 mm grid over the surface whose
/// neighbourhood (+-15 mm) is all of that material (no mixed texels: those are judged by vdrig eval on real sessions).
std::vector<Vec3d> texels_of(const sim::Scene& scene, const std::string& material, int n) {
  std::vector<Vec3d> inside;
  auto is = [&](double x, double y) {
    const int m = scene.material_at(x, y);
    return m >= 0 && scene.materials[static_cast<size_t>(m)].name == material;
  };
  for (double y = -0.5 * scene.height_mm + 5; y < 0.5 * scene.height_mm; y += 10)
    for (double x = -0.5 * scene.width_mm + 5; x < 0.5 * scene.width_mm; x += 10)
      if (is(x, y) && is(x - 15, y - 15) && is(x + 15, y - 15) && is(x - 15, y + 15) && is(x + 15, y + 15))
        inside.emplace_back(x, y, 0.0);
  std::vector<Vec3d> out;
  const size_t want = static_cast<size_t>(n * n);
  if (inside.size() < want) {
    ADD_FAILURE() << "only " << inside.size() << " points of " << material;
    return inside;
  }
  for (size_t k = 0; k < want; ++k) out.push_back(inside[k * inside.size() / want + inside.size() / (2 * want)]);
  return out;
}

/// A fit judged at dense directions against the truth.
struct DenseError {
  double relative_rms = 0.0;    // sqrt(sum |fit - truth|^2 / sum |truth|^2) over the dense directions (as vdrig eval)
  double brighter_codes = 0.0;  // the most the fit is brighter than the truth in any direction and channel, in codes
};

DenseError dense_error(const PhongParams& fit, const sim::Scene& scene, const Vec3d& p, double gain) {
  static const std::vector<Vec3d> dense = fibonacci_hemisphere(1000);
  DenseError e;
  double err2 = 0.0, truth2 = 0.0;
  for (const Vec3d& v : dense) {
    const Vec3d truth = scene.radiance(p, v), model = fit.evaluate(v);
    err2 += (model - truth).squaredNorm();
    truth2 += truth.squaredNorm();
    e.brighter_codes = std::max(e.brighter_codes, (model - truth).maxCoeff() * gain);
  }
  e.relative_rms = std::sqrt(err2 / truth2);
  return e;
}

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(std::ceil(q * static_cast<double>(v.size()))) - 1)];
}

int lobes_with_energy(const PhongParams& p) {
  int n = 0;
  for (const PhongLobe& l : p.lobes) n += l.ks.maxCoeff() > 1e-3 * p.kd.maxCoeff();
  return n;
}

PhongFit fit(const TexelObservations& obs, bool automatic, const PhongFitOptions& options) {
  return automatic ? fit_phong_auto(obs, options) : fit_phong(obs, options);
}

/// The options before the support cap and the lobe-count choice (every lobe kept, as narrow as the fit likes).
PhongFitOptions unguarded() {
  PhongFitOptions o;
  o.lobe_support = 0;
  o.significant_lobes_only = false;
  return o;
}

// The red-cloth texel: a Lambertian patch seen from a sparse geodesic set (73 views, icosahedron:2@85),
// recorded in 8 bits. A lobe there is noise fitted in a gap between the views: phong:1 and phong:auto must give none,
// and nowhere over the hemisphere may the map be brighter than the truth by more than a couple of codes. Over ten
// noise seeds: 0/36 texels with a lobe in each, at most 0.74 codes brighter (0.26 with this seed). With the BIC alone
// (no detection rule, kLobeDetectionSnr) 6 seeds of 10 left lobes, in up to 6 texels, up to 10.9 codes bright.
TEST(BetweenTheSamples, SparseLambertianPatchIn8BitsGetsNoLobe) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::vector<Vec3d> views = scheme_directions("icosahedron:2@85");
  ASSERT_GT(views.size(), 60u);
  for (const bool automatic : {false, true}) {
    int with_lobe = 0, unguarded_with_lobe = 0, texels = 0;
    double brighter = 0.0, unguarded_brighter = 0.0;
    unsigned seed = 1;
    for (const Vec3d& p : texels_of(scene, "red cloth", 6)) {
      TexelObservations obs = observe_texel(scene, p, views);
      const double gain = record_8bit(obs, seed++);
      const PhongFit guarded = fit(obs, automatic, {});
      with_lobe += lobes_with_energy(guarded.params) > 0;
      brighter = std::max(brighter, dense_error(guarded.params, scene, p, gain).brighter_codes);
      const PhongFit before = fit(obs, automatic, unguarded());
      unguarded_with_lobe += lobes_with_energy(before.params) > 0;
      unguarded_brighter = std::max(unguarded_brighter, dense_error(before.params, scene, p, gain).brighter_codes);
      ++texels;
    }
    const char* name = automatic ? "phong:auto" : "phong:1";
    std::printf(
        "%s, red cloth, icosahedron:2@85, 8 bits: %d/%d texels with a lobe, at most %.2f codes brighter "
        "than the truth (unguarded: %d/%d, %.2f codes)\n",
        name, with_lobe, texels, brighter, unguarded_with_lobe, texels, unguarded_brighter);
    EXPECT_EQ(with_lobe, 0) << name;
    EXPECT_LT(brighter, 2.0) << name;
    // The test can fail: without the guards the same observations do get lobes that light up between the views.
    EXPECT_GT(unguarded_brighter, 2.0) << name;
  }
}

// One light, glossy plastic: phong:auto finds one lobe (not more) under noise, at the mirror direction.
TEST(BetweenTheSamples, OneLightGlossyTexelsGetOneLobeUnderNoise) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::vector<Vec3d> views = scheme_directions("latlong:8");
  int one = 0, texels = 0;
  double worst_angle_deg = 0.0;
  unsigned seed = 100;
  for (const Vec3d& p : texels_of(scene, "glossy plastic", 5)) {
    TexelObservations obs = observe_texel(scene, p, views);
    record_8bit(obs, seed++);
    const PhongFit f = fit_phong_auto(obs, {});
    ++texels;
    if (lobes_with_energy(f.params) != 1) continue;
    ++one;
    worst_angle_deg = std::max(
        worst_angle_deg, rad_to_deg(angle_between(f.params.lobes[0].direction, scene.phong_truth(p)->mirror_dir)));
  }
  std::printf("phong:auto, glossy plastic, latlong:8, 8 bits: one lobe in %d/%d texels, worst direction %.2f deg\n",
              one, texels, worst_angle_deg);
  EXPECT_EQ(one, texels);
  EXPECT_LT(worst_angle_deg, 1.5);
}

// The goal for the uniform materials of the demo's scene and scheme (latlong:8, 188 views), between the
// samples: dense mean under 2 % and p99 under 10 % for phong:1 and phong:auto, on 8-bit observations.
TEST(BetweenTheSamples, UniformMaterialsHoldAtDenseDirections) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::vector<Vec3d> views = scheme_directions("latlong:8");
  const std::vector<std::string> materials = {"paper",     "red cloth", "glossy plastic", "band m=2",   "band m=4",
                                              "band m=10", "band m=21", "band m=47",      "band m=103", "band m=227"};
  for (const bool automatic : {false, true}) {
    unsigned seed = 1000;
    for (const std::string& material : materials) {
      std::vector<double> errors;
      for (const Vec3d& p : texels_of(scene, material, 4)) {
        TexelObservations obs = observe_texel(scene, p, views);
        const double gain = record_8bit(obs, seed++);
        errors.push_back(dense_error(fit(obs, automatic, {}).params, scene, p, gain).relative_rms);
      }
      double mean = 0.0;
      for (double e : errors) mean += e / static_cast<double>(errors.size());
      const double p99 = percentile(errors, 0.99);
      const char* name = automatic ? "phong:auto" : "phong:1";
      std::printf("%-10s %-15s dense mean %6.2f %%, p99 %6.2f %%\n", name, material.c_str(), 100 * mean, 100 * p99);
      // The goals are 2 % and 10 %. Measured here at most 0.40 % and 1.10 % (band m=227); over ten noise
      // seeds at most 0.40 % and 1.10 % too (p99 0.42 .. 1.10 %). 0.42 % and 3.25 % without the peak rule
      // (kLobePeakLevel).
      EXPECT_LT(mean, 0.006) << name << ", " << material;
      EXPECT_LT(p99, 0.016) << name << ", " << material;
    }
  }
}

// A lobe narrower than the sampling (m = 500 seen at ~10 deg spacing) is held at the sampling's bound and says so
// (PhongFit::capped_lobes, the map's m_capped channel); a lobe the views resolve (glossy plastic, m = 60) is not.
TEST(BetweenTheSamples, ALobeNarrowerThanTheSamplingIsMarked) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::vector<Vec3d> views = scheme_directions("latlong:8");
  unsigned seed = 7;
  for (const auto& [material, capped] : {std::pair{"band m=500", true}, std::pair{"glossy plastic", false}}) {
    int marked = 0, texels = 0;
    for (const Vec3d& p : texels_of(scene, material, 3)) {
      TexelObservations obs = observe_texel(scene, p, views);
      record_8bit(obs, seed++);
      const PhongFit f = fit_phong(obs, {});
      ASSERT_EQ(f.params.lobes.size(), 1u) << material;
      const double m = f.params.lobes[0].shininess;
      EXPECT_LE(m, phong_support_cap(obs, f.params.lobes[0].direction, PhongFitOptions{}.lobe_support) * (1 + 1e-6));
      marked += f.capped_lobes;
      ++texels;
    }
    if (capped)  // measured: 7 of 9 (the other two chose a wider lobe than their cap on their own)
      EXPECT_GE(3 * marked, 2 * texels) << material;
    else
      EXPECT_EQ(marked, 0) << material;
  }
}

// The cap itself: the largest shininess that keeps `support` observations inside the lobe's 10 % cone.
TEST(BetweenTheSamples, SupportCapPutsTheNthObservationOnTheConesEdge) {
  TexelObservations obs;
  const Vec3d axis = Vec3d::UnitZ();
  for (double deg : {3.0, 7.0, 12.0, 30.0}) {
    obs.direction.push_back(direction_from_spherical(0.3 * deg, deg_to_rad(deg)).cast<float>());
    obs.radiance.emplace_back(1.0f, 1.0f, 1.0f);
    obs.view.push_back(static_cast<int>(obs.view.size()));
  }
  auto cosine = [&](int k) { return obs.direction[static_cast<size_t>(k)].cast<double>().normalized().dot(axis); };
  // Support 2 and 3: the 2nd / 3rd nearest observation on the 10 % cone's edge; the nearest one at >= half the peak.
  for (int support : {2, 3}) {
    const double m = phong_support_cap(obs, axis, support);
    EXPECT_NEAR(std::pow(cosine(support - 1), m), kLobeSupportLevel, 1e-5) << support;
    EXPECT_GE(std::pow(cosine(0), m), kLobePeakLevel) << support;
  }
  // Support 1: the peak rule binds (the nearest observation at half the peak, inside its 10 % cone).
  EXPECT_NEAR(std::pow(cosine(0), phong_support_cap(obs, axis, 1)), kLobePeakLevel, 1e-5);
  // The peak rule alone: one observation 10 deg from a lobe at the horizon allows m up to ln 0.5 / ln cos 10 deg.
  TexelObservations rim;
  rim.direction = {direction_from_spherical(0.0, deg_to_rad(80.0)).cast<float>(),
                   direction_from_spherical(0.05, deg_to_rad(80.0)).cast<float>()};
  rim.radiance.assign(2, Eigen::Vector3f::Ones());
  rim.view = {0, 1};
  EXPECT_NEAR(phong_support_cap(rim, direction_from_spherical(0.0, deg_to_rad(90.0)), 2),
              std::log(0.5) / std::log(std::cos(deg_to_rad(10.0))), 1e-4);  // float directions
  EXPECT_TRUE(std::isinf(phong_support_cap(obs, axis, 0)));
  EXPECT_EQ(phong_support_cap(obs, axis, 5), 1.0);   // fewer observations than the support asks
  EXPECT_EQ(phong_support_cap(obs, -axis, 1), 1.0);  // none in front of the lobe
}

}  // namespace
}  // namespace vdrig::fitting
