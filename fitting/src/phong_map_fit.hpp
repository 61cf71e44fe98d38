// Phong's map fit (private to fitting/), shared by PhongModel::fit_map (phong_map_fit.cpp) and its tiled fit
// (phong_tile_records.cpp): every texel is fitted on its own and staged (StagedPhong) until the map's lobe count is
// known (phong:auto) and the shared-lights pass has refitted the texels with their lobes at the lights' mirror
// directions; then the map is built from the staged texels.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/fitting/phong_model.hpp"

namespace vdrig::fitting::phong_map_fit {

inline constexpr int kMaxLobes = 4;
/// Lobe rays handed to the light estimation at most (an even subsample: RANSAC needs many rays, not all of a map's).
inline constexpr size_t kMaxLobeRays = 20000;

/// The per-texel fit options of `model` from the map's: its PhongFitOptions with the lobe count and shininess sharing
/// of the name (phong:auto: up to kMaxLobes).
inline PhongFitOptions texel_fit_options(const PhongModel& model, const MapFitOptions& options) {
  PhongFitOptions phong = options.model_options.get<PhongFitOptions>();
  phong.lobes = model.auto_lobes() ? kMaxLobes : model.lobes();
  phong.shared_shininess = model.shared_shininess();
  return phong;
}

/// A texel's Phong fit, kept until the map's lobe count is known (phong:auto) and the shared-lights pass has run.
struct StagedPhong {
  PhongParams params;
  FitQuality quality;
  Vec3d holdout = Vec3d::Zero();
  double bic = std::numeric_limits<double>::infinity();  // of the fit as minimised (phong_bic)
  bool shared_lights = false;                            // directions from the estimated lights
  int capped_lobes = 0;                                  // lobes whose shininess the sampling bounds (PhongFit)
};

/// BIC of a fit of `obs` (as phong_bic: RSS of the residuals as minimised = 2 cost, n = 3 x observations).
inline double fit_bic(const PhongFit& fit, const TexelObservations& obs, int parameters) {
  const int n = static_cast<int>(3 * obs.size());
  double sq = 0;
  for (size_t i = 0; i < obs.size(); ++i) sq += obs.radiance[i].cast<double>().squaredNorm();
  return phong_bic(2.0 * fit.cost, n, parameters, std::sqrt(sq / std::max(1, n)));
}

/// The rays toward the lights of one texel's fitted lobes that carry energy (lights.hpp), in lobe order.
inline std::vector<LobeRay> texel_lobe_rays(const StagedPhong& st, int s, int t, const ObservationMapSpec& spec) {
  std::vector<LobeRay> rays;
  const PhongParams& p = st.params;
  for (const PhongLobe& lobe : p.lobes)
    // A lobe far below the diffuse level is the fit's way of saying "no highlight": its direction is noise.
    if (lobe.ks.maxCoeff() > 1e-3 * std::max(p.kd.maxCoeff(), 1e-12))
      rays.push_back(
          lobe_ray(texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm), lobe.direction));
  return rays;
}

/// At most `max_rays` of them, an even subsample (RANSAC needs many rays, not all of a 512 x 512 map's).
inline std::vector<LobeRay> subsample_rays(std::vector<LobeRay> rays, size_t max_rays) {
  if (rays.size() <= max_rays) return rays;
  std::vector<LobeRay> subsample;
  for (size_t k = 0; k < max_rays; ++k) subsample.push_back(rays[k * rays.size() / max_rays]);
  return subsample;
}

/// Rays toward the lights from every texel, in texel order (t * S + s), subsampled.
inline std::vector<LobeRay> lobe_rays(const std::vector<StagedPhong>& staged, const ObservationMapSpec& spec,
                                      size_t max_rays) {
  std::vector<LobeRay> rays;
  for (size_t i = 0; i < staged.size(); ++i) {
    const int s = static_cast<int>(i % spec.texels_s), t = static_cast<int>(i / spec.texels_s);
    for (const LobeRay& r : texel_lobe_rays(staged[i], s, t, spec)) rays.push_back(r);
  }
  return subsample_rays(std::move(rays), max_rays);
}

/// What fit_map and the tiled fit share: the checked options and the per-texel steps of both passes.
struct PhongMapFit {
  const PhongModel* model = nullptr;
  MapFitOptions options;  // a copy: the tiled fit outlives the caller's
  ObservationMapSpec spec;
  PhongFitOptions phong;
  bool auto_lobes = false;

  /// The fit of `model` with the options, checked by PhongModel::check_options.
  static Result<PhongMapFit> make(const PhongModel& model, const MapFitOptions& options,
                                  const ObservationMapSpec& spec) {
    VDRIG_TRY(model.check_options(options));
    PhongMapFit f;
    f.model = &model;
    f.options = options;
    f.spec = spec;
    f.auto_lobes = model.auto_lobes();
    f.phong = texel_fit_options(model, options);
    return f;
  }

