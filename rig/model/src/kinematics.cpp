#include "vdrig/rig/kinematics.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/rig/kinematics_model.hpp"

namespace vdrig::rig {
namespace {

Mat3d rot_x(double a) { return Eigen::AngleAxisd(a, Vec3d::UnitX()).toRotationMatrix(); }
Mat3d rot_z(double a) { return Eigen::AngleAxisd(a, Vec3d::UnitZ()).toRotationMatrix(); }

/// The whole-turn equivalent of `angle` nearest `preferred` that lies within [min, max] (any, for a continuous
/// axis). Nearest matters: the first fitting turn from -2 up put pans a full turn away from zero on a +-360 deg
/// stage, sending the stage the long way round.
std::optional<double> wrap_into(double angle, const AxisSpec& axis, double preferred) {
  const double nearest = preferred + std::remainder(angle - preferred, 2.0 * kPi);
  if (axis.continuous) return nearest;
  std::optional<double> best;
  for (int k = -3; k <= 3; ++k) {
    const double a = nearest + 2.0 * kPi * k;
    if (a < axis.min_rad - 1e-12 || a > axis.max_rad + 1e-12) continue;
    if (!best || std::abs(a - preferred) < std::abs(*best - preferred)) best = a;
  }
  return best;
}

}  // namespace

Mat3d platform_rotation(const PanTilt& pt) { return rot_x(pt.tilt_rad) * rot_z(pt.pan_rad); }

ViewPose surface_pose(const RigGeometry& g, const PanTilt& pt) {
  const model::Params p = model::to_params(g);
  ViewPose pose;
  model::surface_pose(p.data(), pt, &pose.R, &pose.t);
  return pose;
}

Vec3d view_direction(const RigGeometry& g, const PanTilt& pt) {
  const ViewPose pose = surface_pose(g, pt);
  return pose.view_direction(Vec3d::Zero());
}

std::optional<PanTilt> inverse_kinematics(const RigGeometry& g, const StageSpec& spec, const Vec3d& direction,
                                          double preferred_pan_rad) {
  if (!direction.allFinite() || !(direction.norm() > 0.0) || !(g.camera_distance_mm > 0.0)) return std::nullopt;
  // In the platter frame (kinematics.hpp) the camera centre is D u(pan, tilt), u = (sin tilt sin pan, sin tilt cos pan,
  // cos tilt) the ideal view direction at the true axis angles and D the camera distance, and the surface origin is
  // the offset o; the surface's direction d is A d there. Seeing the surface origin from d means
  // D u = o + lambda A d with lambda > 0 and |D u| = D:
  //   lambda^2 + 2 lambda (o . A d) + |o|^2 - D^2 = 0,
  // whose larger root is the only positive one while the surface origin is inside the camera's sphere. This is
  // closed form: an earlier fixed-point iteration on (azimuth, zenith) diverged near the normal, where azimuth is
  // ill-conditioned (errors of tens of degrees within a few degrees of the pole). The encoder zeros then turn the
  // true angles into readings.
  const model::Params p = model::to_params(g);
  const Vec3d d = model::surface_in_platter(p.data()) * direction.normalized();
  Vec3d u = d;
  const Vec3d& o = g.surface_offset_mm;
  if (!o.isZero()) {
    const double D = g.camera_distance_mm;
    const double od = o.dot(d);
    const double disc = od * od - o.squaredNorm() + D * D;
    if (!(disc >= 0.0)) return std::nullopt;
    const double lambda = -od + std::sqrt(disc);
    if (!(lambda > 0.0)) return std::nullopt;
    u = (o + lambda * d) / D;
  }
  const SphericalDir s = spherical_from_direction(u);
  // Two solutions: (pan, tilt) and (pan + pi, -tilt). Try the positive tilt first.
  for (int branch = 0; branch < 2; ++branch) {
    const double tilt = (branch == 0 ? s.zenith_rad : -s.zenith_rad) + g.tilt_zero_rad;
    const double pan = s.zenith_rad < 1e-9 ? preferred_pan_rad
                                           : kPi / 2.0 - s.azimuth_rad + (branch == 0 ? 0.0 : kPi) + g.pan_zero_rad;
    const auto pan_ok = wrap_into(pan, spec.pan, preferred_pan_rad);
    if (!pan_ok || tilt < spec.tilt.min_rad - 1e-12 || tilt > spec.tilt.max_rad + 1e-12) continue;
    // Clamped: a target 1e-12 past a limit would be refused by a stage that checks its limits strictly.
    return PanTilt{std::clamp(*pan_ok, spec.pan.min_rad, spec.pan.max_rad),
                   std::clamp(tilt, spec.tilt.min_rad, spec.tilt.max_rad)};
  }
  return std::nullopt;
}

}  // namespace vdrig::rig
