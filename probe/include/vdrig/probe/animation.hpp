// Frames of a virtual object moving through the room (`vdrig probe animate`, docs/probe.md "Animation"): a diffuse
// and a glossy sphere on a ground plane, seen by a pinhole camera, lit by the frame's soft lights (soft_lights.hpp,
// SH-9 + directional lights) with shadow maps of the strongest lights on the ground. CPU ray casting (the scene is
// two spheres and a plane); the lighting comes from the GPU-fused cube (probe_gl).
//
// Shading, per pixel (linear radiance, R, G, B):
//  - diffuse sphere: albedo / pi * E(n), E = SoftLights::irradiance (the stable lights; spheres receive no shadows);
//  - glossy sphere: its diffuse part (albedo / pi * E(n)) plus specular * L_env(reflect(v, n)), L_env the frame's
//    fused cube shrunk (its 32^2 faces blur the mirror image into a gloss), bilinear (radiance_at);
//  - ground (z = ground_z_mm, inside the room's floor rectangle): albedo / pi * (E(+z) - sum over the shadowing
//    lights k of (1 - V_k) power_k max(0, d_k . z)), V_k the light's shadow-map visibility with 3 x 3 PCF. The
//    whole light leaves where it is shadowed (its SH-9 share included), so a shadow removes exactly that light;
//  - background: black.
// Shadow map of light k: an orthographic depth map looking along -d_k over a square around both spheres, each texel
// the distance along -d_k to the first sphere (ray cast analytically), compared with the ground point's depth with a
// bias of one texel.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/soft_lights.hpp"

namespace vdrig::probe {

/// Pinhole camera: image up is the world +z projected; square pixels, principal point at the image centre.
struct SceneCamera {
  Vec3d position_mm = Vec3d(0, -4000, 2000);
  Vec3d look_at_mm = Vec3d::Zero();
  double fov_deg = 50;  // horizontal field of view
  int width = 640, height = 360;

  /// False with the reason for a non-positive size, fov outside (1, 170) deg, a look-at at the position or a view
  /// along +-z (no image up).
  bool is_valid(std::string* why = nullptr) const;
  /// Unit ray through pixel (x, y) (OpenCV pixel centres at integers, row 0 at the top).
  Vec3d ray(double x, double y) const;
  /// Pixel coordinates of a world point (false when behind the camera).
  bool project(const Vec3d& p_mm, double* x, double* y) const;
  /// Focal length in pixels (width / 2 / tan(fov / 2)).
  double focal_px() const;
};

/// The camera `vdrig probe animate` frames a path with: from the -y side, 35 degrees above the horizontal, looking at
/// the middle of the path's bounding box (at a quarter of its height), far enough for the box and spheres of
/// `sphere_radius_mm` to fit the horizontal field of view `fov_deg`. `positions_mm` must not be empty.
SceneCamera frame_path(const std::vector<Vec3d>& positions_mm, double sphere_radius_mm, double fov_deg);

struct AnimationScene {
  double sphere_radius_mm = 150;
  Rgb diffuse_albedo = Rgb(0.75, 0.5, 0.3);
  Rgb glossy_albedo = Rgb(0.1, 0.15, 0.3);  // the glossy sphere's diffuse part
  double glossy_specular = 0.6;             // weight of the reflected environment
  double ground_z_mm = 0;
  Vec3d ground_min_mm = Vec3d(-2000, -1500, 0), ground_max_mm = Vec3d(2000, 1500, 0);  // x, y extent of the plane
  Rgb ground_albedo = Rgb(0.5, 0.5, 0.5);
  int shadow_lights = 4;      // the strongest lights (luminance of power) cast shadows
  int shadow_map_size = 256;  // texels a side
  int samples_per_axis = 2;   // antialiasing: samples^2 rays per pixel

  bool is_valid(std::string* why = nullptr) const;
};

/// What lights one frame.
struct FrameLighting {
  SoftLights soft;      // in the world frame (the fused cube is world-aligned)
  CubeMap environment;  // the fused cube (shrunk), for the glossy reflection
};

/// Indices of the `count` lights of largest luminance power, strongest first.
std::vector<int> strongest_lights(const std::vector<DirectionalLight>& lights, int count);

/// Linear radiance (CV_32FC3, B, G, R, camera.width x camera.height) of one frame. VDRIG_CHECKs valid camera and
/// scene.
cv::Mat render_animation_frame(const SceneCamera& camera, const AnimationScene& scene, const Vec3d& diffuse_centre_mm,
                               const Vec3d& glossy_centre_mm, const FrameLighting& lighting);

}  // namespace vdrig::probe
