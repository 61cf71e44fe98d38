// A map fit cut into tile jobs whose results are bytes, so that the tiles can be fitted in other processes (the
// MPI driver, cluster/) and each finished tile recorded on disk (restartable fits, docs/scale.md).
//
// A fit runs passes() passes over the tiles. Pass p of tile k reads the tile's observations and, for p > 0, the
// tile's record of pass p - 1, and returns the tile's record of pass p. Between passes the fit may need one piece of
// state computed from every tile (Phong with shared lights: the lights estimated from all texels' lobes): each
// record of pass p gives a small summary(), pass_state() turns all summaries (in tile order) into the state and
// set_pass_state() hands it to every process. assemble() builds the map from the last pass's records.
//
// The result equals fit_parameter_map(ObsMapReader, options) bit for bit, whatever the order in which tiles are fitted,
// the process that fits them and the thread count: records hold every value the single-process fit keeps between
// its passes at full precision, and the between-pass state is computed from the same data in the same order.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {

/// The bytes of one tile's result of one pass, or of a summary or between-pass state (layout private to the model).
using TileBytes = std::vector<uint8_t>;

/// Tile k of a grid of tiles_s x tiles_t tiles: texels [s0, s0 + width) x [t0, t0 + height), global coordinates.
struct TileRect {
  int index = 0;
  int s0 = 0, t0 = 0, width = 0, height = 0;
};

/// What a model's tile fit works on: the tile, and a visitor over its texels (global coordinates, held-out views
/// split off) on `workers` threads.
struct TileWork {
  TileRect rect;
  int workers = 1;
  std::function<Status(const TexelVisitor& visit)> for_each_texel;
};

/// A model's fit in tiles (ReflectanceModel::tiled_fit). Thread-compatible: one call at a time.
class ModelTiledFit {
 public:
  virtual ~ModelTiledFit() = default;
  virtual int passes() const { return 1; }
  /// Pass `pass` of one tile; `previous` is the tile's record of pass - 1 (nullptr in pass 0).
  virtual Result<TileBytes> fit_tile(int pass, const TileWork& work, const TileBytes* previous) = 0;
  /// What pass_state needs of one tile's record of `pass` (< passes() - 1); empty by default.
  virtual Result<TileBytes> summary(int /*pass*/, const TileRect& /*rect*/, const TileBytes& /*record*/) const {
    return TileBytes{};
  }
  /// The state of pass + 1 from every tile's summary of `pass` (summaries[k] is tile k's).
  virtual Result<TileBytes> pass_state(int /*pass*/, const std::vector<TileBytes>& /*summaries*/) {
    return TileBytes{};
  }
  /// Installs the state pass_state returned (on every process, before pass + 1).
  virtual Status set_pass_state(int /*pass*/, const TileBytes& /*state*/) { return Status::ok(); }
  /// The map from the records of the last pass; record(k) reads tile k's (tiles in any order may be requested).
  virtual Result<ParameterMap> assemble(const std::vector<TileRect>& tiles,
                                        const std::function<Result<TileBytes>(int tile)>& record) = 0;
};

/// A fit of an observation-map file in tiles (the file's own tiles).
class TiledMapFit {
 public:
  /// Validates the options as fit_parameter_map does (kInvalidArgument with the reason). The reader must outlive
  /// the fit.
  static Result<TiledMapFit> create(const ObsMapReader& obs, const MapFitOptions& options);
  TiledMapFit(TiledMapFit&&) noexcept;
  TiledMapFit& operator=(TiledMapFit&&) noexcept;
  ~TiledMapFit();

  int tiles() const;
  TileRect tile(int k) const;
  int passes() const;
  /// Pass `pass` of tile k with options.threads threads over its texels; reads the tile from the file (kCorrupt,
  /// kIo when unreadable).
  Result<TileBytes> fit_tile(int pass, int k, const TileBytes* previous);
  Result<TileBytes> summary(int pass, int k, const TileBytes& record) const;
  Result<TileBytes> pass_state(int pass, const std::vector<TileBytes>& summaries);
  Status set_pass_state(int pass, const TileBytes& state);
  /// The map, with the attributes fit_parameter_map sets (vdrig.held_out_views).
  Result<ParameterMap> assemble(const std::function<Result<TileBytes>(int tile)>& record);

 private:
  struct Impl;
  explicit TiledMapFit(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// A text naming everything that decides a fit's result besides the observations: the model and every option
/// (held-out views, min_observations, shared_lights, and what the model's options_fingerprint adds: its own options;
/// not threads or progress). Tile records
/// are tied to it (and to the observation file's identity) so that a resumed fit never mixes in another fit's tiles.
std::string fit_options_fingerprint(const MapFitOptions& options);

/// The generic tiled fit of a model whose fit_map is per texel and independent of the texel's position
/// (fit_map_per_texel): each tile is fitted by model->fit_map on a map of the tile's size; records hold the tile's
/// channels. ReflectanceModel::tiled_fit's default.
/// Options the model's fit_map refuses are kInvalidArgument here.
Result<std::unique_ptr<ModelTiledFit>> per_texel_tiled_fit(ModelPtr model, const MapFitOptions& options,
                                                           const ObservationMapSpec& spec);
/// The same for a model whose texel fit depends on the texel's place on the map (ggx: the light's direction there):
/// each tile is fitted by fit_rect(context of the tile's size, the tile, the whole map's spec) instead of fit_map.
using RectFit = std::function<Result<ParameterMap>(const MapFitContext& tile_context, const TileRect& rect,
                                                   const ObservationMapSpec& whole)>;
Result<std::unique_ptr<ModelTiledFit>> per_texel_tiled_fit(ModelPtr model, const MapFitOptions& options,
                                                           const ObservationMapSpec& spec, RectFit fit_rect);

}  // namespace vdrig::fitting
