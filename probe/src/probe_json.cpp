#include "vdrig/probe/probe_json.hpp"

#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>

namespace vdrig::probe {
namespace {

using nlohmann::json;

constexpr char kLightsFormat[] = "vdrig.probe.lights";
constexpr char kSh9Format[] = "vdrig.probe.sh9";

json rgb_json(const Rgb& c) { return json::array({c.x(), c.y(), c.z()}); }

Error corrupt(const std::string& what) { return make_error(ErrorCode::kCorrupt, what); }

/// Three finite numbers; `what` names the value for the message (e.g. `light 3 "power"`).
Result<Vec3d> read_triple(const json& x, const std::string& what) {
  if (!x.is_array() || x.size() != 3) return corrupt(what + " must be an array of 3 numbers");
  Vec3d v;
  for (int c = 0; c < 3; ++c) {
    if (!x[c].is_number() || !std::isfinite(x[c].get<double>()))
      return corrupt(what + " must be an array of 3 finite numbers");
    v[c] = x[c].get<double>();
  }
  return v;
}

/// Three finite numbers at object[key].
Result<Vec3d> read_triple(const json& object, const char* key, const std::string& where) {
  const auto it = object.find(key);
  if (it == object.end()) return corrupt(where + ": missing \"" + key + "\"");
  return read_triple(*it, where + ": \"" + key + "\"");
}

/// Parses `text` as a JSON object of the given format and version and returns its array `key`; `source` receives
/// the "probe" string (empty when absent).
Result<json> document_array(const std::string& text, const char* format, int version, const char* key,
                            std::string* source) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    return corrupt(std::string("not a ") + format + " file, invalid JSON: " + e.what());
  }
  if (!j.is_object()) return corrupt(std::string("not a ") + format + " file: the top level is not a JSON object");
  const auto f = j.find("format");
  if (f == j.end() || !f->is_string() || f->get<std::string>() != format)
    return corrupt(std::string("not a ") + format + " file: \"format\" is missing or different");
  const auto v = j.find("version");
  if (v == j.end() || !v->is_number_integer() || v->get<int64_t>() != version)
    return corrupt(std::string(format) + ": unsupported \"version\" (this build reads " + std::to_string(version) +
                   ")");
  const auto probe = j.find("probe");
  *source = probe != j.end() && probe->is_string() ? probe->get<std::string>() : std::string();
  const auto array = j.find(key);
  if (array == j.end() || !array->is_array())
    return corrupt(std::string(format) + ": \"" + key + "\" must be an array");
  return *array;
}

}  // namespace

std::string lights_to_json(const LightsDocument& document) {
  json j = {{"format", kLightsFormat},
            {"version", kLightsFormatVersion},
            {"probe", document.source},
            {"method", "median cut (Debevec 2005)"},
            {"power_unit",
             "integral of radiance over the region (radiance x sr); E(n) = sum power max(0, "
             "n.d)"},
            {"lights", json::array()}};
  for (const auto& l : document.lights) {
    const SphericalDir s = spherical_from_direction(l.direction);
    json e = {{"azimuth_deg", rad_to_deg(s.azimuth_rad)}, {"zenith_deg", rad_to_deg(s.zenith_rad)}};
    e["direction"] = {l.direction.x(), l.direction.y(), l.direction.z()};
    e["power"] = rgb_json(l.power);
    e["solid_angle_sr"] = l.solid_angle_sr;
    // Only for lights spread over a cap (hybrid:N, soft:N; cap_lights.hpp): a renderer reproduces E with it.
    if (l.cap_cos_half_angle < 1) e["cap_half_angle_deg"] = rad_to_deg(std::acos(l.cap_cos_half_angle));
    j["lights"].push_back(e);
  }
  return j.dump(2) + "\n";
}

Result<LightsDocument> lights_from_json(const std::string& text) {
  LightsDocument doc;
  const auto lights = document_array(text, kLightsFormat, kLightsFormatVersion, "lights", &doc.source);
  if (!lights) return lights.error();
  for (size_t k = 0; k < lights->size(); ++k) {
    const json& e = (*lights)[k];
    const std::string where = std::string(kLightsFormat) + ": light " + std::to_string(k);
    if (!e.is_object()) return corrupt(where + " is not an object");
    DirectionalLight l;
    auto direction = read_triple(e, "direction", where);
    if (!direction) return direction.error();
    if (std::abs(direction->norm() - 1.0) > 1e-6) return corrupt(where + ": \"direction\" is not a unit vector");
    l.direction = *direction;
    auto power = read_triple(e, "power", where);
    if (!power) return power.error();
    if (power->minCoeff() < 0) return corrupt(where + ": \"power\" must be >= 0");
    l.power = *power;
    const auto sr = e.find("solid_angle_sr");
    if (sr == e.end() || !sr->is_number() || !std::isfinite(sr->get<double>()) || sr->get<double>() < 0)
      return corrupt(where + ": \"solid_angle_sr\" must be a finite number >= 0");
    l.solid_angle_sr = sr->get<double>();
    if (const auto cap = e.find("cap_half_angle_deg"); cap != e.end()) {
      if (!cap->is_number() || !(cap->get<double>() >= 0 && cap->get<double>() < 90))
        return corrupt(where + ": \"cap_half_angle_deg\" must be a number in [0, 90)");
      l.cap_cos_half_angle = std::cos(deg_to_rad(cap->get<double>()));
    }
    doc.lights.push_back(l);
  }
  return doc;
}

