// Fitting a whole observation map, texel by texel, in parallel, into a ParameterMap.
#pragma once

#include <functional>

#include "vdrig/fitting/obsmap.hpp"
#include "vdrig/fitting/parameter_map.hpp"

namespace vdrig::fitting {

struct MapFitProgress {
  int texels_done = 0;
  int texels_total = 0;
  double elapsed_s = 0.0;
  double eta_s = 0.0;
};

struct MapFitOptions {
  ModelDescriptor model;
  PhongFitOptions phong;     // lobes/shininess sharing taken from `model`
  int threads = 0;           // 0 = hardware concurrency
  int min_observations = 6;  // texels with fewer valid observations get zeros and n = their count
  std::function<void(const MapFitProgress&)> on_progress;  // called from worker threads, serialised
};

/// Fits every texel; the map's quality channels are filled (rms, mpe, n).
Result<ParameterMap> fit_parameter_map(const ObservationMap& obs, const MapFitOptions& options);

}  // namespace vdrig::fitting
