// Irradiance maps: E(n) = integral of L(w) max(0, n . w) dw for the normal n of every output pixel or texel, by one
// of four methods (docs/probe.md, "Irradiance maps"):
//  - exact: the sum over every pixel of the source map (IrradianceIntegrator), the reference;
//  - sh9: 9 SH coefficients (sh_irradiance.hpp);
//  - mediancut:N: N median-cut directional lights (median_cut.hpp);
//  - hybrid:N: median cut into K = the smallest power of two >= 8 N regions; the N of highest mean radiance
//    (power / solid angle) become lights, and the map with those regions set to zero is projected onto SH-9. The
//    sharp sources keep their direction; the broad rest costs 9 coefficients instead of K - N lights;
//  - soft:N: SH-9 plus N soft lights (soft_lights.hpp), continuous in the map: the method for a moving object.
// A white furnace (constant L) gives E = pi L for every method within 1 % (test_irradiance_map).
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
  /// The directional lights (mediancut, hybrid, soft; empty otherwise). For soft, each adds only its residual
  /// over SH-9 (SoftLights::irradiance).
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
