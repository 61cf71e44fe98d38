// Point lights estimated from the per-texel Phong lobes of a whole map.
//
// Why: the rig's lights are fixed to the platform and the surface is planar (surface frame, mm, z = 0, geometric
// normal +z; docs/conventions.md), so the mirror direction r of every texel's highlight comes from the same few
// point lights: r(p) = mirror of normalize(L - p) about +z. From sparse view sets (e.g. 17 icosahedron directions,
// ~30 deg apart) a glossy texel's free Phong fit trades r against Ks and m at no cost in residual; the lights,
// estimated from the many texels whose lobes ARE well determined, give each texel its r, and fit_phong with
// PhongFitOptions::fixed_directions then recovers Ks and m.
//
// A LobeRay is one texel's evidence: the line from the texel centre p (surface frame, mm, z = 0) along the direction
// toward the light implied by its fitted mirror direction r, i.e. r mirrored about +z: (-r.x, -r.y, r.z)
// (mirror_direction(r, +z), core/geometry.hpp; the mirror is its own inverse). A point light is where many of these
// lines meet; a very distant light makes them parallel (at_infinity).
//
// estimate_point_lights: RANSAC over pairs of rays (a hypothesis is the closest point of the two lines when it lies in
// front of both origins, or their mean direction when the pair is nearly parallel, i.e. within 2 inlier angles);
// inliers are rays whose angle between toward_light and (hypothesis - origin) (or the hypothesis direction) is below
// inlier_angle_rad; the best hypothesis (largest inlier weight) is refined on its inliers (weighted linear least
// squares point closest to the lines, then Gauss-Newton on the angular errors; inliers recomputed, a few rounds),
// it becomes a light at infinity when the lines do not meet in front of the surface within max_distance_mm or the
// point explains them no better than a direction (BIC); its inliers and the rays within exclusion_angle_rad of it
// are removed and the next light is searched, up to max_lights while a light gathers >= min_inliers rays.
// Rays with a non-positive or non-finite weight, a non-finite origin, a zero / non-finite direction or a direction
// within min_elevation_rad of the surface plane are ignored.
#pragma once

#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

/// One texel's line toward its light: origin_mm the texel centre (surface frame, mm, z = 0), toward_light the
/// direction toward the light (need not be unit; normalised), weight its confidence (> 0; e.g. the lobe's Ks / Kd).
struct LobeRay {
  Vec3d origin_mm = Vec3d::Zero();
  Vec3d toward_light = Vec3d::UnitZ();
  double weight = 1.0;
};

/// The ray of a texel at p_mm whose fitted lobe has mirror direction `mirror_dir` (unit, surface frame).
inline LobeRay lobe_ray(const Vec3d& p_mm, const Vec3d& mirror_dir, double weight = 1.0) {
  return {p_mm, mirror_direction(mirror_dir, Vec3d::UnitZ()), weight};
}

struct EstimatedLight {
  Vec3d position_mm = Vec3d::Zero();  // surface frame; meaningless when at_infinity
  bool at_infinity = false;           // the inliers' lines are parallel to within the data (or meet beyond
                                      // max_distance_mm, or behind the surface): a directional light
  Vec3d direction = Vec3d::UnitZ();   // unit, toward the light: the light's direction when at_infinity, else from
                                      // the inliers' weighted centroid toward position_mm
  int inliers = 0;                    // rays explained by this light
  double rms_angle_rad = 0.0;         // weighted rms angle between the inliers' rays and the light
};

/// The mirror direction r (unit, surface frame) of the light at a texel at p_mm (z = 0, normal +z): the direction
/// toward the light reflected about +z. p_mm must not coincide with a finite light's position.
Vec3d mirror_direction_at(const EstimatedLight& light, const Vec3d& p_mm);

struct LightEstimationOptions {
  int max_lights = 4;                         // >= 1
  double inlier_angle_rad = deg_to_rad(0.5);  // (0, pi/2): angle below which a ray is explained by a light
  // [inlier_angle_rad, pi/2): once a light is found, the rays within this angle of it leave the search for further
  // lights without counting as its inliers: its noise tail and lobes biased toward it (a free glossy fit from sparse
  // views misses r by ~1.4 deg) would otherwise gather into spurious lights beside it. Lights on the platform are
  // tens of degrees apart.
  double exclusion_angle_rad = deg_to_rad(2.0);
  int min_inliers = 8;           // >= 2: fewer rays do not make a light
  int ransac_iterations = 500;   // >= 1, pairs tried per light
  double max_distance_mm = 1e5;  // > 0: a light farther than this from its inliers' centroid is at_infinity
  // [0, pi/2): rays closer than this to the surface plane are ignored. A lobe peaking at the horizon is a grazing rise
  // of the reflectance (Fresnel, a sheen, or grazing views' blur), not a light's mirror image: a light there hardly
  // lights the plane (cos 10 deg = 0.17 of the light overhead), and on Blender's session such lobes gathered into a
  // "light" in the surface plane that outvoted the lamp (docs/models.md, "The light").
  double min_elevation_rad = deg_to_rad(10.0);
  unsigned seed = 1;  // RANSAC's sampling; the result is deterministic for a given seed

  bool is_valid(std::string* why) const;
};

/// Point (or directional) lights explaining the rays, sorted by inlier count (largest first); see the file comment.
/// Invalid options are kInvalidArgument; fewer usable rays than max(2, min_inliers), or no light gathering
/// min_inliers rays, give an empty vector (not an error).
Result<std::vector<EstimatedLight>> estimate_point_lights(const std::vector<LobeRay>& rays,
                                                          const LightEstimationOptions& options);

}  // namespace vdrig::fitting
