// Modified Phong with K lobes, per colour channel c:   I_c(v) = Kd_c + sum_k Ks_kc max(0, v . r_k)^m_k
// (docs/conventions.md). With one lobe: 10 stored values (Kd RGB, Ks RGB, r xyz, m; 9 free, r being unit). m is shared
// by all lobes (as the source method) or one per lobe. phong_model.hpp makes it a ReflectanceModel of parameter maps.
//
// Fitting (fit_phong): non-linear least squares, all observations of a texel at once (3 residuals each), analytic
// derivatives, the bounded Levenberg-Marquardt of bounded_lm.hpp (private to fitting/). Parameters: Kd, Ks >= 0
// (bounds), r_k as (azimuth, zenith) with zenith in [0, pi/2] (so r stays on the upper hemisphere and unit by
// construction), log(m) in [0, log(max_shininess)] (m >= 1; log keeps the steps in m proportional). Initialisation: r_0
// at the brightest observation, m by a coarse search (linear least squares for Kd, Ks at each candidate m); for K > 1
// lobe k starts at the peak of the previous fit's residual.
//
// Fixed lobe directions (PhongFitOptions::fixed_directions): when the lobe directions are known from elsewhere (the
// rig's lights are fixed to the platform and the surface is planar, so every texel's mirror directions follow from a
// few point lights estimated over the whole map: lights.hpp), r_k is held at the given value and only Kd, Ks, m are
// fitted: from sparse view sets a free fit can trade r against Ks and m with no loss in residual, and with r fixed
// Ks and m become identifiable (docs/models.md).
//
// Between the samples (docs/models.md, "Between the samples"): a lobe is a measurement only where the observations can
// identify it. Two rules, both on by default, keep the fit from inventing highlights in the gaps between the views:
//  - support (PhongFitOptions::lobe_support): at least that many observations lie inside each lobe's support cone,
//    where the lobe is >= kLobeSupportLevel of its peak. A lobe narrower than the sampling around it has its shininess
//    capped (phong_support_cap) and is refitted, so its peak is never more than 1 / kLobeSupportLevel times what the
//    observations show of it. Lobes held at fixed_directions are exempt where their width is measured
//    (phong_lobe_width_measured: at least lobe_support observations see them above the noise, and those views see
//    the lobe fall by >= 1 / kLobePeakLevel between them): their direction comes from elsewhere (the lights estimated
//    over the whole map), and with it Ks and m are measured on the lobe's flanks. Where fewer see them, or all at
//    about the same height on the flank, Ks and m are not measured (they trade along what the views saw) and the cap
//    of free lobes applies to them, so their peak too stays within a bounded factor of what the observations show;
//    the shared-lights pass then keeps a refit only within the free fit's bound (phong_refit_within_free_fit);
//  - significance (PhongFitOptions::significant_lobes_only): a lobe is kept only where it lowers the BIC and stands
//    above the fit's noise (phong_lobe_snr >= kLobeDetectionSnr); the lobe count is chosen among 0..K, so a diffuse
//    texel gets no lobe.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/fit_quality.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

struct PhongLobe {
  Vec3d ks = Vec3d::Zero();
  Vec3d direction = Vec3d::UnitZ();  // r_k, unit, upper hemisphere
  double shininess = 1.0;            // m_k (all equal when shared)
};

struct PhongParams {
  Vec3d kd = Vec3d::Zero();
  std::vector<PhongLobe> lobes;

  /// RGB radiance toward unit direction v.
  Vec3d evaluate(const Vec3d& v) const;
};

enum class ResidualMode {
  kAbsolute,  // I_model - I_observed: fits highlights best, lets them dominate
  kRelative,  // (I_model - I_observed) / (I_observed + floor): every sample weighs alike over the dynamic range
};

/// Which least-squares solver minimises the residuals (both see the same parameters, bounds and residuals).
enum class PhongSolver {
  kDirect,  // analytic Jacobian, bounded Levenberg-Marquardt on the normal equations of one texel (the default;
            // docs/models.md compares the two)
  kCeres,   // Ceres, automatic derivatives, one residual block per texel: the reference implementation
};

