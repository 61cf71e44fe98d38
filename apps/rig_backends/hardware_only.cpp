// rig_backends.hpp for a build without the simulator (VDRIG_WITH_SIM off: the `capture` preset).
#include "rig_backends.hpp"

namespace vdrig::app {

rig::BackendRegistry rig_backends() {
  rig::BackendRegistry registry;
  rig::register_hardware_backends(registry);
  return registry;
}

Result<nlohmann::json> simulated_rig_config(const std::string&) {
  return make_error(ErrorCode::kUnsupported,
                    "this vdrig is built without the simulator (VDRIG_WITH_SIM=OFF): give a rig config file");
}

// Without the simulator no backend reads a "sim" section (make_rig refuses a config with one): no rig is simulated.
Result<std::optional<SurfaceSize>> simulated_surface_size(const nlohmann::json&) {
  return std::optional<SurfaceSize>();
}

}  // namespace vdrig::app
