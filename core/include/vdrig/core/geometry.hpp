// Frames and direction conventions shared by every module (docs/conventions.md):
//  - surface frame: origin at the surface centre, x along its width, y along its height, z the outward normal, mm;
//  - directions are unit vectors; spherical angles are `azimuth` (from +x toward +y, [0, 2pi)) and
//    `zenith` (from +z, [0, pi]); never bare theta/phi in interfaces;
//  - latitude-longitude maps: u = azimuth / 2pi across, v = zenith / pi down, pixel centres at (i + 0.5) / W.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace vdrig {

using Vec2d = Eigen::Vector2d;
using Vec3d = Eigen::Vector3d;
using Mat3d = Eigen::Matrix3d;

inline constexpr double kPi = std::numbers::pi;
inline double deg_to_rad(double deg) { return deg * kPi / 180.0; }
inline double rad_to_deg(double rad) { return rad * 180.0 / kPi; }

/// A direction as azimuth (from +x toward +y, [0, 2pi)) and zenith (from +z, [0, pi]), radians.
struct SphericalDir {
  double azimuth_rad = 0.0;
  double zenith_rad = 0.0;
};

/// Unit vector of the given spherical angles.
inline Vec3d direction_from_spherical(double azimuth_rad, double zenith_rad) {
  const double s = std::sin(zenith_rad);
  return {s * std::cos(azimuth_rad), s * std::sin(azimuth_rad), std::cos(zenith_rad)};
}
inline Vec3d direction_from_spherical(const SphericalDir& d) {
  return direction_from_spherical(d.azimuth_rad, d.zenith_rad);
}

/// Spherical angles of a (not necessarily unit, non-zero) vector; azimuth wrapped into [0, 2pi).
inline SphericalDir spherical_from_direction(const Vec3d& v) {
  const double n = v.norm();
  double az = std::atan2(v.y(), v.x());
  if (az < 0) az += 2.0 * kPi;
  const double c = std::clamp(v.z() / n, -1.0, 1.0);
  return {az, std::acos(c)};
}

/// Mirror of incoming direction `to_light` (unit, pointing away from the surface) about normal n.
inline Vec3d mirror_direction(const Vec3d& to_light, const Vec3d& normal) {
  return 2.0 * to_light.dot(normal) * normal - to_light;
}

/// Angle between two unit vectors, radians, robust near 0 and pi.
inline double angle_between(const Vec3d& a, const Vec3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

/// Centre of texel (s, t) of an S x T map on a W x H mm surface, in the surface frame (z = 0).
inline Vec3d texel_centre_mm(int s, int t, int S, int T, double width_mm, double height_mm) {
  return {(s + 0.5) * width_mm / S - width_mm / 2.0, (t + 0.5) * height_mm / T - height_mm / 2.0, 0.0};
}

/// Latitude-longitude map pixel (i, j) of a W x H map -> unit direction through the pixel centre.
inline Vec3d latlong_direction(double i, double j, int W, int H) {
  return direction_from_spherical(2.0 * kPi * (i + 0.5) / W, kPi * (j + 0.5) / H);
}

/// Solid angle (sr) of one pixel in row j of a W x H latitude-longitude map.
inline double latlong_pixel_solid_angle(int j, int W, int H) {
  return (std::cos(kPi * j / H) - std::cos(kPi * (j + 1) / H)) * 2.0 * kPi / W;
}

}  // namespace vdrig
