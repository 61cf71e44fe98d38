// A lobe held at a fixed direction (PhongFitOptions::fixed_directions, the shared-lights refit) that the observations
// barely see: its peak must stay near what they allow, not run to a highlight nothing saw (docs/models.md, "Sparse
// views and shared lights"). On adaptive:60 sessions of lights2 such lobes reached Ks 18000 at m 5000, 2400 % relative
// RMS between the views.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "rig_observations.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/sim/texel_recording.hpp"

namespace vdrig::fitting {
namespace {

using test_support::scheme_directions;

/// `truth` seen from `views` as an 8-bit camera records it (sim::record_texel, noise seed `seed`).
TexelObservations recorded_texel(const std::vector<Vec3d>& views, const PhongParams& truth, unsigned seed) {
  TexelObservations obs;
  for (const Vec3d& v : views) {
    obs.direction.push_back(v.cast<float>());
    obs.radiance.push_back(truth.evaluate(v).cast<float>());
    obs.view.push_back(static_cast<int>(obs.view.size()));
  }
  sim::record_texel(obs.radiance, {}, seed);
  return obs;
}

/// The worst, over `seeds` seeds of 8-bit noise (sim::record_texel), of a fit with the lobe held at `mirror`: the
/// prediction there, and the fitted peak over `seen`, what the nearest view saw of the truth's lobe.
struct Worst {
  double at_mirror = 0.0, peak_over_seen = 0.0;
};
Worst fit_over_seeds(const std::vector<Vec3d>& views, const PhongParams& truth, const Vec3d& mirror, double seen,
                     unsigned seeds) {
  Worst worst;
  for (unsigned seed = 1; seed <= seeds; ++seed) {
    const TexelObservations obs = recorded_texel(views, truth, seed);
    PhongFitOptions o;
    o.fixed_directions = {mirror};
    const PhongFit fit = fit_phong(obs, o);
    const double peak = fit.params.lobes.empty() ? 0.0 : fit.params.lobes[0].ks.maxCoeff();
    const double m = fit.params.lobes.empty() ? 0.0 : fit.params.lobes[0].shininess;
    const double at_mirror = fit.params.evaluate(mirror).maxCoeff();
    std::printf("seed %u: lobes %zu  Ks %.3g  m %.1f  capped %d  I(mirror) %.3g (truth %.3f; seen %.4f)\n", seed,
                fit.params.lobes.size(), peak, m, fit.capped_lobes, at_mirror, truth.evaluate(mirror).maxCoeff(), seen);
    worst.at_mirror = std::max(worst.at_mirror, at_mirror);
    worst.peak_over_seen = std::max(worst.peak_over_seen, peak / seen);
  }
  std::printf("worst: I(mirror) %.3g, peak / seen %.3g\n", worst.at_mirror, worst.peak_over_seen);
  return worst;
}

// A narrow highlight (m = 500) whose mirror direction lies 7 deg from the nearest of 17 views and >= 25 deg from the
// others: one view sees its flank (cos(7 deg)^500 = 2.4 % of the peak), none its shape. Observed as an 8-bit camera
// records them. With the direction fixed and no cap, Ks and m trade along what the one view saw and the solve runs to
// m = max_shininess; the cap (phong_support_cap, both rules) holds the peak to twice what that view saw.
TEST(FixedDirectionSupport, LobeSeenByOneViewKeepsItsPeakNearWhatThatViewSaw) {
  const std::vector<Vec3d> views = scheme_directions("icosahedron:1");
  ASSERT_EQ(views.size(), 17u);
  // The view nearest zenith 40 deg, azimuth 0; the mirror direction 7 deg from it, away from the other views' ring.
  const Vec3d target = direction_from_spherical(0.0, deg_to_rad(40.0));
  const Vec3d nearest = *std::max_element(
      views.begin(), views.end(), [&](const Vec3d& a, const Vec3d& b) { return a.dot(target) < b.dot(target); });
  const SphericalDir sd = spherical_from_direction(nearest);
  const Vec3d mirror =
      direction_from_spherical(sd.azimuth_rad + deg_to_rad(7.0) / std::sin(sd.zenith_rad), sd.zenith_rad);
  std::vector<double> angles_deg;
  for (const Vec3d& v : views) angles_deg.push_back(rad_to_deg(std::acos(std::clamp(v.dot(mirror), -1.0, 1.0))));
  std::sort(angles_deg.begin(), angles_deg.end());
  std::printf("mirror direction: nearest views at %.1f, %.1f, %.1f deg\n", angles_deg[0], angles_deg[1], angles_deg[2]);
  ASSERT_NEAR(angles_deg[0], 7.0, 0.5);
  ASSERT_GT(angles_deg[1], 20.0);

  PhongParams truth;
  truth.kd = Vec3d(0.07, 0.07, 0.07);
  truth.lobes.push_back({Vec3d(1.0, 1.0, 1.0), mirror, 500.0});
  const double seen = truth.lobes[0].ks.maxCoeff() * std::pow(std::cos(deg_to_rad(angles_deg[0])), 500.0);

  const Worst worst = fit_over_seeds(views, truth, mirror, seen, 8);
  // The peak is at most 1 / kLobePeakLevel = 2 times what the one view saw of it: measured 1.26 (8 seeds; 28 without
  // the cap, m held at the coarse search's 438).
  EXPECT_LT(worst.peak_over_seen, 2.0);
  // The prediction at the mirror direction: measured 0.100 (0.736 without the cap). The truth's 1.07 is what the
  // sampling cannot show, and the map does not claim it.
  EXPECT_LT(worst.at_mirror, 0.15);
}

// A lobe held at a fixed direction that two views see at about the same cosine (8.7 and 8.9 deg from its axis, every
// other view >= 30 deg away): both see it, but at the same height on its flank, so they do not measure its width --
// Ks and m trade along what they saw, and the ratio of the two noisy observations sets m = ln(I1 / I2) / ln(c1 / c2).
// On adaptive sessions such lobes ran to m 1866, Ks 9e8 (lights2 adaptive:60 seed 2; patchwork adaptive:45: m 1312,
// Ks 4e5): phong_lobe_width_measured caps them as free lobes.
TEST(FixedDirectionSupport, LobeSeenByTwoViewsAtTheSameCosineKeepsItsPeakNearWhatTheySaw) {
  const Vec3d mirror = direction_from_spherical(0.3, deg_to_rad(30.0));
  const Vec3d across = mirror.cross(Vec3d::UnitZ()).normalized();
  const Vec3d along = across.cross(mirror).normalized();
  std::vector<Vec3d> views;
  for (const Vec3d& v : scheme_directions("icosahedron:1"))
    if (v.dot(mirror) < std::cos(deg_to_rad(30.0))) views.push_back(v);
  // The two near views, on either side of the axis (across the plane of incidence, both above the horizon).
  views.push_back(Eigen::AngleAxisd(deg_to_rad(8.7), along) * mirror);
  views.push_back(Eigen::AngleAxisd(-deg_to_rad(8.9), along) * mirror);
  ASSERT_GE(views.size(), 12u);

  PhongParams truth;
  truth.kd = Vec3d(0.07, 0.07, 0.07);
  truth.lobes.push_back({Vec3d(0.5, 0.5, 0.5), mirror, 60.0});
  const double seen = 0.5 * std::pow(std::cos(deg_to_rad(8.7)), 60.0);

  const Worst worst = fit_over_seeds(views, truth, mirror, seen, 16);
  // Capped (rule (b) of phong_support_cap), the peak is at most 1 / kLobePeakLevel = 2 times what the nearer view
  // saw: measured 2.02 over 16 seeds (2.67 without phong_lobe_width_measured, m free to 83.5). The prediction at the
  // mirror direction: measured 0.575 (0.736 before; the truth is 0.570).
  EXPECT_LT(worst.peak_over_seen, 2.2);
  EXPECT_LT(worst.at_mirror, 0.62);
}

/// The largest channel of `p` over the upper hemisphere (a 4000-direction Fibonacci spiral) and at its lobe axes.
double hemisphere_peak(const PhongParams& p) {
  double peak = 0.0;
  for (const PhongLobe& lobe : p.lobes) peak = std::max(peak, p.evaluate(lobe.direction).maxCoeff());
  const int n = 4000;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
    peak = std::max(peak, p.evaluate(Vec3d(r * std::cos(golden * i), r * std::sin(golden * i), z)).maxCoeff());
  }
  return peak;
}

/// Over `seeds` seeds of 8-bit noise: the worst hemisphere peak (over the truth's) of the refit with its lobe held at
/// `fixed`, and of what the shared-lights pass keeps of it (phong_refit_within_free_fit: the refit or the free fit);
/// how many refits the check accepted.
struct RefitOutcome {
  double refit_peak = 0.0, kept_peak = 0.0;
  int accepted = 0;
};
RefitOutcome refit_over_seeds(const std::vector<Vec3d>& views, const PhongParams& truth, const Vec3d& fixed,
                              unsigned seeds) {
  RefitOutcome out;
  const double truth_peak = hemisphere_peak(truth);
  for (unsigned seed = 1; seed <= seeds; ++seed) {
    const TexelObservations obs = recorded_texel(views, truth, seed);
    PhongFitOptions o;
    const PhongFit free = fit_phong(obs, o);
    o.fixed_directions = {fixed};
    const PhongFit refit = fit_phong(obs, o);
    const bool accepted = phong_refit_within_free_fit(refit.params, free.params, obs);
    const double refit_peak = hemisphere_peak(refit.params) / truth_peak;
    const double kept_peak = hemisphere_peak(accepted ? refit.params : free.params) / truth_peak;
    std::printf("seed %u: refit Ks %.3g m %.1f capped %d, peak / truth %.3g, %s, kept peak / truth %.3g\n", seed,
                refit.params.lobes.empty() ? 0.0 : refit.params.lobes[0].ks.maxCoeff(),
                refit.params.lobes.empty() ? 0.0 : refit.params.lobes[0].shininess, refit.capped_lobes, refit_peak,
                accepted ? "accepted" : "rejected", kept_peak);
    out.refit_peak = std::max(out.refit_peak, refit_peak);
    out.kept_peak = std::max(out.kept_peak, kept_peak);
    out.accepted += accepted;
  }
  std::printf("worst: refit peak / truth %.3g, kept %.3g; %d of %u refits accepted\n", out.refit_peak, out.kept_peak,
              out.accepted, seeds);
  return out;
}

// The shared-lights refit where the estimated light's mirror direction misses the texel's own lobe by a few degrees
// (brushed metal on lights2: 6 deg between the free lobe and the refit's axis) on a sparse view set (30 views): the
// views see only the far flank of the lobe, the fixed-axis lobe reproduces it with a narrow, enormous peak between the
// views -- lights2 adaptive:30 refits reached Ks 4e5 at m 930 (relative RMS 53 on the map), 10 deg from the nearest
// view, and neither support rule capped them (the views that see it see it fall). phong_refit_within_free_fit keeps the
// free fit there.
TEST(FixedDirectionSupport, RefitBetweenSparseViewsStaysWithinTheFreeFit) {
  const std::vector<Vec3d> views = scheme_directions("spiral:30:3@85");
  ASSERT_EQ(views.size(), 30u);
  PhongParams truth;
  truth.kd = Vec3d(0.035, 0.031, 0.027);
  truth.lobes.push_back({Vec3d(0.2, 0.17, 0.12), direction_from_spherical(deg_to_rad(60.0), deg_to_rad(40.0)), 50.0});
  const Vec3d fixed = direction_from_spherical(deg_to_rad(60.0), deg_to_rad(47.0));  // 7 deg off the lobe

  const RefitOutcome off = refit_over_seeds(views, truth, fixed, 16);
  // The explosion, reproduced: the refit's peak is 1.6e7 to 8.2e7 times the truth's over 16 seeds (Ks 3.7e6 to 1.9e7,
  // m 548 to 601, none capped).
  EXPECT_GT(off.refit_peak, 1e6);
  // What the pass keeps (the free fit, every refit rejected) peaks at 0.757 of the truth at worst (8.2e7 without the
  // check).
  EXPECT_EQ(off.accepted, 0);
  EXPECT_LT(off.kept_peak, 1.1);

  // Where the light's mirror direction is the lobe's, the check keeps the refit: 16 of 16 accepted, peak / truth 0.973
  // to 1.02.
  const RefitOutcome on = refit_over_seeds(views, truth, truth.lobes[0].direction, 16);
  EXPECT_GE(on.accepted, 15);
  EXPECT_LT(on.kept_peak, 1.5);
}

}  // namespace
}  // namespace vdrig::fitting
