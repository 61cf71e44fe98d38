// Scenes of the simulated rig: a planar surface in the surface frame (z = 0, geometric normal +z, mm) made of
// rectangular patches of Phong-form or GGX materials and round markers, lit by lights fixed to the platform. Every
// scene exposes its ground truth: the radiance leaving any surface point in any direction, and the per-texel model
// parameters where the material is of the model's form.
//
// Radiance of a point p toward unit direction v (surface frame), with n the shading normal at p (+z, or the
// material's deterministic bump pattern), for each point light with intensity I at position P:
//     E = I cos(theta_i) / d^2            (irradiance, d = |P - p|, cos(theta_i) = n . (P - p) / d)
//     L(v) = E (kd + ks max(0, v . r)^m)  (r the mirror of the light direction about n)
// so a Lambertian patch has L = kd I cos(theta_i) / d^2 in every direction, and under one point light a texel is
// exactly the modified Phong I(v) = Kd + Ks (v . r)^m with Kd = E kd, Ks = E ks. A GGX material replaces the
// Phong lobe by pi times the microfacet BRDF (sim/ggx.hpp): L(v) = E (kd + pi f_ggx(l, v)), so that kd and the GGX
// lobe use the same scale (a white Lambertian kd = 1 and a lossless mirror both reflect all of E). An area light is a
// fixed stratified grid of point lights (deterministic). Ambient adds kd * ambient. Radiance is zero below the
// geometric horizon (v.z <= 0) and outside the surface.
// Colours are RGB (index 0 = R). Radiance is relative: a light of intensity I at distance d lights a white
// Lambertian surface facing it to I / d^2.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace cv {
class Mat;
}

namespace vdrig::sim {

/// The specular lobe of a material.
enum class MaterialKind {
  kPhong,  // ks max(0, v . r)^shininess
  kGgx,    // pi f_ggx: Trowbridge-Reitz distribution, height-correlated Smith shadowing, Schlick Fresnel (ggx.hpp)
};

struct Material {
  std::string name;
  Vec3d kd = Vec3d::Zero();  // diffuse albedo-like factor per RGB channel
  Vec3d ks = Vec3d::Zero();  // specular factor per RGB channel
  double shininess = 1.0;    // Phong exponent m (>= 1)
  MaterialKind kind = MaterialKind::kPhong;
  // GGX lobe (kind kGgx; ks and shininess are not used then). roughness is the GGX alpha along the surface's x axis
  // (projected onto the tangent plane), roughness_y along y; roughness_y = 0 means isotropic (= roughness).
  double roughness = 0.3;
  double roughness_y = 0.0;
  Vec3d f0 = Vec3d::Constant(0.04);  // Fresnel reflectance at normal incidence per RGB channel, in [0, 1]
  // Normal perturbation (a "metal-like", brushed/hammered look): the shading normal is that of a height field made
  // of a few fixed sinusoids whose largest slope is about bump_slope (radians ~ slope for small values); 0 = flat.
  double bump_slope = 0.0;
  double bump_period_mm = 6.0;
  // Printed, text-like pattern: where the procedural glyphs have ink, kd becomes ink_kd (ks unchanged). Glyphs are
  // 3 x 5 cells of print_cell_mm, advancing 4 cells, lines 8 cells apart.
  bool printed = false;
  Vec3d ink_kd = Vec3d::Constant(0.05);
  double print_cell_mm = 1.0;
  // kd from an image (scene files' "kd_image"): when set, kd at a point is the image's linear RGB (CV_32FC3, R G B
  // order) bilinearly sampled, the image stretched over the rectangle of the patch the point lies in (the whole
  // surface for the background, the disc's bounding square for a marker); image row 0 lies at the rectangle's
  // smallest y, as in a parameter map. kd_image is the file it came from (absolute), kept for saving.
  std::string kd_image = {};
  std::shared_ptr<const cv::Mat> kd_texture = {};
};

/// An axis-aligned rectangle of the surface, [x0, x1] x [y0, y1] in mm, with one material.
struct Patch {
  double x0_mm, y0_mm, x1_mm, y1_mm;
  int material = 0;  // index into Scene::materials
};

/// A filled disc of the surface (registration markers), painted over the patches.
struct Disc {
  Vec2d centre_mm = Vec2d::Zero();
  double radius_mm = 30.0;
  int material = 0;
};

struct PointLight {
  Vec3d position_mm = Vec3d::Zero();  // surface frame (the light is fixed to the platform)
  Vec3d intensity = Vec3d::Ones();    // RGB
};

/// A rectangular Lambertian emitter: centre, two edge vectors (full lengths), emitting on the side of
/// edge_u x edge_v with radiant intensity `intensity * cos(angle from that normal)` in total. Rendered as a fixed
/// samples_per_axis^2 stratified grid of point lights (cell centres), so rendering stays deterministic.
struct AreaLight {
  Vec3d centre_mm = Vec3d::Zero();
  Vec3d edge_u_mm = Vec3d::UnitX();
  Vec3d edge_v_mm = -Vec3d::UnitY();
  Vec3d intensity = Vec3d::Ones();  // RGB, of the whole rectangle along its normal
  int samples_per_axis = 4;

