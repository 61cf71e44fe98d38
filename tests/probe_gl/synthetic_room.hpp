// The synthetic room of bench_probe_temporal, shared by the probe_gl tests and bench_probe_gpu: a 4 x 3 x 2.6 m box
// whose walls emit a known radiance (a colour per wall times a slow gradient, a 0.8 x 0.8 m window of radiance ~28
// on the +x wall, a 0.3 x 0.3 m ceiling lamp of ~170), and probes rendered analytically in it with the proxy depth.
#pragma once

#include <cmath>
#include <vector>

#include "vdrig/probe/fusion.hpp"

namespace vdrig::probe::testing {

inline const ProxyBox kSyntheticRoom{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};

/// Emitted radiance of the wall point x with inward normal n.
inline Rgb room_emitted(const Vec3d& x, const Vec3d& n) {
  if (n.x() < -0.5 && std::abs(x.y()) <= 400 && std::abs(x.z() - 1400) <= 400) return Rgb(30, 28, 24);
  if (n.z() < -0.5 && std::abs(x.x() + 800) <= 150 && std::abs(x.y() - 500) <= 150) return Rgb(180, 170, 150);
  const Rgb wall[3] = {{0.6, 0.45, 0.35}, {0.35, 0.5, 0.6}, {0.8, 0.8, 0.75}};
  const int axis = std::abs(n.x()) > 0.5 ? 0 : (std::abs(n.y()) > 0.5 ? 1 : 2);
  return wall[axis] * (1.0 + 0.3 * std::sin(x.x() / 700.0 + x.y() / 900.0) * std::cos(x.z() / 800.0));
}

/// A height x 2 height probe at `position` (2 x 2 rays per pixel) with its proxy depth.
inline Probe render_room_probe(const Vec3d& position, int height) {
  Probe p = make_probe(height);
  p.position_mm = position;
  const int W = p.width(), H = p.height(), ss = 2;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      Rgb sum = Rgb::Zero();
      for (int b = 0; b < ss; ++b)
        for (int a = 0; a < ss; ++a) {
          const ProxyHit hit = intersect_from_inside(
              kSyntheticRoom, position, latlong_direction(i - 0.5 + (a + 0.5) / ss, j - 0.5 + (b + 0.5) / ss, W, H));
          sum += room_emitted(hit.point_mm, hit.normal);
        }
      p.set_pixel(i, j, sum / (ss * ss));
    }
  p.depth_mm = proxy_depth(p, kSyntheticRoom);
  return p;
}

/// The four probe positions of bench_probe_temporal.
inline std::vector<Vec3d> room_probe_positions() {
  return {{-1000, -700, 1200}, {1000, -700, 1000}, {1000, 800, 1300}, {-1000, 800, 900}};
}

/// A dark object `distance_mm` in front of the probe along `axis` (unit, world) hiding a cone of half-angle
/// `half_angle_rad`: its depth map records the object and its pixels see black, as test_fusion's occluder.
inline void add_occluder(Probe* p, const Vec3d& axis, double half_angle_rad, double distance_mm) {
  const int W = p->width(), H = p->height();
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i)
      if (latlong_direction(i, j, W, H).dot(axis) > std::cos(half_angle_rad)) {
        p->set_pixel(i, j, Rgb::Zero());
        p->depth_mm.at<float>(j, i) = static_cast<float>(distance_mm);
      }
}

}  // namespace vdrig::probe::testing
