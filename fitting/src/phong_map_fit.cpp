// PhongModel::fit_map: every texel fitted on its own and staged, then (shared lights) the lights estimated from all
// texels' lobes and each texel refitted toward them, then the map built from the staged texels (phong_map_fit.hpp).
#include "phong_map_fit.hpp"

#include <atomic>

#include <fmt/format.h>

#include "vdrig/core/log.hpp"

namespace vdrig::fitting {
namespace phong_map_fit {

/// The lights from the lobe rays (estimate_point_lights), logged; "vdrig.shared_lights" of them in *attribute.
Result<std::vector<EstimatedLight>> estimate_and_log_lights(const std::vector<LobeRay>& rays,
                                                            const LightEstimationOptions& options,
                                                            std::string* attribute) {
  auto lights = estimate_point_lights(rays, options);
  if (!lights) return lights.error();
  auto logger = log::get("fitting");
  attribute->clear();
  if (lights->empty()) {
    logger->warn("shared lights: no light explains enough texels' lobes; every texel keeps its own fit");
    return lights;
  }
  for (const EstimatedLight& l : lights.value()) {
    const Vec3d& v = l.at_infinity ? l.direction : l.position_mm;
    *attribute += fmt::format("{}{} {:.3f} {:.3f} {:.3f}", attribute->empty() ? "" : "; ",
                              l.at_infinity ? "direction" : "point", v.x(), v.y(), v.z());
  }
  for (const EstimatedLight& l : lights.value())
    if (l.at_infinity)
      logger->info("shared lights: distant light toward ({:.3f}, {:.3f}, {:.3f}), {} texel lobes, rms {:.2f} deg",
                   l.direction.x(), l.direction.y(), l.direction.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
    else
      logger->info("shared lights: point light at ({:.1f}, {:.1f}, {:.1f}) mm, {} texel lobes, rms {:.2f} deg",
                   l.position_mm.x(), l.position_mm.y(), l.position_mm.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
  return lights;
}

}  // namespace phong_map_fit

using namespace phong_map_fit;

Result<ParameterMap> PhongModel::fit_map(const MapFitContext& context) const {
  auto f = PhongMapFit::make(*this, context.options, context.spec);
  if (!f) return f.error();
  const ObservationMapSpec& spec = context.spec;
  const int total = spec.texels_s * spec.texels_t;
  const bool shared_lights = context.options.shared_lights;
  const int passes = shared_lights ? 2 : 1;

  // Texels are staged and the map built at the end: phong:auto learns the map's lobe count only then, and the
  // shared-lights pass may replace a texel's fit.
  std::vector<StagedPhong> staged(total);

  // Pass 1: every texel on its own.
  VDRIG_TRY(context.for_each_texel(
      0, passes, [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
        f->fit_free(texel, held, &staged[static_cast<size_t>(t) * spec.texels_s + s]);
      }));

  // Pass 2 (shared lights): the lights from every texel's lobes, then each texel refitted with its lobes pointing at
  // them; the refit replaces the free fit where its BIC is lower (it has 2 parameters fewer per lobe, so it wins
  // wherever it fits as well, and loses where the texel's normal or light differs, e.g. a bumpy patch) and where it
  // stays within the free fit between the views (phong_refit_within_free_fit).
  std::string lights_attribute;
  if (shared_lights) {
    auto lights = estimate_and_log_lights(lobe_rays(staged, spec, kMaxLobeRays), f->light_options(), &lights_attribute);
    if (!lights) return lights.error();
    if (!lights->empty()) {
      std::atomic<int> replaced{0};
      VDRIG_TRY(context.for_each_texel(
          1, passes, [&](int, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
            if (f->refit(s, t, texel, held, lights.value(), &staged[static_cast<size_t>(t) * spec.texels_s + s]))
              replaced.fetch_add(1);
          }));
      log::get("fitting")->info("shared lights: {} of {} texels fitted with the lights' directions", replaced.load(),
                                total);
    }
  }
  return f->build_map([&](int i) -> const StagedPhong& { return staged[static_cast<size_t>(i)]; }, lights_attribute);
}

}  // namespace vdrig::fitting
