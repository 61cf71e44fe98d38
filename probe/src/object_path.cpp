#include "vdrig/probe/object_path.hpp"

#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <sstream>

namespace vdrig::probe {
namespace {

using nlohmann::json;

constexpr char kFormat[] = "vdrig.probe.path";
constexpr int kVersion = 1;

Error invalid(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }
Error corrupt(const std::string& m) { return make_error(ErrorCode::kCorrupt, "path JSON: " + m); }

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string describe(const Vec3d& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ") mm";
  return s.str();
}

}  // namespace

Status validate_path(const ObjectPath& path, const ProxyBox& room, double margin_mm) {
  std::string why;
  if (!room.is_valid(&why)) return invalid("path: the room is not a valid box: " + why);
  if (path.keys.empty()) return invalid("the object's path is empty: it needs at least one key (time, position)");
  static const char* const kWall[3][2] = {{"x min", "x max"}, {"y min", "y max"}, {"z min", "z max"}};
  for (size_t k = 0; k < path.keys.size(); ++k) {
    const PathKey& key = path.keys[k];
    const std::string name = "path key " + std::to_string(k);
    if (!std::isfinite(key.time_s) || !key.position_mm.allFinite())
      return invalid(name + " has a non-finite time or position");
    if (k > 0 && !(key.time_s > path.keys[k - 1].time_s))
      return invalid(name + " at " + number(key.time_s) + " s does not come after key " + std::to_string(k - 1) +
                     " at " + number(path.keys[k - 1].time_s) + " s (times must increase)");
    // position_at and sample_path divide by time differences: a span beyond the largest double (times of opposite
    // signs near 1e308) would make them inf and the positions NaN.
    if (k > 0 && !std::isfinite(key.time_s - path.keys.front().time_s))
      return invalid(name + " at " + number(key.time_s) + " s is too far from key 0 at " +
                     number(path.keys.front().time_s) + " s (the path's duration must be a finite number of seconds)");
    for (int a = 0; a < 3; ++a) {
      const bool below = key.position_mm[a] <= room.min_mm[a] + margin_mm;
      const bool above = key.position_mm[a] >= room.max_mm[a] - margin_mm;
      if (below || above)
        return invalid(name + " at " + describe(key.position_mm) + " leaves the room through the " +
                       kWall[a][above ? 1 : 0] + " wall (room " + describe(room.min_mm) + " to " +
                       describe(room.max_mm) + ", margin " + number(margin_mm) + " mm)");
    }
  }
  return Status::ok();
}

Vec3d position_at(const ObjectPath& path, double time_s) {
  VDRIG_CHECK(!path.keys.empty(), "position_at needs a non-empty path");
  const auto& keys = path.keys;
  if (time_s <= keys.front().time_s) return keys.front().position_mm;
  if (time_s >= keys.back().time_s) return keys.back().position_mm;
  size_t k = 1;
  while (keys[k].time_s < time_s) ++k;
  const double a = (time_s - keys[k - 1].time_s) / (keys[k].time_s - keys[k - 1].time_s);
  return (1 - a) * keys[k - 1].position_mm + a * keys[k].position_mm;
}

std::vector<Vec3d> sample_path(const ObjectPath& path, int frame_count) {
  VDRIG_CHECK(!path.keys.empty() && frame_count >= 1, "sample_path needs a non-empty path and a frame");
  std::vector<Vec3d> out;
  out.reserve(frame_count);
  const double t0 = path.keys.front().time_s;
  for (int f = 0; f < frame_count; ++f) {
    // The last frame at the last key's time exactly (t0 + duration may round below it).
    out.push_back(position_at(path, frame_count == 1       ? t0
                                    : f == frame_count - 1 ? path.keys.back().time_s
                                                           : t0 + path.duration_s() * f / (frame_count - 1)));
  }
  return out;
}

Result<ObjectPath> path_from_json(const std::string& text) {
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return corrupt("not valid JSON");
  // Checked by type before reading: json::value("format", "") throws on a "format" that is not a string, and
  // get<int> wraps a version like 4294967297 to 1.
  if (!doc.is_object() || !doc.contains("format") || !doc["format"].is_string() ||
      doc["format"].get<std::string>() != kFormat)
    return corrupt(std::string("\"format\" must be \"") + kFormat + "\"");
  if (!doc.contains("version") || !doc["version"].is_number_integer() || doc["version"].get<int64_t>() != kVersion)
    return corrupt("\"version\" must be " + std::to_string(kVersion));
  if (!doc.contains("keys") || !doc["keys"].is_array()) return corrupt("\"keys\" must be an array");
  ObjectPath path;
  for (size_t k = 0; k < doc["keys"].size(); ++k) {
    const json& key = doc["keys"][k];
    const std::string name = "key " + std::to_string(k);
    if (!key.is_object() || !key.contains("time_s") || !key["time_s"].is_number())
      return corrupt(name + " needs a number \"time_s\"");
    const json& p = key.value("position_mm", json());
    if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number())
      return corrupt(name + " needs \"position_mm\", an array of 3 numbers");
    path.keys.push_back(
        {key["time_s"].get<double>(), Vec3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>())});
  }
  return path;
}

std::string path_to_json(const ObjectPath& path) {
  json keys = json::array();
  for (const PathKey& k : path.keys)
    keys.push_back({{"time_s", k.time_s}, {"position_mm", {k.position_mm.x(), k.position_mm.y(), k.position_mm.z()}}});
  return json{{"format", kFormat}, {"version", kVersion}, {"keys", keys}}.dump(2) + "\n";
}

}  // namespace vdrig::probe
