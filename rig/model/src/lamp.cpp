#include "vdrig/rig/lamp.hpp"

#include <Eigen/Geometry>

#include <cmath>

namespace vdrig::rig {
namespace {

constexpr const char* kLampKeys[] = {"position_mm", "position_frame", "intensity", "position_source"};

}  // namespace

bool is_lamp_key(const std::string& key) {
  for (const char* k : kLampKeys)
    if (key == k) return true;
  return false;
}

nlohmann::json without_lamp_keys(const nlohmann::json& light_section) {
  if (!light_section.is_object()) return light_section;
  nlohmann::json out = light_section;
  for (const char* k : kLampKeys) out.erase(k);
  return out;
}

Result<std::optional<LampPosition>> lamp_from_light_section(const nlohmann::json& section) {
  if (!section.is_object() || !section.contains("position_mm")) {
    if (section.is_object())
      for (const char* k : {"position_frame", "intensity"})
        if (section.contains(k))
          return make_error(ErrorCode::kInvalidArgument,
                            std::string("light: \"") + k + "\" needs the lamp's \"position_mm\"");
    return std::optional<LampPosition>();
  }
  std::vector<std::string> problems;
  LampPosition lamp;
  const nlohmann::json& p = section["position_mm"];
  if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number()) {
    problems.push_back("\"position_mm\" must be [x, y, z] (mm), got " + p.dump());
  } else {
    lamp.position_mm = Vec3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    if (!lamp.position_mm.allFinite()) problems.push_back("\"position_mm\" must be finite");
  }
  if (const auto f = section.find("position_frame"); f != section.end()) {
    const std::string frame = f->is_string() ? f->get<std::string>() : "";
    if (frame == "surface") {
      lamp.frame = LampPosition::Frame::kSurface;
    } else if (frame == "platter") {
      lamp.frame = LampPosition::Frame::kPlatter;
    } else {
      problems.push_back("\"position_frame\" must be \"surface\" or \"platter\", got " + f->dump());
    }
  }
  if (const auto i = section.find("intensity"); i != section.end()) {
    Vec3d rgb = Vec3d::Constant(-1.0);
    if (i->is_number()) {
      rgb = Vec3d::Constant(i->get<double>());
    } else if (i->is_array() && i->size() == 3 && (*i)[0].is_number() && (*i)[1].is_number() && (*i)[2].is_number()) {
      rgb = Vec3d((*i)[0].get<double>(), (*i)[1].get<double>(), (*i)[2].get<double>());
    }
    if (!rgb.allFinite() || rgb.minCoeff() < 0.0 || !(rgb.maxCoeff() > 0.0))
      problems.push_back("\"intensity\" must be a positive number or [r, g, b] (none negative), got " + i->dump());
    else
      lamp.intensity = rgb;
  }
  if (const auto s = section.find("position_source"); s != section.end()) {
    if (s->is_string())
      lamp.source = s->get<std::string>();
    else
      problems.push_back("\"position_source\" must be a string");
  }
  if (!problems.empty()) {
    std::string message = "light: invalid lamp position";
    for (const auto& why : problems) message += "; " + why;
    return make_error(ErrorCode::kInvalidArgument, message);
  }
  return std::optional<LampPosition>(lamp);
}

nlohmann::json lamp_keys(const LampPosition& lamp) {
  nlohmann::json j = {{"position_mm", {lamp.position_mm.x(), lamp.position_mm.y(), lamp.position_mm.z()}},
                      {"position_frame", lamp.frame == LampPosition::Frame::kSurface ? "surface" : "platter"}};
  if (lamp.intensity) j["intensity"] = {lamp.intensity->x(), lamp.intensity->y(), lamp.intensity->z()};
  if (!lamp.source.empty()) j["position_source"] = lamp.source;
  return j;
}

Vec3d lamp_in_surface_frame(const LampPosition& lamp, const RigGeometry& geometry) {
  if (lamp.frame == LampPosition::Frame::kSurface) return lamp.position_mm;
  const Mat3d a = (Eigen::AngleAxisd(geometry.pan_axis_tilt_x_rad, Vec3d::UnitX()) *
                   Eigen::AngleAxisd(geometry.pan_axis_tilt_y_rad, Vec3d::UnitY()))
                      .toRotationMatrix();
  return a.transpose() * (lamp.position_mm - geometry.surface_offset_mm);
}

}  // namespace vdrig::rig
