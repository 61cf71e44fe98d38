// The rig's lamp as a rig config states it: an optional measured position (and intensity) in the "light" section,
// beside the light backend's own settings, which a BRDF fit takes as the session's light (docs/models.md, "The
// light"; pipeline/session_light.hpp). The lamp is fixed to the platform (kinematics.hpp), so one position serves
// every view:
//   "light": { "backend": "gpio", ...,
//              "position_mm": [x, y, z],        the lamp's centre, mm
//              "position_frame": "surface",     "surface" (default: the surface frame, docs/conventions.md) or
//                                               "platter" (the platter frame, kinematics.hpp: the world frame with
//                                               both axes at their true zero; the surface's offset and tilt on the
//                                               platter are then the rig geometry's)
//              "intensity": 1.2e7,              optional, a number or [r, g, b], the simulator's relative units (a
//                                               white Lambertian surface facing it at d mm has radiance I / d^2);
//                                               absent: the fit fixes the scale (irradiance 1 at the sample's centre)
//              "position_source": "tape, 2026-12-04" }   optional free text, not read
// The keys belong to the registry, not to the backend: BackendRegistry strips them before the backend's settings
// parser and factory see the section (a rig without a switchable lamp still needs a light backend for them).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/result.hpp"
#include "vdrig/rig/kinematics.hpp"

namespace vdrig::rig {

struct LampPosition {
  enum class Frame { kSurface, kPlatter };
  Vec3d position_mm = Vec3d::Zero();
  Frame frame = Frame::kSurface;
  std::optional<Vec3d> intensity;  // relative units (above); unset: not measured
  std::string source;              // free text ("position_source")
};

/// Whether `key` is one of the lamp's keys of a "light" section (above).
bool is_lamp_key(const std::string& key);
/// The section without the lamp's keys: what the light backend's parser and factory get.
nlohmann::json without_lamp_keys(const nlohmann::json& light_section);
/// The lamp of a "light" section: nullopt when it states no position; kInvalidArgument naming every problem (a
/// position that is not three finite numbers, an unknown frame, a negative or non-finite intensity, "intensity" or
/// "position_frame" without "position_mm").
Result<std::optional<LampPosition>> lamp_from_light_section(const nlohmann::json& light_section);
/// The lamp's keys of a section for `lamp` (what lamp_from_light_section reads back).
nlohmann::json lamp_keys(const LampPosition& lamp);
/// The lamp's position in the surface frame (mm): as stated, or from the platter frame through the geometry's
/// surface offset and pan-axis tilt (p_platter = A p_surface + offset, kinematics.hpp).
Vec3d lamp_in_surface_frame(const LampPosition& lamp, const RigGeometry& geometry);

}  // namespace vdrig::rig
