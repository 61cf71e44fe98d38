// rig_backends.hpp for a build with the simulator (VDRIG_WITH_SIM).
#include "rig_backends.hpp"

#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::app {

rig::BackendRegistry rig_backends() { return sim::simulator_and_hardware_backends(); }

Result<nlohmann::json> simulated_rig_config(const std::string& scene) {
  return sim::sim_rig_config({{"scene", scene}});
}

Result<std::optional<SurfaceSize>> simulated_surface_size(const nlohmann::json& rig_config) {
  if (!rig_config.contains("sim")) return std::optional<SurfaceSize>();
  auto scene = sim::make_scene(rig_config["sim"].value("scene", "patchwork"));
  if (!scene) return scene.error();
  return std::optional<SurfaceSize>(SurfaceSize{scene->width_mm, scene->height_mm});
}

}  // namespace vdrig::app