std::string sh9_to_json(const Sh9Document& document) {
  json j = {{"format", kSh9Format},
            {"version", kSh9FormatVersion},
            {"probe", document.source},
            {"basis", "real SH, design notes' normalisation with Condon-Shortley phase, i = l(l+1)+m"},
            {"radiance_coefficients", json::array()},
            {"cosine_factors", {sh9_cosine_factor(0), sh9_cosine_factor(1), sh9_cosine_factor(2)}},
            {"note", "E(n) = sum_i cosine_factors[l(i)] * radiance_coefficients[i] * y_i(n)"}};
  for (const auto& c : document.radiance.coeffs) j["radiance_coefficients"].push_back(rgb_json(c));
  return j.dump(2) + "\n";
}

Result<Sh9Document> sh9_from_json(const std::string& text) {
  Sh9Document doc;
  const auto coeffs = document_array(text, kSh9Format, kSh9FormatVersion, "radiance_coefficients", &doc.source);
  if (!coeffs) return coeffs.error();
  if (coeffs->size() != kSh9Count)
    return corrupt(std::string(kSh9Format) + ": \"radiance_coefficients\" must be an array of " +
                   std::to_string(kSh9Count) + " RGB triples");
  for (int i = 0; i < kSh9Count; ++i) {
    auto c = read_triple((*coeffs)[i], std::string(kSh9Format) + ": radiance coefficient " + std::to_string(i));
    if (!c) return c.error();
    doc.radiance.coeffs[i] = *c;
  }
  return doc;
}

Result<RoomDocument> room_from_json(const std::string& text) {
  constexpr char kRoomFormat[] = "vdrig.probe.room";
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return corrupt("room: not valid JSON");
  if (!doc.is_object() || !doc.contains("format") || !doc["format"].is_string() ||
      doc["format"].get<std::string>() != kRoomFormat)
    return corrupt(std::string("room: \"format\" must be \"") + kRoomFormat + "\"");
  if (!doc.contains("version") || !doc["version"].is_number_integer() ||
      doc["version"].get<int64_t>() != kRoomFormatVersion)  // get<int> would wrap 4294967297 to 1
    return corrupt("room: \"version\" must be " + std::to_string(kRoomFormatVersion));
  RoomDocument out;
  const auto room = doc.find("room_mm");
  if (room == doc.end() || !room->is_object()) return corrupt("room: missing object \"room_mm\"");
  auto lo = read_triple(*room, "min", "room: \"room_mm\"");
  if (!lo) return lo.error();
  auto hi = read_triple(*room, "max", "room: \"room_mm\"");
  if (!hi) return hi.error();
  out.room = ProxyBox{*lo, *hi};
  std::string why;
  if (!out.room.is_valid(&why)) return corrupt("room: \"room_mm\": " + why);
  const auto probes = doc.find("probes");
  if (probes == doc.end() || !probes->is_array() || probes->empty())
    return corrupt("room: \"probes\" must be a non-empty array");
  for (size_t k = 0; k < probes->size(); ++k) {
    const json& p = (*probes)[k];
    const std::string where = "room: probe " + std::to_string(k);
    if (!p.is_object() || !p.contains("file") || !p["file"].is_string() || p["file"].get<std::string>().empty())
      return corrupt(where + " needs a \"file\" string");
    RoomProbe rp;
    rp.file = p["file"].get<std::string>();
    if (p.contains("position_mm")) {
      auto pos = read_triple(p, "position_mm", where);
      if (!pos) return pos.error();
      rp.has_position = true;
      rp.position_mm = *pos;
    }
    out.probes.push_back(std::move(rp));
  }
  return out;
}

std::string room_to_json(const RoomDocument& d) {
  json probes = json::array();
  for (const RoomProbe& p : d.probes) {
    json o{{"file", p.file}};
    if (p.has_position) o["position_mm"] = rgb_json(p.position_mm);
    probes.push_back(o);
  }
  return json{{"format", "vdrig.probe.room"},
              {"version", kRoomFormatVersion},
              {"room_mm", {{"min", rgb_json(d.room.min_mm)}, {"max", rgb_json(d.room.max_mm)}}},
              {"probes", probes}}
             .dump(2) +
         "\n";
}

}  // namespace vdrig::probe
