// The motion keys every axis section of a stage backend shares (modbus, gpio-stepdir).
#pragma once

#include "vdrig/core/settings.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::rig {

/// Reads min_deg < max_deg (default -180..180), max_speed_deg_s (30), accel_deg_s2 (60), continuous (false);
/// converted to radians. Problems are recorded in `s`.
AxisSpec read_axis_spec(Settings& s);

/// The same keys for an axis as read (degrees): what `vdrig rig check` prints of it.
nlohmann::json axis_spec_json(const AxisSpec& axis);

}  // namespace vdrig::rig
