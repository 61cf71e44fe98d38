#include "vdrig/rig/geometry_config.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/core/file_read.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/rig/kinematics_model.hpp"

namespace vdrig::rig {

bool geometry_is_valid(const RigGeometry& g, std::string* why) {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(g.camera_distance_mm > 0) || !std::isfinite(g.camera_distance_mm)) return fail("distance_mm must be positive");
  if (!g.surface_offset_mm.allFinite() || g.surface_offset_mm.norm() >= g.camera_distance_mm)
    return fail("surface_offset_mm must be finite and nearer the axes than the camera");
  if (!(std::abs(g.pan_zero_rad) <= kPi) || !(std::abs(g.tilt_zero_rad) <= kPi))
    return fail("pan_zero_deg and tilt_zero_deg must be within +-180");
  if (!(std::abs(g.pan_axis_tilt_x_rad) <= deg_to_rad(10.0)) || !(std::abs(g.pan_axis_tilt_y_rad) <= deg_to_rad(10.0)))
    return fail("pan_axis_tilt_deg must be within +-10 deg");
  return true;
}

Result<RigGeometry> geometry_from_section(const nlohmann::json& section) {
  Settings s(section, "geometry");
  s.reject_unknown(
      {"distance_mm", "surface_offset_mm", "pan_zero_deg", "tilt_zero_deg", "pan_axis_tilt_deg", "source"});
  RigGeometry g;
  g.camera_distance_mm = s.required_number("distance_mm", 1e-3);
  const std::vector<double> offset = s.number_list("surface_offset_mm", {0.0, 0.0, 0.0}, 3);
  g.surface_offset_mm = Vec3d(offset[0], offset[1], offset[2]);
  g.pan_zero_rad = deg_to_rad(s.number("pan_zero_deg", 0.0, -180.0, 180.0));
  g.tilt_zero_rad = deg_to_rad(s.number("tilt_zero_deg", 0.0, -180.0, 180.0));
  const std::vector<double> axis_tilt = s.number_list("pan_axis_tilt_deg", {0.0, 0.0}, 2);
  g.pan_axis_tilt_x_rad = deg_to_rad(axis_tilt[0]);
  g.pan_axis_tilt_y_rad = deg_to_rad(axis_tilt[1]);
  s.string("source", "");
  std::string why;
  if (s.is_valid(nullptr) && !geometry_is_valid(g, &why)) s.fail(why);
  if (!s.is_valid(nullptr)) return s.error();
  return g;
}

nlohmann::json geometry_section(const RigGeometry& g, const std::string& source) {
  const Vec3d& o = g.surface_offset_mm;
  nlohmann::json j = {{"distance_mm", g.camera_distance_mm},
                      {"surface_offset_mm", {o.x(), o.y(), o.z()}},
                      {"pan_zero_deg", rad_to_deg(g.pan_zero_rad)},
                      {"tilt_zero_deg", rad_to_deg(g.tilt_zero_rad)},
                      {"pan_axis_tilt_deg", {rad_to_deg(g.pan_axis_tilt_x_rad), rad_to_deg(g.pan_axis_tilt_y_rad)}}};
  if (!source.empty()) j["source"] = source;
  return j;
}

nlohmann::json kinematics_to_json(const RigGeometry& g) {
  const Vec3d& o = g.surface_offset_mm;
  return {{"camera_distance_mm", g.camera_distance_mm},
          {"surface_offset_mm", {o.x(), o.y(), o.z()}},
          {"pan_zero_deg", rad_to_deg(g.pan_zero_rad)},
          {"tilt_zero_deg", rad_to_deg(g.tilt_zero_rad)},
          {"pan_axis_tilt_x_deg", rad_to_deg(g.pan_axis_tilt_x_rad)},
          {"pan_axis_tilt_y_deg", rad_to_deg(g.pan_axis_tilt_y_rad)}};
}

Result<RigGeometry> kinematics_from_json(const nlohmann::json& j) {
  try {
    RigGeometry g;
    g.camera_distance_mm = j.at("camera_distance_mm").get<double>();
    const auto& o = j.at("surface_offset_mm");
    g.surface_offset_mm = {o.at(0).get<double>(), o.at(1).get<double>(), o.at(2).get<double>()};
    g.pan_zero_rad = deg_to_rad(j.value("pan_zero_deg", 0.0));
    g.tilt_zero_rad = deg_to_rad(j.value("tilt_zero_deg", 0.0));
    g.pan_axis_tilt_x_rad = deg_to_rad(j.value("pan_axis_tilt_x_deg", 0.0));
    g.pan_axis_tilt_y_rad = deg_to_rad(j.value("pan_axis_tilt_y_deg", 0.0));
    const model::Params p = model::to_params(g);
    if (!std::all_of(p.begin(), p.end(), [](double v) { return std::isfinite(v); }) || !(g.camera_distance_mm > 0))
      return make_error(ErrorCode::kCorrupt, "kinematics: non-finite values or a non-positive camera distance");
    return g;
  } catch (const nlohmann::json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("kinematics: ") + e.what());
  }
}

Result<RigGeometry> read_fitted_geometry(const std::filesystem::path& views_json) {
  const std::string where = views_json.string() + ": ";
  auto file = read_json_file(views_json);
  if (!file) return make_error(file.error().code, where + file.error().message);
  const nlohmann::json& j = file.value();
  if (!j.is_object() || !j.contains("kinematics") || j["kinematics"].is_null())
    return make_error(ErrorCode::kInvalidArgument,
                      where + "no kinematic fit (\"kinematics\"); run vdrig calib extrinsics on a session first");
  auto g = kinematics_from_json(j["kinematics"]);
  if (!g) return make_error(g.error().code, where + g.error().message);
  std::string why;
  if (!geometry_is_valid(g.value(), &why)) return make_error(ErrorCode::kCorrupt, where + "kinematics: " + why);
  return g;
}

}  // namespace vdrig::rig
