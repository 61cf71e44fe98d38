// The phong:1 map a perfect fit of a simulated scene would give: each texel the scene's own Phong parameters at the
// texel's centre (texels off every material left unset). For tests of what reads a map (render, eval, the viewers)
// that are not about fitting.
#pragma once

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/model.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/sim/scene.hpp"

namespace vdrig::test {

/// `texels` x `texels` over the scene's surface, with Kd scaled by `kd_scale` (1: the truth).
inline fitting::ParameterMap phong_truth_map(const sim::Scene& scene, int texels, double kd_scale = 1.0) {
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), texels, texels, scene.width_mm, scene.height_mm);
  for (int t = 0; t < texels; ++t)
    for (int s = 0; s < texels; ++s) {
      const auto truth = scene.phong_truth(texel_centre_mm(s, t, texels, texels, scene.width_mm, scene.height_mm));
      if (!truth) continue;
      fitting::PhongParams p;
      p.kd = truth->kd * kd_scale;
      p.lobes = {{truth->ks, truth->mirror_dir, truth->shininess}};
      fitting::set_phong_texel(map, s, t, p);
    }
  return map;
}

}  // namespace vdrig::test
