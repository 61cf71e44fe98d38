#include "vdrig/fitting/fit_map.hpp"

#include "vdrig/fitting/tiled_fit.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
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

/// Checks the options that concern every model; returns the held-out views sorted and unique.
Result<std::vector<int>> resolve_held_out(const MapFitOptions& options, int views) {
  if (!options.model) return make_error(ErrorCode::kInvalidArgument, "fit_parameter_map: no model");
  if (options.min_observations < 1)
    return make_error(ErrorCode::kInvalidArgument, "fit_parameter_map: min_observations must be >= 1");
  if (options.threads < 0 || options.threads > MapFitOptions::kMaxThreads)
    return make_error(ErrorCode::kInvalidArgument, "threads must be in [0, " +
                                                       std::to_string(MapFitOptions::kMaxThreads) +
                                                       "] (0: all cores), got " + std::to_string(options.threads));
  std::vector<int> held_out = options.held_out;
  std::sort(held_out.begin(), held_out.end());
  held_out.erase(std::unique(held_out.begin(), held_out.end()), held_out.end());
  for (int v : held_out)
    if (v < 0 || v >= views)
      return make_error(ErrorCode::kInvalidArgument, "held-out view " + std::to_string(v) + " is not in the map");
  return held_out;
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

Result<ParameterMap> fit_tiles(const TileGrid& grid, const TileLoader& load, const MapFitOptions& options) {
  auto held_out = resolve_held_out(options, grid.views);
  if (!held_out) return held_out.error();
  const int total = grid.spec.texels_s * grid.spec.texels_t;
  MapFitContext context{options, grid.spec, worker_count(options.threads), {}};
  context.for_each_texel = [&](int pass, int passes, const TexelVisitor& visit) {
    // Progress over every pass: pass k reports texels_done + k x total of passes x total.
    std::function<void(const MapFitProgress&)> progress;
    if (options.on_progress)
      progress = [&, pass, passes](const MapFitProgress& p) {
        MapFitProgress q = p;
        q.texels_done = p.texels_done + pass * total;
        q.texels_total = passes * total;
        q.eta_s = q.texels_done ? p.elapsed_s / q.texels_done * (q.texels_total - q.texels_done) : 0.0;
        options.on_progress(q);
      };
    auto fit_texel = [&](int worker, int s, int t, const TexelObservations& all) {
      TexelObservations texel, held;
      split_texel(all, held_out.value(), &texel, &held);
      visit(worker, s, t, texel, held);
    };
    return for_each_texel(grid, load, options.threads, fit_texel, progress);
  };
  auto map = options.model->fit_map(context);
  if (map && !held_out->empty()) {
    // Recorded so that later tools (vdrig compare --holdout, the texel inspector) find the views the fit never saw.
    std::string views;
    for (int v : held_out.value()) views += (views.empty() ? "" : ",") + std::to_string(v);
    map->image().string_attributes["vdrig.held_out_views"] = views;
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

// ---------------------------------------------------------------------------------------------------------------
// TiledMapFit (tiled_fit.hpp)

namespace vdrig::fitting {

struct TiledMapFit::Impl {
  const ObsMapReader* obs = nullptr;
  MapFitOptions options;
  std::vector<int> held_out;
  TileGrid grid;
  std::unique_ptr<ModelTiledFit> model_fit;
};

Result<TiledMapFit> TiledMapFit::create(const ObsMapReader& obs, const MapFitOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->obs = &obs;
  impl->options = options;
  impl->options.on_progress = nullptr;  // tiles report their own progress (the driver's)
  impl->grid = TileGrid{obs.spec(), obs.views(), obs.header().tile_size};
  auto held_out = resolve_held_out(options, obs.views());
  if (!held_out) return held_out.error();
  impl->held_out = std::move(held_out.value());
  auto model_fit = options.model->tiled_fit(impl->options, obs.spec());
  if (!model_fit) return model_fit.error();
  impl->model_fit = std::move(model_fit.value());
  return TiledMapFit(std::move(impl));
}

TiledMapFit::TiledMapFit(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
TiledMapFit::TiledMapFit(TiledMapFit&&) noexcept = default;
TiledMapFit& TiledMapFit::operator=(TiledMapFit&&) noexcept = default;
TiledMapFit::~TiledMapFit() = default;

int TiledMapFit::tiles() const { return impl_->grid.tiles_s() * impl_->grid.tiles_t(); }
int TiledMapFit::passes() const { return impl_->model_fit->passes(); }

TileRect TiledMapFit::tile(int k) const {
  const TileGrid& g = impl_->grid;
  VDRIG_CHECK(k >= 0 && k < tiles(), "tile index out of range");
  TileRect r;
  r.index = k;
  r.s0 = (k % g.tiles_s()) * g.tile_size;
  r.t0 = (k / g.tiles_s()) * g.tile_size;
  r.width = std::min(g.tile_size, g.spec.texels_s - r.s0);
  r.height = std::min(g.tile_size, g.spec.texels_t - r.t0);
  return r;
}

Result<TileBytes> TiledMapFit::fit_tile(int pass, int k, const TileBytes* previous) {
  const TileGrid& g = impl_->grid;
  const TileRect rect = tile(k);
  auto obs_tile = impl_->obs->read_tile(k % g.tiles_s(), k / g.tiles_s());
  if (!obs_tile) return obs_tile.error();
  const ObsTile& data = obs_tile.value();
  TileWork work;
  work.rect = rect;
  work.workers = std::min(worker_count(impl_->options.threads), rect.height);
  const std::vector<int>& held_out = impl_->held_out;
  // Threads take the tile's texel rows in turn; a texel's fit does not depend on which thread fits it.
  work.for_each_texel = [&](const TexelVisitor& visit) -> Status {
    std::atomic<int> next_row{0};
    auto worker = [&](int worker_index) {
      for (int row = next_row.fetch_add(1); row < rect.height; row = next_row.fetch_add(1)) {
        const int t = rect.t0 + row;
        for (int s = rect.s0; s < rect.s0 + rect.width; ++s) {
          TexelObservations texel, held;
          split_texel(data.texel(s, t), held_out, &texel, &held);
          visit(worker_index, s, t, texel, held);
        }
      }
    };
    std::vector<std::thread> pool;
    for (int i = 1; i < work.workers; ++i) pool.emplace_back(worker, i);
    worker(0);
    for (auto& th : pool) th.join();
    return Status::ok();
  };
  return impl_->model_fit->fit_tile(pass, work, previous);
}

Result<TileBytes> TiledMapFit::summary(int pass, int k, const TileBytes& record) const {
  return impl_->model_fit->summary(pass, tile(k), record);
}

Result<TileBytes> TiledMapFit::pass_state(int pass, const std::vector<TileBytes>& summaries) {
  VDRIG_CHECK(static_cast<int>(summaries.size()) == tiles(), "pass_state needs every tile's summary");
  return impl_->model_fit->pass_state(pass, summaries);
}

Status TiledMapFit::set_pass_state(int pass, const TileBytes& state) {
  return impl_->model_fit->set_pass_state(pass, state);
}

Result<ParameterMap> TiledMapFit::assemble(const std::function<Result<TileBytes>(int tile)>& record) {
  std::vector<TileRect> rects;
  for (int k = 0; k < tiles(); ++k) rects.push_back(tile(k));
  auto map = impl_->model_fit->assemble(rects, record);
  if (map && !impl_->held_out.empty()) {
    // As fit_tiles.
    std::string views;
    for (int v : impl_->held_out) views += (views.empty() ? "" : ",") + std::to_string(v);
    map->image().string_attributes["vdrig.held_out_views"] = views;
  }
  return map;
}

}  // namespace vdrig::fitting
