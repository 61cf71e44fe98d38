#include "vdrig/rig/registry.hpp"

namespace vdrig::rig {

// Each hardware backend adds itself here, guarded by the build option of its library.
void register_hardware_backends(BackendRegistry& /*registry*/) {}

}  // namespace vdrig::rig
