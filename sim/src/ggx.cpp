#include "vdrig/sim/ggx.hpp"

#include <algorithm>
#include <cmath>

namespace vdrig::sim {

double ggx_distribution(const Vec3d& h, double ax, double ay) {
  if (h.z() <= 0.0) return 0.0;
  const double sx = h.x() / ax, sy = h.y() / ay;
  const double q = sx * sx + sy * sy + h.z() * h.z();
  return 1.0 / (kPi * ax * ay * q * q);
}

double ggx_lambda(const Vec3d& w, double ax, double ay) {
  const double z2 = w.z() * w.z();
  const double t = (ax * ax * w.x() * w.x() + ay * ay * w.y() * w.y()) / z2;
  return 0.5 * (std::sqrt(1.0 + t) - 1.0);
}

Vec3d ggx_brdf(const Vec3d& l, const Vec3d& v, double ax, double ay, const Vec3d& f0) {
  if (l.z() <= 0.0 || v.z() <= 0.0) return Vec3d::Zero();
  const Vec3d h = (l + v).normalized();
  const double d = ggx_distribution(h, ax, ay);
  const double g2 = 1.0 / (1.0 + ggx_lambda(l, ax, ay) + ggx_lambda(v, ax, ay));
  const double schlick = std::pow(1.0 - std::clamp(v.dot(h), 0.0, 1.0), 5.0);
  const Vec3d fresnel = f0 + (Vec3d::Ones() - f0) * schlick;
  return fresnel * (d * g2 / (4.0 * l.z() * v.z()));
}

Mat3d ggx_local_frame(const Vec3d& n) {
  Vec3d t = Vec3d::UnitX() - n * n.x();
  if (t.squaredNorm() < 1e-12) t = Vec3d::UnitY() - n * n.y();  // n along x: never for a surface normal (nz > 0)
  t.normalize();
  Mat3d frame;
  frame.row(0) = t.transpose();
  frame.row(1) = n.cross(t).transpose();
  frame.row(2) = n.transpose();
  return frame;
}

}  // namespace vdrig::sim
