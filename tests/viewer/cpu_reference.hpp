// What the viewer's shader computes, on the CPU (surface_renderer.hpp): a pixel's ray meets the surface plane at p,
// and the models of the four nearest texels, each evaluated toward the camera from its own centre, are blended
// bilinearly. The tests compare GL renders with it pixel by pixel.
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>

#include "vdrig/core/camera.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::viewer::test {

/// Where the ray through pixel (x, y) (its centre) meets the surface plane; nullopt when it points away.
inline std::optional<Vec3d> pixel_surface_point(const CameraModel& camera, const ViewPose& pose, int x, int y) {
  const Vec3d ray = pose.R.transpose() * camera.pixel_ray(Vec2d(x, y));
  const Vec3d c = pose.camera_centre();
  if (std::abs(ray.z()) < 1e-12 || -c.z() / ray.z() <= 0) return std::nullopt;
  return c + (-c.z() / ray.z()) * ray;
}

/// RGB radiance the shader gives one sub-sample at surface point p seen from camera centre C.
inline Vec3d expected_radiance(const fitting::ParameterMap& map, const Vec3d& p, const Vec3d& C) {
  const int S = map.texels_s(), T = map.texels_t();
  const double W = map.width_mm(), H = map.height_mm();
  const double sx = (p.x() + 0.5 * W) / W * S - 0.5, sy = (p.y() + 0.5 * H) / H * T - 0.5;
  const int s0 = static_cast<int>(std::floor(sx)), t0 = static_cast<int>(std::floor(sy));
  const double fx = sx - s0, fy = sy - t0;
  Vec3d sum = Vec3d::Zero();
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const int s = std::clamp(s0 + i, 0, S - 1), t = std::clamp(t0 + j, 0, T - 1);
      const Vec3d v = (C - texel_centre_mm(s, t, S, T, W, H)).normalized();
      sum += (i ? fx : 1 - fx) * (j ? fy : 1 - fy) * map.evaluate(s, t, v);
    }
  return sum;
}

}  // namespace vdrig::viewer::test
