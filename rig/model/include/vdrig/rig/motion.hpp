// How long the stage takes to move: the motion model the simulator runs and the route planner optimises.
// Each axis follows a trapezoidal speed profile (accelerate at accel_rad_s2 up to max_speed_rad_s, cruise,
// decelerate to a stop), or a triangular one when the distance is too short to reach max speed; both axes start
// together, so a move takes the longer of the two axis times.
#pragma once

#include "vdrig/core/frame.hpp"
#include "vdrig/rig/stage_spec.hpp"

namespace vdrig::rig {

/// Time (s) for one axis to travel |distance_rad| from rest to rest:
///   d >= v^2 / a: d / v + v / a   (trapezoid: two ramps of v / a, cruise for the rest)
///   d <  v^2 / a: 2 sqrt(d / a)   (triangle: never reaches v)
double axis_move_time_s(double distance_rad, const AxisSpec& axis);

/// Time (s) of a move of both axes from `from` to `to`: the longer axis time. A continuous pan axis travels the
/// shorter way round (|remainder(to - from, 2 pi)|).
double move_time_s(const StageSpec& spec, const PanTilt& from, const PanTilt& to);

}  // namespace vdrig::rig
