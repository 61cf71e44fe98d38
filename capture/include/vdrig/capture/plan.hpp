// Planning a session: scheme -> directions -> reachable pan/tilt targets -> visit order (route planner) -> manifest.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "vdrig/capture/route.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::capture {

struct PlanRequest {
  nlohmann::json rig_config;  // recorded in the manifest (resume rebuilds the rig from it)
  std::string scheme;         // capture/schemes.hpp grammar
  std::string bracket;        // capture/bracket.hpp grammar
  rig::StageSpec stage;       // axis limits and dynamics (from the rig's stage)
  PanTilt start;              // where the stage is when the capture starts (after homing: 0, 0)
  double surface_width_mm = 1000.0;
  double surface_height_mm = 1000.0;
  RouteOptions route;
};

/// The geometry planning aims with (what the user believes the rig is; rig/geometry_config.hpp):
///  - the config's "geometry" section when there is one (a hardware rig's, or a simulated rig the user has
///    calibrated), validated: unknown keys, wrong types and out-of-range values are kInvalidArgument naming the key;
///  - else, for a simulated rig, the ideal rig at the simulator's "distance_mm" (never its hidden pan_zero_deg,
///    tilt_zero_deg, pan_axis_tilt_deg or surface_offset_mm: those are the truth a calibration has to find);
///  - else (or for a null config) the ideal rig of rig::RigGeometry's defaults (2500 mm).
Result<rig::RigGeometry> geometry_from_rig_config(const nlohmann::json& rig_config);

/// `rig_config` with its "geometry" section replaced by the kinematic fit of a calibration (the "kinematics" of a
/// views.json, rig::read_fitted_geometry), every key written and "source" naming the file, so that the manifest
/// records the geometry the session was planned with (a resume or a later stage need not find the file again).
/// Errors of reading the file, naming it; the config is not changed then.
Result<nlohmann::json> with_fitted_geometry(const nlohmann::json& rig_config, const std::filesystem::path& views_json);

/// Validates scheme, bracket and the geometry (geometry_from_rig_config), plans targets (unreachable directions logged
/// and counted in extra), orders the views with plan_route and records in `extra.route` the planned and naive (scheme
/// order) move times. Views are stored in visit order and re-indexed 0..N-1; extra.route.scheme_index maps them back.
Result<Manifest> plan_manifest(const PlanRequest& request);

}  // namespace vdrig::capture
