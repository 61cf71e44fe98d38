// Median-cut light extraction (Debevec 2005, "A median cut algorithm for light probe sampling"): the probe's
// lat-long map is split recursively into 2^k regions of (nearly) equal energy and each region becomes one
// directional light carrying the region's whole power, placed at its energy centroid.
//
// Energy of a pixel = luminance(L) x the pixel's solid angle (row solid angle, docs/conventions.md), so that the polar
// rows, over-represented in a lat-long map, weigh what they subtend. A region is cut across its longer side,
// the width measured as columns x sin(zenith of the region's middle row) (= cos latitude; rows and columns span
// the same angle when W = 2 H), at the pixel boundary that best halves its energy (summed-area table, O(1) per
// candidate). Cuts fall on pixel boundaries, so a region holding a very bright pixel (the sun) cannot always be
// halved: its energy stays above the mean. Regions of a single pixel cannot be split; when a round meets some, the
// most energetic splittable regions are split instead so that exactly 2^k lights come out (a map of fewer than
// 2^k pixels gives one light per pixel).
#pragma once

#include <vector>

#include "vdrig/probe/probe.hpp"

namespace vdrig::probe {

/// Pixel rectangle [x0, x1) x [y0, y1) of the lat-long map and its energy (luminance x solid angle).
struct MedianCutRegion {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double energy = 0;
};

/// A light at infinity: irradiance on a surface of normal n is power * max(0, n . direction).
struct DirectionalLight {
  Vec3d direction = Vec3d::UnitZ();  // unit, probe frame, pointing toward the light
  Rgb power = Rgb::Zero();           // integral of L over the region's solid angle (L x sr)
  double solid_angle_sr = 0;         // the region's solid angle; power / solid_angle_sr is its mean radiance
  MedianCutRegion region;
  // The light's spread, for the methods that model it (hybrid:N, soft:N; SoftLights::irradiance): the cosine of the
  // half-angle of the uniform cap whose mean direction is as long as the region's luminance-weighted mean direction
  // (cap_lights.hpp). 1 = a point. median_cut fills it; irradiance_from_lights ignores it (plain median cut stays
  // Debevec's).
  double cap_cos_half_angle = 1;
};

/// True for 1, 2, 4, ...
constexpr bool is_power_of_two(int n) { return n > 0 && (n & (n - 1)) == 0; }

/// `count` lights (a power of two; VDRIG_CHECKed) from the probe's map (fewer only if the map has fewer pixels).
/// The lights' powers sum to total_power(probe) up to rounding.
std::vector<DirectionalLight> median_cut(const Probe& probe, int count);

/// The same for any count >= 1 (VDRIG_CHECKed): floor(log2 count) rounds, then the most energetic regions are split
/// one at a time until `count`. For a power of two it is median_cut exactly.
std::vector<DirectionalLight> median_cut_any_count(const Probe& probe, int count);

/// Irradiance at normal n from a set of directional lights: sum of power_k max(0, n . d_k).
Rgb irradiance_from_lights(const std::vector<DirectionalLight>& lights, const Vec3d& normal);

}  // namespace vdrig::probe
