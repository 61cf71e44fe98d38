#include "vdrig/rig/motion.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"  // VDRIG_CHECK

namespace vdrig::rig {

double axis_move_time_s(double distance_rad, const AxisSpec& axis) {
  VDRIG_CHECK(axis.max_speed_rad_s > 0.0 && axis.accel_rad_s2 > 0.0, "axis speed and acceleration must be > 0");
  const double d = std::abs(distance_rad);
  const double v = axis.max_speed_rad_s, a = axis.accel_rad_s2;
  if (d >= v * v / a) return d / v + v / a;
  return 2.0 * std::sqrt(d / a);
}

double move_time_s(const StageSpec& spec, const PanTilt& from, const PanTilt& to) {
  double pan = to.pan_rad - from.pan_rad;
  if (spec.pan.continuous) pan = std::remainder(pan, 2.0 * kPi);
  return std::max(axis_move_time_s(pan, spec.pan), axis_move_time_s(to.tilt_rad - from.tilt_rad, spec.tilt));
}

}  // namespace vdrig::rig
