// Planning a session: scheme -> directions -> reachable pan/tilt targets -> visit order (route planner) -> manifest.
#pragma once

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

/// Geometry a rig config states: "geometry": {"distance_mm"} for hardware, or the simulator's "sim":
/// {"distance_mm"} (default 2500 mm, ideal axes).
rig::RigGeometry geometry_from_rig_config(const nlohmann::json& rig_config);

/// Validates scheme and bracket, plans targets (unreachable directions logged and counted in extra), orders the
/// views with plan_route and records in `extra.route` the planned and naive (scheme order) move times.
/// Views are stored in visit order and re-indexed 0..N-1; extra.route.scheme_index maps them back.
Result<Manifest> plan_manifest(const PlanRequest& request);

}  // namespace vdrig::capture
