// Scenes of the simulated rig: a planar surface in the surface frame (z = 0, normal +z, mm) made of rectangular
// patches of Phong-form materials, lit by lights fixed to the platform. Every scene exposes its ground truth: the
// radiance leaving any surface point in any direction, and the per-texel model parameters where the material is
// of the model's form.
//
// Radiance of a point p toward unit direction v (surface frame), for each light with intensity I at position P:
//     E = I cos(theta_i) / d^2            (irradiance, d = |P - p|, theta_i between the normal and P - p)
//     L(v) = E (kd + ks max(0, v . r)^m)  (r the mirror of the light direction about the normal)
// so a Lambertian patch has L = kd I cos(theta_i) / d^2 in every direction, and under one point light a texel is
// exactly the design notes' modified Phong I(v) = Kd + Ks (v . r)^m with Kd = E kd, Ks = E ks.
// Colours are RGB (index 0 = R). Radiance is relative: a light of intensity I at distance d lights a white
// Lambertian surface facing it to I / d^2.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"

namespace vdrig::sim {

struct Material {
  std::string name;
  Vec3d kd = Vec3d::Zero();  // diffuse albedo-like factor per RGB channel
  Vec3d ks = Vec3d::Zero();  // specular factor per RGB channel
  double shininess = 1.0;    // Phong exponent m (>= 1)
};

/// An axis-aligned rectangle of the surface, [x0, x1] x [y0, y1] in mm, with one material.
struct Patch {
  double x0_mm, y0_mm, x1_mm, y1_mm;
  int material = 0;  // index into Scene::materials
};

struct PointLight {
  Vec3d position_mm = Vec3d::Zero();  // surface frame (the light is fixed to the platform)
  Vec3d intensity = Vec3d::Ones();    // RGB
};

/// Per-texel truth for a texel whose radiance is exactly one Phong lobe (one point light, Phong-form material).
struct PhongTruth {
  Vec3d kd, ks;       // model Kd, Ks (already multiplied by the irradiance)
  Vec3d mirror_dir;   // r
  double shininess;   // m
};

struct Scene {
  std::string name;
  double width_mm = 1000.0;
  double height_mm = 1000.0;
  std::vector<Material> materials;  // materials[0] is the background of the whole surface
  std::vector<Patch> patches;       // later patches cover earlier ones
  std::vector<PointLight> lights;
  Vec3d ambient = Vec3d::Zero();    // constant radiance added everywhere (kd-weighted)

  /// Index of the material at surface point (x, y), or -1 outside the surface.
  int material_at(double x_mm, double y_mm) const;
  /// Radiance leaving point p (z = 0) toward unit direction `to_viewer` (surface frame). Zero outside the surface
  /// or below the horizon.
  Vec3d radiance(const Vec3d& p_mm, const Vec3d& to_viewer) const;
  /// Ground-truth Phong parameters at p when the scene has exactly one point light and no ambient.
  std::optional<PhongTruth> phong_truth(const Vec3d& p_mm) const;

  bool is_valid(std::string* why) const;
};

/// Builds a scene by name: "patchwork" (default demo surface), "bands" (eight shininess bands), "lights2" (two point
/// lights of different strength). Unknown names are kInvalidArgument listing the known ones.
Result<Scene> make_scene(const std::string& name);
std::vector<std::string> scene_names();

}  // namespace vdrig::sim
