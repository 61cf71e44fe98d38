#include "vdrig/fitting/fit_map.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

namespace vdrig::fitting {
namespace {

/// The texel's observations split into those to fit and the held-out ones.
void split_held_out(const TexelObservations& all, const std::vector<int>& held_out, TexelObservations* fit,
                    TexelObservations* held) {
  for (size_t i = 0; i < all.size(); ++i) {
    TexelObservations* dst = std::binary_search(held_out.begin(), held_out.end(), all.view[i]) ? held : fit;
    dst->direction.push_back(all.direction[i]);
    dst->radiance.push_back(all.radiance[i]);
    dst->view.push_back(all.view[i]);
  }
}

/// Per-thread state of the linear (SH / HSH) fitters.
struct LinearFitter {
  bool hsh = false;
  HshFitOptions hsh_options;
  std::unique_ptr<ShTexelFitter> sh;

  ShExpansion fit(const TexelObservations& obs) {
    std::vector<Vec3d> dirs(obs.size());
    Eigen::MatrixXd values(obs.size(), 3);
    for (size_t i = 0; i < obs.size(); ++i) {
      dirs[i] = obs.direction[i].cast<double>();
      values.row(static_cast<Eigen::Index>(i)) = obs.radiance[i].cast<double>().transpose();
    }
    ShExpansion e;
    e.hemispherical = hsh;
    e.coeffs = hsh ? fit_hsh(hsh_options, dirs, values) : sh->fit(dirs, values);
    return e;
  }
};

struct StagedPhong {
  PhongParams params;
  FitQuality quality;
  Vec3d holdout = Vec3d::Zero();
};

}  // namespace

Result<ParameterMap> fit_parameter_map(const ObservationMap& obs, const MapFitOptions& options) {
  ModelDescriptor model = options.model;
  const bool phong_model = model.kind == "phong";
  const bool auto_lobes = phong_model && (model.auto_lobes || model.lobes == 0);
  std::string why;
  PhongFitOptions phong = options.phong;
  ShFitOptions sh = options.sh;
  HshFitOptions hsh = options.hsh;
  if (phong_model) {
    model.auto_lobes = auto_lobes;
    phong.lobes = auto_lobes ? 4 : model.lobes;
    phong.shared_shininess = model.shared_shininess;
    if (!phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else if (model.kind == "hsh") {
    hsh.bands = model.bands;
    if (!hsh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else if (model.kind == "sh-zh" || model.kind == "sh-lsop" || model.kind == "sh-ls") {
    sh.bands = model.bands;
    sh.method = model.kind == "sh-zh"     ? ShFitMethod::kZeroHemisphere
                : model.kind == "sh-lsop" ? ShFitMethod::kLsop
                                          : ShFitMethod::kLeastSquares;
    if (!sh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else {
    return make_error(ErrorCode::kInvalidArgument, "fit_parameter_map: unknown model " + model.kind);
  }
  std::vector<int> held_out = options.held_out;
  std::sort(held_out.begin(), held_out.end());
  held_out.erase(std::unique(held_out.begin(), held_out.end()), held_out.end());
  for (int v : held_out)
    if (v < 0 || v >= obs.views())
      return make_error(ErrorCode::kInvalidArgument, "held-out view " + std::to_string(v) + " is not in the map");

  const ObservationMapSpec& spec = obs.spec();
  const int total = spec.texels_s * spec.texels_t;
  // phong:auto learns the map's lobe count only at the end: stage the texels, build the map afterwards.
  std::vector<StagedPhong> staged(auto_lobes ? total : 0);
  ModelDescriptor map_model = model;
  if (auto_lobes) map_model.lobes = 4;
  ParameterMap map(map_model, auto_lobes ? 1 : spec.texels_s, auto_lobes ? 1 : spec.texels_t, spec.width_mm,
                   spec.height_mm);
  if (!held_out.empty() && !auto_lobes) map.set_holdout_rms(0, 0, Vec3d::Zero());  // channels before threads

  std::atomic<int> next{0}, done{0};
  std::mutex progress_mutex;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&] {
    LinearFitter linear;
    if (!phong_model) {
      linear.hsh = model.kind == "hsh";
      linear.hsh_options = hsh;
      if (!linear.hsh) linear.sh = std::make_unique<ShTexelFitter>(sh);
    }
    for (;;) {
      const int i = next.fetch_add(1);
      if (i >= total) return;
      const int s = i % spec.texels_s, t = i / spec.texels_s;
      TexelObservations texel, held;
      if (held_out.empty())
        texel = obs.texel(s, t);
      else
        split_held_out(obs.texel(s, t), held_out, &texel, &held);
      const bool enough = static_cast<int>(texel.size()) >= options.min_observations;
      FitQuality q, hq;
      q.samples = static_cast<int>(texel.size());
      // Distinct texels: no two threads write the same map element.
      if (phong_model) {
        PhongParams params;
        if (enough) {
          const PhongFit fit = auto_lobes ? fit_phong_auto(texel, phong, 4) : fit_phong(texel, phong);
          params = fit.params;
          q = fit.quality;
          if (held.size()) hq = measure_quality(params, held);
        }
        if (auto_lobes) {
          staged[i] = {params, q, hq.rms};
        } else {
          map.set_phong(s, t, params);
        }
      } else if (enough) {
        const ShExpansion e = linear.fit(texel);
        map.set_sh(s, t, e.coeffs);
        q = measure_quality(e, texel);
        if (held.size()) hq = measure_quality(e, held);
      }
      if (!auto_lobes) {
        map.set_quality(s, t, q);
        if (!held_out.empty()) map.set_holdout_rms(s, t, hq.rms);
      }
      const int d = done.fetch_add(1) + 1;
      if (options.on_progress && (d % 256 == 0 || d == total)) {
        std::lock_guard lock(progress_mutex);
        MapFitProgress p;
        p.texels_done = d;
        p.texels_total = total;
        p.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        p.eta_s = p.elapsed_s / d * (total - d);
        options.on_progress(p);
      }
    }
  };
  const int threads = options.threads > 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (int k = 0; k < threads; ++k) pool.emplace_back(worker);
  for (auto& th : pool) th.join();

  if (auto_lobes) {
    int max_lobes = 1;
    for (const auto& st : staged) max_lobes = std::max(max_lobes, static_cast<int>(st.params.lobes.size()));
    map_model.lobes = max_lobes;
    map = ParameterMap(map_model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    for (int i = 0; i < total; ++i) {
      const int s = i % spec.texels_s, t = i / spec.texels_s;
      map.set_phong(s, t, staged[i].params);
      map.at("lobes", s, t) = static_cast<float>(staged[i].params.lobes.size());
      map.set_quality(s, t, staged[i].quality);
      if (!held_out.empty()) map.set_holdout_rms(s, t, staged[i].holdout);
    }
  }
  return map;
}

}  // namespace vdrig::fitting
