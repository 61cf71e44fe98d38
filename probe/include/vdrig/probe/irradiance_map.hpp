// Irradiance maps: E(n) = integral of L(w) max(0, n . w) dw for the normal n of every output pixel or texel, by one
// of four methods (docs/probe.md, "Irradiance maps"):
//  - exact: the sum over every pixel of the source map (IrradianceIntegrator), the reference;
//  - sh9: 9 SH coefficients (sh_irradiance.hpp);
//  - mediancut:N: N median-cut directional lights (median_cut.hpp);
//  - hybrid:N: SH-9 of the whole map plus N median-cut lights of the whole map, each adding only its residual over
//    its SH-9 band limit and spread over its region's cap (hybrid_lights, soft_lights.hpp; cap_lights.hpp). Bands
//    0..2 of E are exact and the lights carry only the rest of the cosine kernel. (Until issue 28 the N brightest of
//    8 N median-cut regions were lights and the rest of the map went to SH-9: the lights then held 11-45 % of the
//    power and SH-9's error on the other 55-89 % dominated, whatever N.)
//  - soft:N: SH-9 plus N soft lights (soft_lights.hpp), continuous in the map: the method for a moving object.
// A white furnace (constant L) gives E = pi L within 0.13 % on average for exact, sh9, mediancut:256 and soft:64,
// 0.4 % for hybrid:64 and 1.0 % for hybrid:16, whose 16 lights are large regions that their caps only approximate
// (test_irradiance_map). On real probes see docs/probe.md.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/probe/soft_lights.hpp"

namespace vdrig::probe {

enum class IrradianceMethod { kExact, kSh9, kMedianCut, kHybrid, kSoft };

struct IrradianceMethodSpec {
  IrradianceMethod method = IrradianceMethod::kExact;
  int light_count = 0;  // N of mediancut:N (a power of two), hybrid:N and soft:N (>= 1); 0 for exact and sh9
};

/// Parses "exact", "sh9", "mediancut:N" (N a power of two), "hybrid:N" or "soft:N" (N >= 1); kInvalidArgument with
/// the reason.
Result<IrradianceMethodSpec> parse_irradiance_method(const std::string& text);
/// The text parse_irradiance_method reads.
std::string to_string(const IrradianceMethodSpec& spec);

/// E(n) of one map by one method, built once, then evaluated per normal (probe frame).
class IrradianceModel {
 public:
  /// From a lat-long map (exact: over its full resolution).
  static IrradianceModel build(const Probe& probe, const IrradianceMethodSpec& spec);
  /// From a cube map: exact and sh9 sum over the texels with their exact solid angles; mediancut, hybrid and soft
  /// work on the cube resampled to a lat-long map of height 2 size (cube_to_latlong).
  static IrradianceModel build(const CubeMap& cube, const IrradianceMethodSpec& spec);

  Rgb irradiance(const Vec3d& normal) const;
  /// The directional lights (mediancut, hybrid, soft; empty otherwise). For hybrid and soft, each adds only its
  /// residual over SH-9 through its cap (SoftLights::irradiance).
  const std::vector<DirectionalLight>& lights() const { return soft_ ? soft_->lights : lights_; }
  /// The SH-9 part (sh9, hybrid, soft).
  const std::optional<Sh9>& sh9() const { return sh9_; }

 private:
  IrradianceModel() = default;
  static IrradianceModel from_latlong_cut(const Probe& probe, const IrradianceMethodSpec& spec);
  std::optional<IrradianceIntegrator> exact_;
  std::optional<Sh9> sh9_;
  std::vector<DirectionalLight> lights_;
  std::optional<SoftLights> soft_;
};

/// A width x width / 2 lat-long map (vdrig layout, pose at the origin) whose pixel holds E at the normal through its
/// centre. VDRIG_CHECKs width even and >= 2.
Probe irradiance_latlong(const IrradianceModel& model, int width);
/// A cube of `size` whose texel holds E at the normal through its centre.
CubeMap irradiance_cube(const IrradianceModel& model, int size);

}  // namespace vdrig::probe
