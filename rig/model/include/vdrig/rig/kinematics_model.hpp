// The rig's forward model (kinematics.hpp describes it) written once over the scalar type, so that the double
// valued surface_pose() and the kinematic calibration's automatic derivatives (Ceres jets) run the same code.
// The geometry travels as a flat parameter vector, lengths in mm and angles in radians, in the order of `Param`.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>

#include "vdrig/core/frame.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::rig::model {

enum Param : int {
  kDistance = 0,  // camera_distance_mm
  kOffsetX,       // surface_offset_mm
  kOffsetY,
  kOffsetZ,
  kPanZero,  // pan_zero_rad
  kTiltZero,
  kAxisTiltX,  // pan_axis_tilt_x_rad
  kAxisTiltY,
};
inline constexpr int kParamCount = kAxisTiltY + 1;

using Params = std::array<double, kParamCount>;

inline Params to_params(const RigGeometry& g) {
  const Vec3d& o = g.surface_offset_mm;
  return {g.camera_distance_mm, o.x(), o.y(), o.z(), g.pan_zero_rad, g.tilt_zero_rad, g.pan_axis_tilt_x_rad,
          g.pan_axis_tilt_y_rad};
}

inline RigGeometry from_params(const Params& p) {
  RigGeometry g;
  g.camera_distance_mm = p[kDistance];
  g.surface_offset_mm = Vec3d(p[kOffsetX], p[kOffsetY], p[kOffsetZ]);
  g.pan_zero_rad = p[kPanZero];
  g.tilt_zero_rad = p[kTiltZero];
  g.pan_axis_tilt_x_rad = p[kAxisTiltX];
  g.pan_axis_tilt_y_rad = p[kAxisTiltY];
  return g;
}

template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

// Rotations about one axis, written out rather than Eigen::AngleAxis<T>(a, Vec3<T>::UnitX()).toRotationMatrix():
// for Ceres jets that builds the general Rodrigues matrix with jet products by the axis' zero entries, and measured
// (GCC 12 -O3, ceres::Jet<double, 8>) surface_pose took 3x as long (6.5-6.9 us against 2.1-2.5 us per evaluation);
// in doubles its diagonal (1 - c) + c is not always exactly 1 (12 % of poses differ, by up to 2.2e-16).
template <typename T>
Mat3<T> rot_x(const T& a) {
  using std::cos;
  using std::sin;
  const T c = cos(a), s = sin(a), zero(0.0), one(1.0);
  Mat3<T> m;
  m << one, zero, zero, zero, c, -s, zero, s, c;
  return m;
}

template <typename T>
Mat3<T> rot_y(const T& a) {
  using std::cos;
  using std::sin;
  const T c = cos(a), s = sin(a), zero(0.0), one(1.0);
  Mat3<T> m;
  m << c, zero, s, zero, one, zero, -s, zero, c;
  return m;
}

template <typename T>
Mat3<T> rot_z(const T& a) {
  using std::cos;
  using std::sin;
  const T c = cos(a), s = sin(a), zero(0.0), one(1.0);
  Mat3<T> m;
  m << c, -s, zero, s, c, zero, zero, zero, one;
  return m;
}

/// The surface in the platter frame: p_platter = A p_surface + offset, A = Rx(axis_tilt_x) Ry(axis_tilt_y).
template <typename T>
Mat3<T> surface_in_platter(const T* p) {
  return rot_x(p[kAxisTiltX]) * rot_y(p[kAxisTiltY]);
}

/// The platter in the world for encoder readings: Rx(tilt_r - tilt_zero) Rz(pan_r - pan_zero).
template <typename T>
Mat3<T> platter_in_world(const T* p, const PanTilt& reading) {
  return rot_x(T(reading.tilt_rad) - p[kTiltZero]) * rot_z(T(reading.pan_rad) - p[kPanZero]);
}

/// Pose of the surface in the camera, p_cam = R p_surface + t, at the stage's `reading`.
template <typename T>
void surface_pose(const T* p, const PanTilt& reading, Mat3<T>* R, Vec3<T>* t) {
  Mat3<T> R_cw = Mat3<T>::Zero();  // camera from world: diag(1, -1, -1)
  R_cw(0, 0) = T(1.0);
  R_cw(1, 1) = T(-1.0);
  R_cw(2, 2) = T(-1.0);
  const Mat3<T> R_wp = platter_in_world(p, reading);
  const Vec3<T> offset(p[kOffsetX], p[kOffsetY], p[kOffsetZ]);
  const Vec3<T> C(T(0.0), T(0.0), p[kDistance]);
  *R = R_cw * R_wp * surface_in_platter(p);
  *t = R_cw * (R_wp * offset - C);
}

}  // namespace vdrig::rig::model
