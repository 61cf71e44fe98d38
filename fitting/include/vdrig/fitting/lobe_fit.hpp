// Building blocks of a per-texel fit of a lobe model (a base term plus view-dependent lobes, e.g. Phong's Kd and
// Ks max(0, v . r)^m, phong.hpp): how a new lobe is started before the non-linear solve. Phong's fit (fitting/src/
// phong.cpp) is made of them; a new lobe model (Ward, GGX, ...) uses the same instead of copying them.
//
// Starting a lobe: lobe_target gives what the model so far leaves unexplained and the observation where that is
// largest (the new lobe's direction, lobe_start_direction); search_lobe_width then tries each candidate width, fits
// the base and the lobe's scale per colour by fit_two_terms (linear, non-negative), and keeps the best.
#pragma once

#include <array>
#include <functional>
#include <limits>
#include <span>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

/// Linear least squares of o_i = base + scale s_i for one colour channel with base, scale >= 0 (the better of the
/// bounded solutions when the free one is negative). Returns the squared error; s and o have the same size.
double fit_two_terms(std::span<const double> s, std::span<const double> o, double* base, double* scale);

/// What a new lobe must explain.
struct LobeTarget {
  std::array<std::vector<double>, 3> residual;  // per colour channel, per observation: observed - current lobes
  size_t peak = 0;  // the observation whose luminance (R + G + B) exceeds base + current lobes the most (first of ties)
};

/// The target of a new lobe of a texel whose model so far is `base` (RGB, direction-independent) plus
/// `lobes_at(v)`, the current lobes' RGB radiance toward v. Needs at least one observation.
LobeTarget lobe_target(const TexelObservations& obs, const Vec3d& base,
                       const std::function<Vec3d(const Vec3d& v)>& lobes_at);

/// A lobe's starting direction at an observation direction: normalised and lifted to z >= 1e-3 (a lobe direction
/// stays on the upper hemisphere).
Vec3d lobe_start_direction(const Vec3d& observation_direction);

/// The best of the candidate widths of a new lobe.
struct LobeStart {
  Vec3d base = Vec3d::Zero();                               // the refitted base term
  Vec3d scale = Vec3d::Zero();                              // the lobe's scale per colour (Phong: Ks)
  double width = std::numeric_limits<double>::quiet_NaN();  // the winning candidate; NaN when none fitted
  double squared_error = std::numeric_limits<double>::infinity();
};

/// For each width of `widths`, in order, `shape(width, s)` fills s (one value per observation, s already sized) with
/// the lobe's value toward each observation per unit scale; base and scale follow per channel by fit_two_terms
/// against `target.residual`. The width of least squared error (summed over R, G, B) wins, the first on ties.
LobeStart search_lobe_width(const LobeTarget& target, std::span<const double> widths,
                            const std::function<void(double width, std::vector<double>& s)>& shape);

/// first, first * ratio, first * ratio^2, ... up to last (by repeated multiplication; ratio > 1).
std::vector<double> geometric_steps(double first, double last, double ratio);

}  // namespace vdrig::fitting