  Vec3d normal() const { return edge_u_mm.cross(edge_v_mm).normalized(); }
};

/// Per-texel truth for a texel whose radiance is exactly one Phong lobe (one point light, Phong-form material).
struct PhongTruth {
  Vec3d kd, ks;      // model Kd, Ks (already multiplied by the irradiance)
  Vec3d mirror_dir;  // r
  double shininess;  // m
};

/// What the surface is at one point: material index, shading normal (unit, surface frame) and local kd.
struct SurfacePoint {
  int material = -1;
  Vec3d normal = Vec3d::UnitZ();
  Vec3d kd = Vec3d::Zero();
};

struct Scene {
  std::string name;
  double width_mm = 1000.0;
  double height_mm = 1000.0;
  std::vector<Material> materials;  // materials[0] is the background of the whole surface
  std::vector<Patch> patches;       // later patches cover earlier ones
  std::vector<Disc> markers;        // registration markers, painted over every patch
  std::vector<PointLight> lights;
  std::vector<AreaLight> area_lights;
  Vec3d ambient = Vec3d::Zero();  // constant irradiance-like term: adds kd * ambient everywhere

  /// Index of the material at surface point (x, y), or -1 outside the surface.
  int material_at(double x_mm, double y_mm) const;
  /// Material, shading normal and kd at (x, y); material -1 outside the surface.
  SurfacePoint surface_at(double x_mm, double y_mm) const;
  /// Radiance leaving point p (z = 0) toward unit direction `to_viewer` (surface frame). Zero outside the surface
  /// or below the horizon.
  Vec3d radiance(const Vec3d& p_mm, const Vec3d& to_viewer) const;
  /// Ground-truth Phong parameters at p when the scene has exactly one point light, no area light and no ambient
  /// (nullopt otherwise, or outside the surface, on a GGX material, or when the light is below p's shading horizon).
  /// Bumped and printed materials are still of Phong form: the truth uses the local normal and kd.
  std::optional<PhongTruth> phong_truth(const Vec3d& p_mm) const;
  /// Centres of the registration markers (surface frame, mm, z = 0), in the order of `markers`:
  /// (-x, -y), (+x, -y), (+x, +y), (-x, +y) corners for the built-in scenes.
  std::vector<Vec3d> marker_centres_mm() const;

  bool is_valid(std::string* why) const;
};

/// Builds a built-in scene by name, or loads a scene file (scene_file.hpp) when `name` ends in ".json". The
/// built-in scenes are the files of sim/scenes/, compiled into the library (an installed vdrig needs no data folder):
///  - "patchwork": paper background, red cloth (Lambertian), glossy plastic, a metal-like bumped patch, a printed
///    text-like patch, a band of eight shininess values (m = 2 .. 500) and four black corner markers; one point
///    light at (1500, 1500, 2000) mm;
///  - "bands": eight vertical bands of one colour with m = 2 .. 500 (the shininess test surface), same light;
///  - "lights2": patchwork lit by two point lights of different strength (two highlights);
///  - "softbox": patchwork lit by a 400 x 400 mm area light where the point light was, plus a little ambient.
/// Every built-in scene has the four corner markers (30 mm radius, centred 50 mm in from each corner, albedo 0.02).
/// Unknown names are kInvalidArgument listing the known ones; file errors are those of load_scene_file().
Result<Scene> make_scene(const std::string& name);
std::vector<std::string> scene_names();

/// Shininess of band k (0..7) of the band surfaces: geometric from 2 to 500.
double band_shininess(int k);

}  // namespace vdrig::sim
