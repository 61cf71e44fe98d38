// The rig backends the executables (vdrig, vdrigd) offer, and what they know of a simulated rig. Two
// implementations, chosen by CMake (apps/CMakeLists.txt): with_simulator.cpp when the simulator is built
// (VDRIG_WITH_SIM), hardware_only.cpp otherwise, so a capture-only build links no simulator and no source here
// carries an #if.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vdrig/core/result.hpp"
#include "vdrig/rig/registry.hpp"

namespace vdrig::app {

/// Every backend of this build: the hardware compiled into rig, and the simulator's ("sim") when it is built.
rig::BackendRegistry rig_backends();

/// The rig config of a simulated rig showing `scene` (a built-in name or a scene FILE.json): `--rig sim`, vdrigd
/// without --rig. kUnsupported in a build without the simulator.
Result<nlohmann::json> simulated_rig_config(const std::string& scene);

struct SurfaceSize {
  double width_mm = 0.0, height_mm = 0.0;
};
/// The size of the surface a simulated rig shows (its "sim" section's scene); nullopt for a rig that is not
/// simulated, whose surface the manifest's defaults describe. An unreadable scene is its error.
Result<std::optional<SurfaceSize>> simulated_surface_size(const nlohmann::json& rig_config);

}  // namespace vdrig::app
