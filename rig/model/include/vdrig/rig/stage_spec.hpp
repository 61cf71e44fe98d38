// What a pan/tilt stage can do, as the kinematics, the route planner and the motion model see it: the limits and
// the speed profile of each axis. A stage backend reports it (PanTiltStage::spec, devices.hpp); it is plain data, so
// the hardware-free rig model (vdrig::rig_model) holds it.
#pragma once

namespace vdrig::rig {

/// Motion limits and dynamics of one axis, in radians. A move follows a trapezoidal speed profile.
struct AxisSpec {
  double min_rad = 0.0;
  double max_rad = 0.0;
  double max_speed_rad_s = 0.5;
  double accel_rad_s2 = 1.0;
  bool continuous = false;  // true for a pan axis that may turn without end (takes the shorter way round)
};

struct StageSpec {
  AxisSpec pan;
  AxisSpec tilt;
};

}  // namespace vdrig::rig
