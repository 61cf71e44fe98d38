// Ground-truth observations for the fitting tests: what the rig sees of a simulated scene's texel, without rendering.
// For each nominal scheme direction the camera is posed as the rig poses it (rig::surface_pose: pan = pi/2 - azimuth,
// tilt = zenith, camera at `distance_mm`), the view direction is the one from the texel to that camera centre (not
// the nominal direction: at a finite distance every texel has its own), and the radiance is the scene's exact one.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "vdrig/capture/schemes.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::fitting::test_support {

/// The directions of a capture scheme (capture/schemes.hpp), e.g. "icosahedron:1" (17 directions).
inline std::vector<Vec3d> scheme_directions(const std::string& spec) {
  auto set = capture::generate(spec);
  EXPECT_TRUE(set) << spec << ": " << (set ? "" : set.error().describe());
  return set ? set->directions : std::vector<Vec3d>{};
}

/// Observations of surface point p (mm) from the rig posed at each nominal direction.
inline TexelObservations observe_texel(const sim::Scene& scene, const Vec3d& p, const std::vector<Vec3d>& nominal,
                                       double distance_mm = 2500.0) {
  rig::RigGeometry geometry;
  geometry.camera_distance_mm = distance_mm;
  TexelObservations obs;
  for (const Vec3d& d : nominal) {
    const SphericalDir s = spherical_from_direction(d);
    const ViewPose pose = rig::surface_pose(geometry, {kPi / 2 - s.azimuth_rad, s.zenith_rad});
    const Vec3d v = pose.view_direction(p);
    obs.direction.push_back(v.cast<float>());
    obs.radiance.push_back(scene.radiance(p, v).cast<float>());
    obs.view.push_back(static_cast<int>(obs.view.size()));
  }
  return obs;
}

/// An S x T observation map over the whole surface, every texel observed as observe_texel does (all valid).
inline ObservationMap observe_map(const sim::Scene& scene, const std::vector<Vec3d>& nominal, int S, int T,
                                  double distance_mm = 2500.0) {
  ObservationMap map({S, T, scene.width_mm, scene.height_mm}, static_cast<int>(nominal.size()));
  for (int t = 0; t < T; ++t)
    for (int s = 0; s < S; ++s) {
      const TexelObservations obs =
          observe_texel(scene, texel_centre_mm(s, t, S, T, scene.width_mm, scene.height_mm), nominal, distance_mm);
      for (size_t v = 0; v < obs.size(); ++v)
        map.set(s, t, static_cast<int>(v), obs.radiance[v], obs.direction[v], kObsValid);
    }
  return map;
}

/// |a - b| / |b|.
inline double rel(double a, double b) { return std::abs(a - b) / std::abs(b); }

/// Worst relative errors of a fit's first lobe against the truth (Kd, Ks over channels; r in degrees).
struct Errors {
  double kd = 0, ks = 0, r_deg = 0, m = 0;
};
inline Errors errors(const PhongFit& fit, const sim::PhongTruth& truth) {
  if (fit.params.lobes.empty()) return {1e9, 1e9, 1e9, 1e9};
  Errors e;
  for (int c = 0; c < 3; ++c) {
    e.kd = std::max(e.kd, rel(fit.params.kd[c], truth.kd[c]));
    e.ks = std::max(e.ks, rel(fit.params.lobes[0].ks[c], truth.ks[c]));
  }
  e.r_deg = rad_to_deg(angle_between(fit.params.lobes[0].direction, truth.mirror_dir));
  e.m = rel(fit.params.lobes[0].shininess, truth.shininess);
  return e;
}

}  // namespace vdrig::fitting::test_support