struct PhongFitOptions {
  int lobes = 1;  // 1..4
  PhongSolver solver = PhongSolver::kDirect;
  bool shared_shininess = true;
  double max_shininess = 10000.0;
  int max_iterations = 100;
  ResidualMode residual = ResidualMode::kAbsolute;
  double relative_floor = 1e-3;  // added to |observed| in kRelative mode
  // Empty: the lobe directions are fitted. Otherwise exactly `lobes` directions (surface frame, unit within 1e-6 --
  // they are renormalised -- with z >= 0): lobe k is held at fixed_directions[k] (initialised there too, with m by
  // the coarse search and Kd, Ks by linear least squares) and only Kd, Ks, m are fitted, by either solver. Not
  // allowed with fit_phong_auto (the lobe count is what it chooses; compare fits by phong_bic instead).
  std::vector<Vec3d> fixed_directions = {};  // (the initialiser keeps designated initialisers warning-free)
  // Observations a lobe needs inside its support cone (>= kLobeSupportLevel of its peak); its shininess is capped to
  // make it so. 0: no cap (a lobe may be as narrow as max_shininess allows, wherever it lies).
  int lobe_support = 2;
  // Lobe count chosen by BIC among 0..lobes (phong:K) or 0..max_lobes (phong:auto); false: always `lobes` lobes
  // (phong:K) or at least one (phong:auto), as before.
  bool significant_lobes_only = true;
  // Each observation's squared residual weighted by the solid angle of its spherical Voronoi cell (voronoi.hpp;
  // relative to the mean, capped at 8x): the fit then minimises the error integrated over the hemisphere, as the
  // evaluation measures it, rather than over the views, which weighs where views are dense. For non-uniform view
  // sets (adaptive:N, dense-around); on a uniform set the weights are about 1 (docs/sampling.md, "adaptive").
  bool solid_angle_weights = false;

  bool is_valid(std::string* why) const;
  /// Every field as text (model_options.hpp): equal text, equal options. A new field goes here too.
  std::string fingerprint() const;
};

/// The level that bounds a lobe's support cone: cos(theta)^m >= kLobeSupportLevel.
inline constexpr double kLobeSupportLevel = 0.1;
/// The level the nearest observation must reach, so that a lobe's peak is never more than 1 / kLobePeakLevel times
/// what was seen of it (a lobe beyond the last ring of views, at the horizon, is the case this rule is for).
inline constexpr double kLobePeakLevel = 0.5;

/// The largest shininess for which a lobe at unit `direction` has at least `support` observations of `obs` inside its
/// support cone: ln(kLobeSupportLevel) / ln(c), c the support-th largest cosine between `direction` and the
/// observation directions. +inf when support <= 0 or that observation lies on the lobe's axis; 1 (the smallest m) when
/// fewer than `support` observations lie in front of the lobe (c <= 0).
double phong_support_cap(const TexelObservations& obs, const Vec3d& direction, int support);

struct PhongFit {
  PhongParams params;
  FitQuality quality;
  double cost = 0.0;  // 0.5 * sum of squared (weighted) residuals
  bool converged = false;
  // Lobes whose shininess sits at the support cap (PhongFitOptions::lobe_support): the sampling bounds their width,
  // the surface may be glossier there than the map says.
  int capped_lobes = 0;
};

/// Fits one texel with `options.lobes` lobes (0..lobes with significant_lobes_only, chosen by BIC). Needs at least
/// (parameter count / 3 + 1) observations; otherwise returns a fit with Kd the mean and no lobe, converged = false.
PhongFit fit_phong(const TexelObservations& obs, const PhongFitOptions& options);

/// The signal-to-noise ratio at which a fitted lobe counts as detected (significant_lobes_only): what the lobe adds
/// at the observed directions must stand this far above the fit's residual noise (phong_lobe_snr). The BIC alone lets
/// a free lobe, which searches the whole hemisphere for the pair of samples it fits best, buy its parameters with a
/// few noisy samples: on 8-bit observations of a Lambertian patch, 6 seeds in 10 left such lobes, up to 11 codes bright
/// between the views (tests/fitting/test_between_samples.cpp, docs/models.md).
inline constexpr double kLobeDetectionSnr = 20.0;

/// A lobe's signal-to-noise ratio over `obs`: the root sum of squares of its contribution (ks cos^m, RGB) at the
/// observed directions, over `noise_rms` (the RMS of one residual of the fit, per channel and observation). +inf for
/// noise_rms 0.
double phong_lobe_snr(const TexelObservations& obs, const PhongLobe& lobe, double noise_rms);

