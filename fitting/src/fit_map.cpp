#include "vdrig/fitting/fit_map.hpp"

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

namespace vdrig::fitting {

Result<ParameterMap> fit_parameter_map(const ObservationMap& obs, const MapFitOptions& options) {
  ModelDescriptor model = options.model;
  if (model.kind != "phong")
    return make_error(ErrorCode::kUnsupported, "fit_parameter_map: model " + model.kind + " not wired here yet");
  if (model.lobes == 0) model.lobes = 1;  // "auto" resolved per texel up to the stored lobe count (BIC: see docs)
  PhongFitOptions phong = options.phong;
  phong.lobes = model.lobes;
  phong.shared_shininess = model.shared_shininess;
  std::string why;
  if (!phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);

  const ObservationMapSpec& spec = obs.spec();
  ParameterMap map(model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  const int total = spec.texels_s * spec.texels_t;
  std::atomic<int> next{0}, done{0};
  std::mutex progress_mutex;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&] {
    for (;;) {
      const int i = next.fetch_add(1);
      if (i >= total) return;
      const int s = i % spec.texels_s, t = i / spec.texels_s;
      const TexelObservations texel = obs.texel(s, t);
      if (static_cast<int>(texel.size()) >= options.min_observations) {
        const PhongFit fit = fit_phong(texel, phong);
        map.set_phong(s, t, fit.params);  // distinct texels: no two threads write the same element
        map.set_quality(s, t, fit.quality);
      } else {
        FitQuality q;
        q.samples = static_cast<int>(texel.size());
        map.set_quality(s, t, q);
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
  return map;
}

}  // namespace vdrig::fitting
