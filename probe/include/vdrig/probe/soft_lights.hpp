// Soft lights: directional lights that do not jump between frames, for lighting a moving object from a probe that
// changes every frame (docs/probe.md, "The moving object").
//
// Median-cut regions are cut at pixel boundaries chosen by comparisons, so a small change of the map can move a cut
// and a light's direction and power jump. Here every quantity is a continuous function of the map:
//  - SH-9 of the whole map carries bands 0..2 of the irradiance exactly;
//  - `count` lights sit at fixed Fibonacci directions c_k; light k takes the share w_k(w) = exp(kappa (w . c_k - 1))
//    / sum_j exp(kappa (w . c_j - 1)) of every pixel (a smooth partition of unity), carries power sum L dw w_k and
//    points at the luminance centroid of its share;
//  - each light adds only what SH-9 cannot hold: power x (K(t) - its SH-9 band limit), t = n . d, K the clamped
//    cosine seen through the uniform cap with the share's mean direction length (cap_lights.hpp; for a point
//    K = max(0, t) and the band limit 1/4 + t/2 + 5 (3 t^2 - 1) / 32), so E = sh9_irradiance + sum of those.
// The lights are directional lights (DirectionalLight, region unset, cap_cos_half_angle set) for a renderer that adds
// the SH-9 term. hybrid_lights builds the same structure from median-cut lights (irradiance_map.hpp, hybrid:N).
#pragma once

#include <vector>

#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/sh_irradiance.hpp"

namespace vdrig::probe {

struct SoftLightOptions {
  int count = 64;       // lights, >= 1
  double kappa = 40.0;  // sharpness of the shares (> 0): larger keeps a light's share nearer its centre direction
  // Spread each light over the cap of its share's mean direction length (cap_lights.hpp) instead of a point.
  bool cap_spread = true;
};

struct SoftLights {
  Sh9 sh9;
  std::vector<DirectionalLight> lights;

  /// E(n) = sh9_irradiance(sh9, n) + sum_k power_k (K_k(n . d_k) - its SH-9 band limit), K_k the clamped cosine
  /// seen through light k's cap (cap_clamped_cosine, cap_sh9_clamped_cosine; max(0, t) and sh9_clamped_cosine for a
  /// point light, cap_cos_half_angle = 1).
  Rgb irradiance(const Vec3d& normal) const;
};

/// The SH-9 band limit of the clamped cosine max(0, t) (Funk-Hecke: sum_l A_l (2 l + 1) / (4 pi) P_l(t)).
double sh9_clamped_cosine(double t);

/// Soft lights of a lat-long map. VDRIG_CHECKs count >= 1 and kappa > 0. The powers sum to total_power(probe).
SoftLights soft_lights(const Probe& probe, const SoftLightOptions& options = {});
/// Soft lights of a cube map: the same sums over its texels with their exact solid angles (SH-9 likewise). On a
/// 6 x 16^2 cube 64 lights take ~1 ms; `vdrig probe animate` feeds it the GPU-fused cube shrunk to that.
/// (Both overloads skip a pixel's shares below e^-30 of its largest: below the rounding of the sums.)
SoftLights soft_lights(const CubeMap& cube, const SoftLightOptions& options = {});

/// The lights of hybrid:N (docs/probe.md, "Irradiance maps"): SH-9 of the whole map, which holds bands 0..2 of the
/// irradiance exactly, plus `count` median-cut lights of the whole map (median_cut_any_count) that add only what
/// SH-9 cannot hold, each spread over its region's cap (or a point, cap_spread false). VDRIG_CHECKs count >= 1.
SoftLights hybrid_lights(const Probe& probe, int count, bool cap_spread = true);

}  // namespace vdrig::probe
