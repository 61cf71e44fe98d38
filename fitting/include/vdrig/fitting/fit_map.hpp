// Fitting a whole observation map, texel by texel, in parallel, into a ParameterMap of one reflectance model
// (model.hpp). The tiling, threading, held-out views and progress are here; what is fitted per texel is the model's
// (ReflectanceModel::fit_map).
#pragma once

#include <functional>
#include <vector>

#include "vdrig/fitting/lights.hpp"
#include "vdrig/fitting/model.hpp"
#include "vdrig/fitting/model_options.hpp"
#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {

struct MapFitProgress {
  int texels_done = 0;
  int texels_total = 0;
  double elapsed_s = 0.0;
  double eta_s = 0.0;
};

struct MapFitOptions {
  ModelPtr model = parse_model("phong:1").value();
  /// Each model's own options, by type (model_options.hpp; each model reads its own and ignores the others):
  /// PhongFitOptions (phong.hpp; lobes and shininess sharing taken from `model`), ShFitOptions (sh.hpp; bands and
  /// method taken from `model`), HshFitOptions (hsh.hpp; bands taken from `model`), e.g.
  /// `options.model_options.edit<PhongFitOptions>().lobe_support = 0`. Unset: the type's defaults.
  ModelOptions model_options;
  /// Observation-map view indices left out of the fit (any order); their observations give holdout.R/G/B, the RMS
  /// residual of the fitted model on them (0 where a texel has no held-out observation). The map records them
  /// (vdrig.held_out_views, sorted).
  std::vector<int> held_out;
  /// Phong only (other models reject it): after the per-texel fits, estimate the lights from all texels' lobes
  /// (estimate_point_lights, at most K lights for phong:K, 4 for phong:auto) and refit each texel with its lobes
  /// held at the lights' mirror directions (fit_phong with fixed_directions), keeping whichever of the two fits has
  /// the lower BIC; a texel whose normal is not the surface's keeps its own fit (docs/models.md has why and how
  /// much it helps). The map gets a "shared_lights" channel (1 where the refit won) and a header attribute
  /// "vdrig.shared_lights" listing the lights found, "; "-separated, each "point X Y Z" (surface frame, mm) or
  /// "direction X Y Z" (unit, toward a light at infinity); empty when none was found.
  bool shared_lights = false;
  LightEstimationOptions lights;
  static constexpr int kMaxThreads = 256;
  int threads = 0;           // 0 = hardware concurrency; at most kMaxThreads (each worker holds a tile's fit state)
  int min_observations = 6;  // texels with fewer valid observations get zeros and n = their count
  std::function<void(const MapFitProgress&)> on_progress;  // called from worker threads, serialised
};

/// Fits every texel with options.model; the map's quality channels are filled (rms, mpe, n over the fitted
/// observations; holdout.* when views are held out). Invalid options are kInvalidArgument with the reason. Texels
/// are fitted tile by tile (32 x 32). With the camera at a finite distance no two texels see a view from exactly
/// the same direction, so each texel is fitted on its own directions (no shared operators).
Result<ParameterMap> fit_parameter_map(const ObservationMap& obs, const MapFitOptions& options);

/// The same from an observation-map file, one tile per worker thread in memory at a time (the file's tiles), so a
/// map of any size is fitted with bounded memory: threads x tile^2 x views x 25 B for the observations plus the
/// parameter map itself. Gives the same parameters as the in-memory overload on the same observations. A tile that
/// cannot be read (kCorrupt, kIo) ends the fit with that error.
Result<ParameterMap> fit_parameter_map(const ObsMapReader& obs, const MapFitOptions& options);

}  // namespace vdrig::fitting
