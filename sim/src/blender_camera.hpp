// The "blender" camera backend's registration (sim_rig.cpp calls it with the simulator's shared world, whose stage
// pose, scene, intrinsics and sensor the Blender camera uses), and the compiled-in driver script.
#pragma once

#include <functional>
#include <memory>

#include "vdrig/rig/registry.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::sim {

/// sim/blender/vdrig_blender.py, compiled in (generated blender_script.cpp).
const char* blender_driver_script();

using WorldOf = std::function<Result<std::shared_ptr<SimWorld>>(rig::RigContext&)>;
void register_blender_camera(rig::BackendRegistry& registry, WorldOf world_of);

}  // namespace vdrig::sim
