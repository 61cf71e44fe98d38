// The fitting tests' GGX sample (tests/fitting/test_ggx.cpp, tests/pipeline/test_session_light.cpp): the simulator's
// `bands` surface made of one GGX material.
#pragma once

#include "vdrig/sim/scene.hpp"

namespace vdrig::fitting::test_support {

/// The simulator's `bands` surface (1 m, its one point light at (1.5, 1.5, 2) m) made of one GGX material, its
/// patches and markers removed.
inline sim::Scene ggx_scene(const Vec3d& kd, const Vec3d& f0, double alpha) {
  sim::Scene scene = sim::make_scene("bands").value();
  sim::Material ggx{"ggx", kd};
  ggx.kind = sim::MaterialKind::kGgx;
  ggx.roughness = alpha;
  ggx.f0 = f0;
  scene.materials = {ggx};
  scene.patches.clear();
  scene.markers.clear();
  return scene;
}

}  // namespace vdrig::fitting::test_support
