#include "vdrig/capture/plan.hpp"

#include "vdrig/capture/bracket.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/rig/geometry_config.hpp"

namespace vdrig::capture {

Result<rig::RigGeometry> geometry_from_rig_config(const nlohmann::json& rc) {
  if (rc.is_null()) return rig::RigGeometry{};  // a plan without a rig config (library use): the ideal rig
  if (!rc.is_object()) return make_error(ErrorCode::kInvalidArgument, "rig config must be a JSON object");
  if (rc.contains("geometry")) return rig::geometry_from_section(rc["geometry"]);
  rig::RigGeometry g;
  if (rc.contains("sim")) {
    // Only the distance, which the user sets up and knows; the simulator's other geometry is its hidden truth.
    Settings s(rc["sim"], "sim");
    g.camera_distance_mm = s.number("distance_mm", g.camera_distance_mm, 1e-3);
    if (!s.is_valid(nullptr)) return s.error();
  }
  return g;
}

Result<nlohmann::json> with_fitted_geometry(const nlohmann::json& rig_config, const std::filesystem::path& views_json) {
  if (!rig_config.is_object()) return make_error(ErrorCode::kInvalidArgument, "rig config must be a JSON object");
  auto fitted = rig::read_fitted_geometry(views_json);
  if (!fitted) return fitted.error();
  nlohmann::json rc = rig_config;
  std::error_code ec;  // the provenance names the file wherever the session is read later
  const std::filesystem::path absolute = std::filesystem::absolute(views_json, ec);
  rc["geometry"] = rig::geometry_section(fitted.value(), "kinematic fit of " + (ec ? views_json : absolute).string());
  return rc;
}

Result<Manifest> plan_manifest(const PlanRequest& req) {
  auto logger = log::get("capture");
  auto bracket = parse_bracket(req.bracket);
  if (!bracket) return bracket.error();
  auto samples = generate(req.scheme);
  if (!samples) return samples.error();
  auto geometry = geometry_from_rig_config(req.rig_config);
  if (!geometry) return geometry.error();
  const auto plan = plan_targets(geometry.value(), req.stage, samples->directions);
  for (const auto& u : plan.unreachable) {
    const SphericalDir s = spherical_from_direction(u.direction);
    logger->warn("direction {} (azimuth {:.1f} deg, zenith {:.1f} deg) is unreachable within the axis limits", u.index,
                 rad_to_deg(s.azimuth_rad), rad_to_deg(s.zenith_rad));
  }
  if (plan.reachable.empty())
    return make_error(ErrorCode::kInvalidArgument, "scheme '" + req.scheme + "': no direction is reachable");
  std::vector<PanTilt> targets;
  for (const auto& t : plan.reachable) targets.push_back(t.pan_tilt);
  const Route route = plan_route(req.stage, req.start, targets, req.route);
  logger->info("route over {} views: {:.1f} s of moves planned vs {:.1f} s in scheme order ({} passes, {:.3f} s)",
               targets.size(), route.planned_time_s, route.naive_time_s, route.passes, route.planning_s);

  Manifest m;
  m.rig_config = req.rig_config;
  m.scheme = req.scheme;
  m.bracket = bracket->to_spec();
  if (bracket->kind == BracketSpec::Kind::kFixed) m.exposures_s = bracket->exposures_s;
  m.surface_width_mm = req.surface_width_mm;
  m.surface_height_mm = req.surface_height_mm;
  std::vector<size_t> scheme_index;
  for (size_t k : route.order) {
    const auto& t = plan.reachable[k];
    m.views.push_back({static_cast<int>(m.views.size()), t.direction, t.pan_tilt});
    scheme_index.push_back(t.index);
  }
  m.extra["route"] = {{"planned_time_s", route.planned_time_s},     {"naive_time_s", route.naive_time_s},
                      {"used_naive_order", route.used_naive_order}, {"passes", route.passes},
                      {"unreachable", plan.unreachable.size()},     {"scheme_index", scheme_index}};
  return m;
}

}  // namespace vdrig::capture
