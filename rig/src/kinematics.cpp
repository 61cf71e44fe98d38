#include "vdrig/rig/kinematics.hpp"

#include <cmath>

namespace vdrig::rig {
namespace {

Mat3d rot_x(double a) {
  return Eigen::AngleAxisd(a, Vec3d::UnitX()).toRotationMatrix();
}
Mat3d rot_z(double a) {
  return Eigen::AngleAxisd(a, Vec3d::UnitZ()).toRotationMatrix();
}

/// Brings an angle into [min, max] by whole turns when possible.
std::optional<double> wrap_into(double angle, const AxisSpec& axis) {
  if (axis.continuous) return angle;
  for (int k = -2; k <= 2; ++k) {
    const double a = angle + 2.0 * kPi * k;
    if (a >= axis.min_rad - 1e-12 && a <= axis.max_rad + 1e-12) return a;
  }
  return std::nullopt;
}

}  // namespace

Mat3d platform_rotation(const PanTilt& pt) { return rot_x(pt.tilt_rad) * rot_z(pt.pan_rad); }

ViewPose surface_pose(const RigGeometry& g, const PanTilt& pt) {
  const Mat3d R_cw = Vec3d(1, -1, -1).asDiagonal();
  const Mat3d R_ws = platform_rotation(pt);
  const Vec3d C(0, 0, g.camera_distance_mm);
  ViewPose pose;
  pose.R = R_cw * R_ws;
  pose.t = R_cw * (R_ws * g.surface_offset_mm - C);
  return pose;
}

Vec3d view_direction(const RigGeometry& g, const PanTilt& pt) {
  const ViewPose pose = surface_pose(g, pt);
  return pose.view_direction(Vec3d::Zero());
}

std::optional<PanTilt> inverse_kinematics(const RigGeometry& g, const StageSpec& spec, const Vec3d& direction,
                                          double preferred_pan_rad) {
  const Vec3d d = direction.normalized();
  const SphericalDir s = spherical_from_direction(d);
  // Two solutions on an ideal rig: (pan, tilt) and (pan + pi, -tilt). Try the positive tilt first.
  std::optional<PanTilt> best;
  for (int branch = 0; branch < 2; ++branch) {
    const double tilt = branch == 0 ? s.zenith_rad : -s.zenith_rad;
    double pan = s.zenith_rad < 1e-9 ? preferred_pan_rad : kPi / 2.0 - s.azimuth_rad + (branch == 0 ? 0.0 : kPi);
    auto pan_ok = wrap_into(pan, spec.pan);
    if (!pan_ok || tilt < spec.tilt.min_rad - 1e-12 || tilt > spec.tilt.max_rad + 1e-12) continue;
    PanTilt pt{*pan_ok, tilt};
    if (!g.surface_offset_mm.isZero()) {
      // With an offset surface the direction to the surface origin differs from the ideal one; refine by a few
      // Newton steps on (azimuth, zenith) of the actual direction.
      for (int it = 0; it < 20; ++it) {
        const Vec3d v = view_direction(g, pt);
        const SphericalDir sv = spherical_from_direction(v);
        double daz = s.azimuth_rad - sv.azimuth_rad;
        daz = std::remainder(daz, 2.0 * kPi);
        const double dzen = s.zenith_rad - sv.zenith_rad;
        pt.pan_rad -= (branch == 0 ? 1.0 : 1.0) * daz;
        pt.tilt_rad += (branch == 0 ? 1.0 : -1.0) * dzen;
        if (std::abs(daz) + std::abs(dzen) < 1e-12) break;
      }
      auto wrapped = wrap_into(pt.pan_rad, spec.pan);
      if (!wrapped || pt.tilt_rad < spec.tilt.min_rad || pt.tilt_rad > spec.tilt.max_rad) continue;
      pt.pan_rad = *wrapped;
    }
    best = pt;
    break;
  }
  return best;
}

}  // namespace vdrig::rig
