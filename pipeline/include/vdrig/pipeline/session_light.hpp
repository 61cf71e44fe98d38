// The session's light for a BRDF fit (docs/models.md, "The light"): given on the command line, recorded by the session
// (its rig config's lamp, rig/lamp.hpp: a measured position on a real rig, the scene's point light on the simulator),
// or estimated from the images by the Phong fit's shared-lights pass (fitting/lights.hpp) with its uncertainty.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "vdrig/capture/session.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/obsmap_file.hpp"

namespace vdrig::pipeline {

/// A light and where it came from (the fit logs it and writes it into the map's header, vdrig.session_light_source).
struct ResolvedSessionLight {
  fitting::SessionLight light;
  std::string source;
};

/// The light at `position_m` (surface frame, metres) whose irradiance at the sample's centre is 1: the gauge when
/// the intensity is not known. Radiance is relative (docs/conventions.md), and the intensity multiplies the albedo and
/// f0 of a fit alike, so only the product is measured; with this gauge a texel's albedo is its radiance over the
/// centre's irradiance (the simulator's scenes are built so: `bands`, `patchwork` have E = 1 there).
fitting::SessionLight unit_centre_irradiance_light(const Vec3d& position_m);

/// The light the session recorded: its rig config's lamp ("light": "position_mm", ...), in the surface frame (a
/// platter-frame position through the calibrated geometry of SESSION/calib/views.json, else the config's stated one),
/// with its intensity (mm units, scaled to SessionLight's metres) or, when none is stated, the unit-centre gauge.
/// nullopt when the session recorded none; kInvalidArgument when its lamp is malformed.
Result<std::optional<ResolvedSessionLight>> recorded_session_light(const capture::Session& session);

/// A point light estimated from the observations.
struct LightEstimate {
  fitting::EstimatedLight light;            // surface frame, mm: the Phong lobes' light, refined by ggx:iso's residuals
  Mat3d covariance_mm2 = Mat3d::Zero();     // its position's, from the residuals' curvature (a lower bound)
  int rays = 0;                             // texel lobes offered to the estimate
  fitting::SessionLight session_light;      // in metres, with the unit-centre gauge
  Vec3d phong_position_mm = Vec3d::Zero();  // the Phong lobes' estimate, before the ggx:iso refinement
  Mat3d phong_covariance_mm2 = Mat3d::Zero();     // its covariance (light_uncertainty.hpp)
  int refine_evaluations = 0, refine_texels = 0;  // ggx:iso fits the refinement made, texels each
  /// "(x, y, z) mm +- (sx, sy, sz) mm, distance D +- sD mm from the centre, N of M texel lobes, rms A deg".
  std::string describe() const;
  /// The 1-sigma error of the distance from the sample's centre (mm), from the covariance.
  double distance_sigma_mm() const;
};

/// Fits phong:1 to every texel (the fit views only: `held_out` left out), turns each texel's lobe into a ray toward
/// its light (lights.hpp) and estimates the point light that most rays meet, with its covariance; then moves it to
/// where ggx:iso fits of a subsample of texels (at most 16 x 16) leave the least residual (session_light.cpp has why
/// and how), with the covariance of that minimum. kInvalidArgument
/// when no point light gathers enough rays (a matte sample, too few views) or it lies at infinity (no position), with
/// the reason and what to give instead (--light X,Y,Z).
Result<LightEstimate> estimate_session_light(const fitting::ObsMapReader& obs, const std::vector<int>& held_out,
                                             int threads = 0);
Result<LightEstimate> estimate_session_light(const fitting::ObservationMap& obs, const std::vector<int>& held_out,
                                             int threads = 0);

}  // namespace vdrig::pipeline
