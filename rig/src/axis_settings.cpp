#include "axis_settings.hpp"

#include "vdrig/core/geometry.hpp"

namespace vdrig::rig {

nlohmann::json axis_spec_json(const AxisSpec& a) {
  constexpr double kDegPerRad = 180.0 / kPi;  // multiplied: the inverse of read_axis_spec's division
  return {{"min_deg", a.min_rad * kDegPerRad},
          {"max_deg", a.max_rad * kDegPerRad},
          {"max_speed_deg_s", a.max_speed_rad_s * kDegPerRad},
          {"accel_deg_s2", a.accel_rad_s2 * kDegPerRad},
          {"continuous", a.continuous}};
}

AxisSpec read_axis_spec(Settings& s) {
  constexpr double kDegPerRad = 180.0 / kPi;  // divided (not deg_to_rad) to keep the radians bit-identical
  AxisSpec axis;
  const double min_deg = s.number("min_deg", -180.0, -1e6, 1e6);
  const double max_deg = s.number("max_deg", 180.0, -1e6, 1e6);
  if (min_deg >= max_deg) s.fail("\"min_deg\" must be below \"max_deg\"");
  axis.min_rad = min_deg / kDegPerRad;
  axis.max_rad = max_deg / kDegPerRad;
  axis.max_speed_rad_s = s.number("max_speed_deg_s", 30.0, 1e-6, 1e6) / kDegPerRad;
  axis.accel_rad_s2 = s.number("accel_deg_s2", 60.0, 1e-6, 1e7) / kDegPerRad;
  axis.continuous = s.boolean("continuous", false);
  return axis;
}

}  // namespace vdrig::rig
