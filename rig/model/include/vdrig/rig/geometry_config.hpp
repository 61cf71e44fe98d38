// The rig geometry (kinematics.hpp) in JSON, in its two spellings:
//  - a rig config's "geometry" section, what the user states the rig to be (the simulator's "sim" keys):
//      {"distance_mm": 2500, "surface_offset_mm": [x, y, z], "pan_zero_deg": 0, "tilt_zero_deg": 0,
//       "pan_axis_tilt_deg": [x, y], "source": "where the numbers came from (free text, not read)"}
//    Every key but distance_mm is optional (0 = the ideal rig). Planning aims with it (capture/plan.hpp).
//  - the "kinematics" object `vdrig calib extrinsics` writes into views.json (calib/kinematic.hpp), with the fit's
//    names: camera_distance_mm, surface_offset_mm, pan_zero_deg, tilt_zero_deg, pan_axis_tilt_x_deg,
//    pan_axis_tilt_y_deg. It is read here so that capture uses a calibration without depending on calib.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/core/result.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::rig {

/// The range a stated or simulated geometry must be in (messages name the rig config keys): a positive distance,
/// a finite offset nearer the axes than the camera, zeros within +-180 deg and an axis tilt within +-10 deg (beyond
/// that a rig is broken, not miscalibrated).
bool geometry_is_valid(const RigGeometry& geometry, std::string* why);

/// Parses and validates a rig config's "geometry" section (keys above). Unknown keys, wrong types and values out of
/// range are kInvalidArgument naming the key ("geometry: invalid settings; ...").
Result<RigGeometry> geometry_from_section(const nlohmann::json& section);
/// The section for a geometry (every key written), with `source` recorded when not empty.
nlohmann::json geometry_section(const RigGeometry& geometry, const std::string& source = "");

/// views.json "kinematics" keys (above).
nlohmann::json kinematics_to_json(const RigGeometry& geometry);
/// The distance and offset are required; a missing angle is 0 (files written before the full model read as the
/// ideal rig they were fitted as). kCorrupt on wrong types or values.
Result<RigGeometry> kinematics_from_json(const nlohmann::json& j);

/// The fitted geometry of a calibration: the "kinematics" object of a views.json (SESSION/calib/views.json after
/// `vdrig calib extrinsics`). kNotFound/kIo when the file cannot be read, kInvalidArgument when it is not JSON or
/// has no kinematic fit, kCorrupt when the fit is malformed; each message names the file.
Result<RigGeometry> read_fitted_geometry(const std::filesystem::path& views_json);

}  // namespace vdrig::rig
