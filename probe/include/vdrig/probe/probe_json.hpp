// JSON files of what is extracted from a light probe: median-cut lights ("vdrig.probe.lights") and the SH-9
// radiance coefficients ("vdrig.probe.sh9"), as `vdrig probe lights` and `vdrig probe irradiance` write them.
// Both carry "format" and "version" (1); readers reject other formats and versions. Directions are in the probe's
// frame (probe.hpp), RGB triples in R, G, B order.
#pragma once

#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/sh_irradiance.hpp"

namespace vdrig::probe {

inline constexpr int kLightsFormatVersion = 1;
inline constexpr int kSh9FormatVersion = 1;

/// The lights of one probe: `source` names the probe file they came from (informational).
struct LightsDocument {
  std::string source;
  std::vector<DirectionalLight> lights;
};

/// Text (pretty-printed, newline-terminated) of a "vdrig.probe.lights" file: per light "direction" (unit x, y, z),
/// "azimuth_deg"/"zenith_deg" of that direction (for reading by eye), "power" (RGB, radiance x sr) and
/// "solid_angle_sr", and "cap_half_angle_deg" for a light spread over a cap (cap_cos_half_angle < 1: the lights of
/// hybrid:N and soft:N are evaluated with it, cap_lights.hpp). The median-cut region of each light is not stored.
std::string lights_to_json(const LightsDocument& document);

/// Parses lights_to_json's text. The direction is read from "direction" (the angles are ignored). Errors
/// (kCorrupt, naming the field): text that is not JSON, another format or version, a missing or mistyped field,
/// a direction that is not unit length (1e-6), a negative or non-finite power or solid angle, a cap half-angle outside
/// [0, 90) deg (optional; 0 when absent). Never throws.
Result<LightsDocument> lights_from_json(const std::string& text);

/// SH-9 radiance of one probe: `source` names the probe file it came from (informational).
struct Sh9Document {
  std::string source;
  Sh9 radiance;
};

/// Text of a "vdrig.probe.sh9" file: "radiance_coefficients" (9 RGB triples, index i = l (l + 1) + m of
/// sh_irradiance.hpp's basis), "cosine_factors" (A_0..A_2) and a note on how they combine into E(n).
std::string sh9_to_json(const Sh9Document& document);

/// Parses sh9_to_json's text ("cosine_factors" and "note" are not read: they follow from the basis). Errors
/// (kCorrupt, naming the field): not JSON, another format or version, not exactly 9 finite RGB triples. Never throws.
Result<Sh9Document> sh9_from_json(const std::string& text);

/// A room for fusion (`vdrig probe animate ROOM.json`): the box proxy and the probes placed in it.
///   {"format": "vdrig.probe.room", "version": 1, "room_mm": {"min": [x, y, z], "max": [x, y, z]},
///    "probes": [{"file": "a.exr", "position_mm": [x, y, z]}, {"file": "b.exr"}, ...]}
/// A probe without "position_mm" keeps the position stored in its file (save_probe); relative file names are
/// relative to the JSON file's folder (resolved by the caller).
struct RoomProbe {
  std::string file;
  bool has_position = false;
  Vec3d position_mm = Vec3d::Zero();
};
struct RoomDocument {
  ProxyBox room;
  std::vector<RoomProbe> probes;
};
inline constexpr int kRoomFormatVersion = 1;

/// Errors (kCorrupt, naming the field): not JSON, another format or version, a missing or mistyped field, no probes,
/// a box that is not valid (ProxyBox::is_valid's reason). Never throws.
Result<RoomDocument> room_from_json(const std::string& text);
std::string room_to_json(const RoomDocument& document);

}  // namespace vdrig::probe