/// The level, in units of the fit's residual noise, at which an observation sees a lobe (phong_lobe_width_measured).
inline constexpr double kLobeSeenSnr = 3.0;

/// Whether the observations of `obs` measure the width of `lobe` (held at a fixed direction): at least `support` of
/// them see it (its contribution there, the largest channel of ks cos^m, is at least kLobeSeenSnr x `noise_rms`, the
/// RMS of one residual of the fit) and those that see it show it falling by at
/// least 1 / kLobePeakLevel between them (the brightest sees >= twice what the faintest does), so Ks and m are read
/// off its flank. Views that see it at about the same cosine leave Ks and m trading along what they saw, and the peak
/// unbounded: fit_phong caps such a lobe as a free lobe (phong_support_cap).
bool phong_lobe_width_measured(const TexelObservations& obs, const PhongLobe& lobe, double noise_rms, int support);

/// How far a refit with fixed lobe directions may rise above the texel's free fit anywhere on the hemisphere
/// (phong_refit_within_free_fit): the peak rule's factor.
inline constexpr double kRefitExcessFactor = 1.0 / kLobePeakLevel;
/// Directions at which phong_refit_within_free_fit compares the two fits: a Fibonacci spiral uniform in solid angle
/// over the whole upper hemisphere (as the evaluation measures; ~0.013 sr each, ~6 deg apart), plus the refit's own
/// lobe axes, where it peaks.
inline constexpr int kRefitCheckDirections = 500;
/// The absolute slack of that comparison, as a fraction of the texel's mean observed radiance (all observations and
/// channels): below it a difference is the noise of the observations, not a highlight, and must not decide.
inline constexpr double kRefitCheckFloor = 0.05;

/// Whether a refit of `obs` with its lobes held at fixed directions (the shared-lights pass) may replace the texel's
/// free fit: in every colour channel, at every direction of the check (kRefitCheckDirections and the refit's lobe
/// axes), refit <= kRefitExcessFactor x free + kRefitCheckFloor x the mean observed radiance.
/// Why: the BIC that chooses between the two sees only the observed directions. On sparse view sets a lobe held at a
/// light's mirror direction a few degrees off the texel's own lobe reproduces the far flank the views see with a
/// narrow lobe whose peak, between the views, nothing constrains; phong_lobe_width_measured exempts it from the cap
/// because the views that see it see it fall (lights2 adaptive:30: Ks 4e5 at m 930 on brushed metal, the map's mean
/// relative RMS 53; docs/models.md, "Sparse views and shared lights"). The free fit's lobes are always capped
/// (phong_support_cap), so it is the reference: a refit that claims more than the peak rule's factor above it
/// anywhere is a guess where no observation constrains it, and the texel keeps its free fit.
bool phong_refit_within_free_fit(const PhongParams& refit, const PhongParams& free, const TexelObservations& obs);

/// Number of free parameters of a K-lobe model: Kd (3), per lobe Ks (3) + direction (2 for a unit vector, none when
/// the directions are fixed), m (1 shared or K): 9 for one lobe, 7 with its direction fixed, 3 with no lobe.
int phong_parameter_count(int lobes, bool shared_shininess, bool fixed_directions = false);

/// Bayesian information criterion of a fit with `rss` (sum of squared residuals, as minimised) over n residuals
/// and p parameters: n ln(RSS / n) + p ln n. `rss` is floored at n (1e-6 rms_observed)^2: the observations are
/// float32 and far noisier than that, so smaller differences are round-off and must not buy lobes.
double phong_bic(double rss, int residuals, int parameters, double rms_observed);

/// phong:auto: fits K = 1, 2, ... max_lobes lobes (each starting from the previous fit, as fit_phong) and keeps
/// adding a lobe while the BIC (phong_bic, n = 3 x observations) improves, starting from no lobe (from one lobe
/// when significant_lobes_only is false). `options.lobes` is ignored; the returned params hold the chosen number of
/// lobes.
/// `options.fixed_directions` must be empty (VDRIG_CHECK): fit fixed-direction models with fit_phong.
PhongFit fit_phong_auto(const TexelObservations& obs, const PhongFitOptions& options, int max_lobes = 4);

}  // namespace vdrig::fitting