  /// Pass 1: the texel on its own.
  void fit_free(const TexelObservations& texel, const TexelObservations& held, StagedPhong* st) const {
    const bool enough = static_cast<int>(texel.size()) >= options.min_observations;
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    if (enough) {
      const PhongFit fit = auto_lobes ? fit_phong_auto(texel, phong, kMaxLobes) : fit_phong(texel, phong);
      st->params = fit.params;
      q = fit.quality;
      if (held.size()) hq = measure_quality(fit.params, held);
      st->bic = fit_bic(fit, texel,
                        phong_parameter_count(static_cast<int>(fit.params.lobes.size()), phong.shared_shininess,
                                              !phong.fixed_directions.empty()));
      st->capped_lobes = fit.capped_lobes;
    }
    st->quality = q;
    st->holdout = hq.rms;
  }

  /// Pass 2: the texel refitted with its lobes at the lights' mirror directions; true when the refit replaced *st.
  bool refit(int s, int t, const TexelObservations& texel, const TexelObservations& held,
             const std::vector<EstimatedLight>& lights, StagedPhong* st) const {
    if (static_cast<int>(texel.size()) < options.min_observations) return false;
    const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    PhongFitOptions fixed = phong;
    fixed.lobes = static_cast<int>(lights.size());
    fixed.fixed_directions.clear();
    for (const EstimatedLight& l : lights) fixed.fixed_directions.push_back(mirror_direction_at(l, p));
    // A light below the texel's horizon leaves no highlight to fit: keep the free fit.
    for (const Vec3d& d : fixed.fixed_directions)
      if (!(d.z() >= 0.0)) return false;
    const PhongFit fit = fit_phong(texel, fixed);
    const double bic = fit_bic(
        fit, texel, phong_parameter_count(static_cast<int>(fit.params.lobes.size()), fixed.shared_shininess, true));
    if (!(bic <= st->bic)) return false;
    // The BIC sees only the observed directions: between them the refit must stay within the free fit's bound.
    if (!phong_refit_within_free_fit(fit.params, st->params, texel)) return false;
    st->capped_lobes = fit.capped_lobes;
    st->params = fit.params;
    st->quality = fit.quality;
    st->holdout = held.size() ? measure_quality(fit.params, held).rms : Vec3d::Zero();
    st->bic = bic;
    st->shared_lights = true;
    return true;
  }

  LightEstimationOptions light_options() const {
    LightEstimationOptions l = options.lights;
    l.max_lights = std::min(l.max_lights, auto_lobes ? kMaxLobes : phong.lobes);
    return l;
  }

  /// The map of the staged texels (staged(i) is texel i = t * S + s).
  ParameterMap build_map(const std::function<const StagedPhong&(int i)>& staged,
                         const std::string& lights_attribute) const {
    const int total = spec.texels_s * spec.texels_t;
    int map_lobes = model->lobes();
    if (auto_lobes) {
      map_lobes = 1;
      for (int i = 0; i < total; ++i) map_lobes = std::max(map_lobes, static_cast<int>(staged(i).params.lobes.size()));
    }
    const auto m = std::static_pointer_cast<const PhongModel>(model->with_lobes(map_lobes));
    ParameterMap map(m, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    const bool shared_lights = options.shared_lights;
    const bool holding_out = !options.held_out.empty();
    if (shared_lights) {
      map.add_channel("shared_lights");
      map.image().string_attributes["vdrig.shared_lights"] = lights_attribute;
    }
    // Where the map guesses: lobes whose width the sampling bounds (phong.hpp, "Between the samples").
    const bool support_bounded = phong.lobe_support > 0;
    if (support_bounded) map.add_channel(kCappedLobesChannel);
    for (int i = 0; i < total; ++i) {
      const int s = i % spec.texels_s, t = i / spec.texels_s;
      const StagedPhong& st = staged(i);
      map.set_parameters(s, t, m->parameters_of(st.params));
      if (shared_lights) map.at("shared_lights", s, t) = st.shared_lights ? 1.0f : 0.0f;
      if (support_bounded) map.at(kCappedLobesChannel, s, t) = static_cast<float>(st.capped_lobes);
      map.set_quality(s, t, st.quality);
      if (holding_out) map.set_holdout_rms(s, t, st.holdout);
    }
    return map;
  }
};

/// The lights from the lobe rays (estimate_point_lights), logged; "vdrig.shared_lights" of them in *attribute.
Result<std::vector<EstimatedLight>> estimate_and_log_lights(const std::vector<LobeRay>& rays,
                                                            const LightEstimationOptions& options,
                                                            std::string* attribute);

}  // namespace vdrig::fitting::phong_map_fit
