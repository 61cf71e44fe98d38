#include "vdrig/fitting/fit_map.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "vdrig/core/log.hpp"
#include "vdrig/fitting/lights.hpp"

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

/// Where the texels come from: a grid of tiles, each loaded by one worker at a time. load(tile_s, tile_t) returns
/// an accessor for the observations of the tile's texels (global texel coordinates, every view).
struct TileGrid {
  ObservationMapSpec spec;
  int views = 0;
  int tile_size = 32;
  int tiles_s() const { return (spec.texels_s + tile_size - 1) / tile_size; }
  int tiles_t() const { return (spec.texels_t + tile_size - 1) / tile_size; }
};
using TexelAccessor = std::function<TexelObservations(int s, int t)>;
using TileLoader = std::function<Result<TexelAccessor>(int tile_s, int tile_t)>;

/// A texel's Phong fit, kept until the map's lobe count is known (phong:auto) and the shared-lights pass has run.
struct StagedPhong {
  PhongParams params;
  FitQuality quality;
  Vec3d holdout = Vec3d::Zero();
  double bic = std::numeric_limits<double>::infinity();  // of the fit as minimised (phong_bic)
  bool shared_lights = false;                            // directions from the estimated lights
};

/// BIC of a fit of `obs` (as phong_bic: RSS of the residuals as minimised = 2 cost, n = 3 x observations).
double fit_bic(const PhongFit& fit, const TexelObservations& obs, int parameters) {
  const int n = static_cast<int>(3 * obs.size());
  double sq = 0;
  for (size_t i = 0; i < obs.size(); ++i) sq += obs.radiance[i].cast<double>().squaredNorm();
  return phong_bic(2.0 * fit.cost, n, parameters, std::sqrt(sq / std::max(1, n)));
}

/// Options checked and resolved against the map: the model's settings pushed into the per-model options.
struct ResolvedFit {
  ModelDescriptor model;
  bool phong_model = false;
  bool auto_lobes = false;
  PhongFitOptions phong;
  ShFitOptions sh;
  HshFitOptions hsh;
  std::vector<int> held_out;  // sorted, unique
};

