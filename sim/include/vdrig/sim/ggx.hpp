// The GGX (Trowbridge-Reitz) microfacet BRDF of the simulator's GGX materials, in a local shading frame: x the
// tangent (the surface's x axis projected onto the tangent plane), y = n x t, z the shading normal n. Directions are
// unit vectors pointing away from the surface. alpha_x, alpha_y are the roughnesses along x and y (equal:
// isotropic); they must be > 0.
//
//   D(h)      = 1 / (pi ax ay ((hx/ax)^2 + (hy/ay)^2 + hz^2)^2)      (normalised: integral of D(h) hz dh = 1)
//   Lambda(w) = (sqrt(1 + (ax^2 wx^2 + ay^2 wy^2) / wz^2) - 1) / 2
//   G2(l, v)  = 1 / (1 + Lambda(l) + Lambda(v))                      (height-correlated Smith)
//   F(v . h)  = f0 + (1 - f0) (1 - v . h)^5                          (Schlick)
//   f(l, v)   = D(h) G2(l, v) F(v . h) / (4 lz vz),  h = (l + v) / |l + v|
// f is zero when l or v is at or below the shading horizon.
#pragma once

#include "vdrig/core/geometry.hpp"

namespace vdrig::sim {

/// D(h) for a unit half vector h in the local frame (0 for hz <= 0).
double ggx_distribution(const Vec3d& h_local, double alpha_x, double alpha_y);
/// Smith's Lambda(w) for a unit direction w in the local frame (wz > 0).
double ggx_lambda(const Vec3d& w_local, double alpha_x, double alpha_y);
/// f(l, v) per RGB channel for unit l (to the light) and v (to the viewer) in the local frame.
Vec3d ggx_brdf(const Vec3d& l_local, const Vec3d& v_local, double alpha_x, double alpha_y, const Vec3d& f0);
/// The local frame's axes (rows: tangent, bitangent, normal) for a unit shading normal n: the tangent is the
/// surface x axis projected onto the plane normal to n.
Mat3d ggx_local_frame(const Vec3d& normal);

}  // namespace vdrig::sim
