// Pixel rays of a posed camera intersected with the surface plane z = 0 (surface frame), shared by the stages that
// mask or shade pixels by where they land on the surface.
#pragma once

#include <cmath>

#include "vdrig/core/camera.hpp"

namespace vdrig::pipeline {

/// Calls fn(x, y, p) for every pixel (x, y) whose ray (OpenCV pixel centre, distortion removed) meets the plane
/// z = 0 in front of the camera, p being that point (mm, surface frame). Rows in order.
template <class Fn>
void for_each_surface_hit(const CameraModel& camera, const ViewPose& pose, Fn&& fn) {
  const Mat3d Rt = pose.R.transpose();
  const Vec3d c = pose.camera_centre();
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const Vec3d ray = Rt * camera.pixel_ray({double(x), double(y)});
      if (std::abs(ray.z()) < 1e-12) continue;
      const double s = -c.z() / ray.z();
      if (s <= 0) continue;
      fn(x, y, Vec3d(c + s * ray));
    }
}

}  // namespace vdrig::pipeline