Result<ResolvedFit> resolve(const MapFitOptions& options, int views) {
  ResolvedFit r;
  r.model = options.model;
  r.phong_model = r.model.kind == "phong";
  r.auto_lobes = r.phong_model && (r.model.auto_lobes || r.model.lobes == 0);
  r.phong = options.phong;
  r.sh = options.sh;
  r.hsh = options.hsh;
  std::string why;
  if (r.phong_model) {
    r.model.auto_lobes = r.auto_lobes;
    r.phong.lobes = r.auto_lobes ? 4 : r.model.lobes;
    r.phong.shared_shininess = r.model.shared_shininess;
    if (!r.phong.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else if (r.model.kind == "hsh") {
    r.hsh.bands = r.model.bands;
    if (!r.hsh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else if (r.model.kind == "sh-zh" || r.model.kind == "sh-lsop" || r.model.kind == "sh-ls") {
    r.sh.bands = r.model.bands;
    r.sh.method = r.model.kind == "sh-zh"     ? ShFitMethod::kZeroHemisphere
                  : r.model.kind == "sh-lsop" ? ShFitMethod::kLsop
                                              : ShFitMethod::kLeastSquares;
    if (!r.sh.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  } else {
    return make_error(ErrorCode::kInvalidArgument, "fit_parameter_map: unknown model " + r.model.kind);
  }
  if (options.shared_lights) {
    if (!r.phong_model)
      return make_error(ErrorCode::kInvalidArgument, "shared_lights applies to Phong models only, not " + r.model.kind);
    if (!options.phong.fixed_directions.empty())
      return make_error(ErrorCode::kInvalidArgument, "shared_lights sets each texel's directions itself");
    if (!options.lights.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  }
  if (r.auto_lobes && !options.phong.fixed_directions.empty())
    return make_error(ErrorCode::kInvalidArgument, "phong:auto does not take fixed directions");
  if (options.min_observations < 1)
    return make_error(ErrorCode::kInvalidArgument, "fit_parameter_map: min_observations must be >= 1");
  if (options.threads < 0 || options.threads > MapFitOptions::kMaxThreads)
    return make_error(ErrorCode::kInvalidArgument, "threads must be in [0, " +
                                                       std::to_string(MapFitOptions::kMaxThreads) +
                                                       "] (0: all cores), got " + std::to_string(options.threads));
  r.held_out = options.held_out;
  std::sort(r.held_out.begin(), r.held_out.end());
  r.held_out.erase(std::unique(r.held_out.begin(), r.held_out.end()), r.held_out.end());
  for (int v : r.held_out)
    if (v < 0 || v >= views)
      return make_error(ErrorCode::kInvalidArgument, "held-out view " + std::to_string(v) + " is not in the map");
  return r;
}

int worker_count(int threads) {
  return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// Runs `fit_texel(worker, s, t, observations)` on every texel, tiles handed out to worker_count(threads) workers
/// (worker = 0..count-1, for per-thread state); stops at the first tile that cannot be loaded and returns its error.
/// Progress is reported per texel, serialised.
Status for_each_texel(const TileGrid& grid, const TileLoader& load, int threads,
                      const std::function<void(int worker, int s, int t, const TexelObservations& all)>& fit_texel,
                      const std::function<void(const MapFitProgress&)>& on_progress) {
  const int tiles = grid.tiles_s() * grid.tiles_t();
  const int total = grid.spec.texels_s * grid.spec.texels_t;
  std::atomic<int> next{0}, done{0};
  std::atomic<bool> failed{false};
  std::mutex mutex;  // guards `error` and serialises on_progress
  Status error = Status::ok();
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&](int worker_index) {
    for (;;) {
      const int k = next.fetch_add(1);
      if (k >= tiles || failed.load()) return;
      const int tile_s = k % grid.tiles_s(), tile_t = k / grid.tiles_s();
      auto texels = load(tile_s, tile_t);
      if (!texels) {
        std::lock_guard lock(mutex);
        if (!failed.exchange(true)) error = texels.error();
        return;
      }
      const int s0 = tile_s * grid.tile_size, t0 = tile_t * grid.tile_size;
      const int s1 = std::min(s0 + grid.tile_size, grid.spec.texels_s);
      const int t1 = std::min(t0 + grid.tile_size, grid.spec.texels_t);
      for (int t = t0; t < t1; ++t)
        for (int s = s0; s < s1; ++s) {
          fit_texel(worker_index, s, t, (*texels)(s, t));
          const int d = done.fetch_add(1) + 1;
          if (on_progress && (d % 256 == 0 || d == total)) {
            std::lock_guard lock(mutex);
            MapFitProgress p;
            p.texels_done = d;
            p.texels_total = total;
            p.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            p.eta_s = p.elapsed_s / d * (total - d);
            on_progress(p);
          }
        }
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < worker_count(threads); ++i) pool.emplace_back(worker, i);
  for (auto& th : pool) th.join();
  return error;
}

/// The held-out split of a texel's observations (all of them in `fit` when nothing is held out).
void split_texel(const TexelObservations& all, const std::vector<int>& held_out, TexelObservations* fit,
                 TexelObservations* held) {
  if (held_out.empty())
    *fit = all;
  else
    split_held_out(all, held_out, fit, held);
}

/// Rays toward the lights from every texel whose fitted lobes carry energy (lights.hpp), at most `max_rays`
/// (an even subsample: RANSAC needs many rays, not all of a 512 x 512 map's).
std::vector<LobeRay> lobe_rays(const std::vector<StagedPhong>& staged, const ObservationMapSpec& spec,
                               size_t max_rays) {
  std::vector<LobeRay> rays;
  for (size_t i = 0; i < staged.size(); ++i) {
    const PhongParams& p = staged[i].params;
    const int s = static_cast<int>(i % spec.texels_s), t = static_cast<int>(i / spec.texels_s);
    for (const PhongLobe& lobe : p.lobes)
      // A lobe far below the diffuse level is the fit's way of saying "no highlight": its direction is noise.
      if (lobe.ks.maxCoeff() > 1e-3 * std::max(p.kd.maxCoeff(), 1e-12))
        rays.push_back(lobe_ray(texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm),
                                lobe.direction));
  }
  if (rays.size() <= max_rays) return rays;
  std::vector<LobeRay> subsample;
  for (size_t k = 0; k < max_rays; ++k) subsample.push_back(rays[k * rays.size() / max_rays]);
  return subsample;
}

Result<ParameterMap> fit_tiles(const TileGrid& grid, const TileLoader& load, const MapFitOptions& options) {
  auto resolved = resolve(options, grid.views);
  if (!resolved) return resolved.error();
  const ResolvedFit& r = resolved.value();
  const ObservationMapSpec& spec = grid.spec;
  const int total = spec.texels_s * spec.texels_t;
  const bool holding_out = !r.held_out.empty();
  const bool shared_lights = options.shared_lights;
  const int passes = shared_lights ? 2 : 1;

  // Phong texels are staged and the map built at the end: phong:auto learns the map's lobe count only then, and the
  // shared-lights pass may replace a texel's fit. Linear models go straight into the map.
  std::vector<StagedPhong> staged(r.phong_model ? total : 0);
  ParameterMap map;
  if (!r.phong_model) {
    map = ParameterMap(r.model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
    if (holding_out) map.set_holdout_rms(0, 0, Vec3d::Zero());  // channels before threads
  }
  // Progress over every pass: pass k reports texels_done + k x total of passes x total.
  auto progress_of_pass = [&](int pass) -> std::function<void(const MapFitProgress&)> {
    if (!options.on_progress) return nullptr;
    return [&, pass](const MapFitProgress& p) {
      MapFitProgress q = p;
      q.texels_done = p.texels_done + pass * total;
      q.texels_total = passes * total;
      q.eta_s = q.texels_done ? p.elapsed_s / q.texels_done * (q.texels_total - q.texels_done) : 0.0;
      options.on_progress(q);
    };
  };

  // One linear fitter per worker (ShTexelFitter holds the Gram matrix and work space), made on first use.
  std::vector<std::unique_ptr<LinearFitter>> fitters(worker_count(options.threads));
  auto linear_fitter = [&](int worker) -> LinearFitter& {
    auto& f = fitters[worker];
    if (!f) {
      f = std::make_unique<LinearFitter>();
      f->hsh = r.model.kind == "hsh";
      f->hsh_options = r.hsh;
      if (!f->hsh) f->sh = std::make_unique<ShTexelFitter>(r.sh);
    }
    return *f;
  };

  // Pass 1: every texel on its own.
  auto fit_texel = [&](int worker, int s, int t, const TexelObservations& all) {
    TexelObservations texel, held;
    split_texel(all, r.held_out, &texel, &held);
    const bool enough = static_cast<int>(texel.size()) >= options.min_observations;
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    // Distinct texels: no two threads write the same map element.
    if (r.phong_model) {
      StagedPhong& st = staged[static_cast<size_t>(t) * spec.texels_s + s];
      if (enough) {
        const PhongFit fit = r.auto_lobes ? fit_phong_auto(texel, r.phong, 4) : fit_phong(texel, r.phong);
        st.params = fit.params;
        q = fit.quality;
        if (held.size()) hq = measure_quality(fit.params, held);
        st.bic = fit_bic(fit, texel,
                         phong_parameter_count(static_cast<int>(fit.params.lobes.size()), r.phong.shared_shininess,
                                               !r.phong.fixed_directions.empty()));
      }
      st.quality = q;
      st.holdout = hq.rms;
      return;
    }
    if (enough) {
      const ShExpansion e = linear_fitter(worker).fit(texel);
      map.set_sh(s, t, e.coeffs);
      q = measure_quality(e, texel);
      if (held.size()) hq = measure_quality(e, held);
    }
    map.set_quality(s, t, q);
    if (holding_out) map.set_holdout_rms(s, t, hq.rms);
  };
  VDRIG_TRY(for_each_texel(grid, load, options.threads, fit_texel, progress_of_pass(0)));
  if (!r.phong_model) return map;

  // Pass 2 (shared lights): the lights from every texel's lobes, then each texel refitted with its lobes pointing at
  // them; the refit replaces the free fit where its BIC is lower (it has 2 parameters fewer per lobe, so it wins
  // wherever it fits as well, and loses where the texel's normal or light differs, e.g. a bumpy patch).
  int texels_on_lights = 0;
  std::string lights_attribute;
  if (shared_lights) {
    LightEstimationOptions light_options = options.lights;
    light_options.max_lights = std::min(light_options.max_lights, r.auto_lobes ? 4 : r.phong.lobes);
    auto lights = estimate_point_lights(lobe_rays(staged, spec, 20000), light_options);
    if (!lights) return lights.error();
    auto logger = log::get("fitting");
    if (lights->empty()) {
      logger->warn("shared lights: no light explains enough texels' lobes; every texel keeps its own fit");
    } else {
      for (const EstimatedLight& l : lights.value()) {
        const Vec3d& v = l.at_infinity ? l.direction : l.position_mm;
        lights_attribute += fmt::format("{}{} {:.3f} {:.3f} {:.3f}", lights_attribute.empty() ? "" : "; ",
                                        l.at_infinity ? "direction" : "point", v.x(), v.y(), v.z());
      }
      for (const EstimatedLight& l : lights.value())
        if (l.at_infinity)
          logger->info("shared lights: distant light toward ({:.3f}, {:.3f}, {:.3f}), {} texel lobes, rms {:.2f} deg",
                       l.direction.x(), l.direction.y(), l.direction.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
        else
          logger->info("shared lights: point light at ({:.1f}, {:.1f}, {:.1f}) mm, {} texel lobes, rms {:.2f} deg",
                       l.position_mm.x(), l.position_mm.y(), l.position_mm.z(), l.inliers, rad_to_deg(l.rms_angle_rad));
      std::atomic<int> replaced{0};
      auto refit_texel = [&](int, int s, int t, const TexelObservations& all) {
        TexelObservations texel, held;
        split_texel(all, r.held_out, &texel, &held);
        if (static_cast<int>(texel.size()) < options.min_observations) return;
        const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
        PhongFitOptions fixed = r.phong;
        fixed.lobes = static_cast<int>(lights->size());
        fixed.fixed_directions.clear();
        for (const EstimatedLight& l : lights.value()) fixed.fixed_directions.push_back(mirror_direction_at(l, p));
        // A light below the texel's horizon leaves no highlight to fit: keep the free fit.
        for (const Vec3d& d : fixed.fixed_directions)
          if (!(d.z() >= 0.0)) return;
        const PhongFit fit = fit_phong(texel, fixed);
        const double bic = fit_bic(fit, texel, phong_parameter_count(fixed.lobes, fixed.shared_shininess, true));
        StagedPhong& st = staged[static_cast<size_t>(t) * spec.texels_s + s];
        if (!(bic <= st.bic)) return;
        st.params = fit.params;
        st.quality = fit.quality;
        st.holdout = held.size() ? measure_quality(fit.params, held).rms : Vec3d::Zero();
        st.bic = bic;
        st.shared_lights = true;
        replaced.fetch_add(1);
      };
      VDRIG_TRY(for_each_texel(grid, load, options.threads, refit_texel, progress_of_pass(1)));
      texels_on_lights = replaced.load();
      logger->info("shared lights: {} of {} texels fitted with the lights' directions", texels_on_lights, total);
    }
  }

  ModelDescriptor map_model = r.model;
  if (r.auto_lobes) {
    map_model.lobes = 1;
    for (const auto& st : staged) map_model.lobes = std::max(map_model.lobes, static_cast<int>(st.params.lobes.size()));
  }
  map = ParameterMap(map_model, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  if (shared_lights) {
    map.add_channel("shared_lights");
    map.image().string_attributes["vdrig.shared_lights"] = lights_attribute;
  }
  for (int i = 0; i < total; ++i) {
    const int s = i % spec.texels_s, t = i / spec.texels_s;
    map.set_phong(s, t, staged[i].params);
    if (r.auto_lobes) map.at("lobes", s, t) = static_cast<float>(staged[i].params.lobes.size());
    if (shared_lights) map.at("shared_lights", s, t) = staged[i].shared_lights ? 1.0f : 0.0f;
    map.set_quality(s, t, staged[i].quality);
    if (holding_out) map.set_holdout_rms(s, t, staged[i].holdout);
  }
  return map;
}

}  // namespace

Result<ParameterMap> fit_parameter_map(const ObservationMap& obs, const MapFitOptions& options) {
  TileGrid grid{obs.spec(), obs.views(), 32};
  const TileLoader load = [&obs](int, int) -> Result<TexelAccessor> {
    return TexelAccessor([&obs](int s, int t) { return obs.texel(s, t); });
  };
  return fit_tiles(grid, load, options);
}

Result<ParameterMap> fit_parameter_map(const ObsMapReader& obs, const MapFitOptions& options) {
  TileGrid grid{obs.spec(), obs.views(), obs.header().tile_size};
  const TileLoader load = [&obs](int tile_s, int tile_t) -> Result<TexelAccessor> {
    auto tile = obs.read_tile(tile_s, tile_t);
    if (!tile) return tile.error();
    auto shared = std::make_shared<const ObsTile>(std::move(tile.value()));
    return TexelAccessor([shared](int s, int t) { return shared->texel(s, t); });
  };
  return fit_tiles(grid, load, options);
}

}  // namespace vdrig::fitting
