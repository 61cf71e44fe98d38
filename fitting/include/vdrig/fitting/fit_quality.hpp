// How well a fitted model reproduces a texel's observations, per colour channel.
#pragma once

#include <cmath>

#include "vdrig/core/geometry.hpp"
#include "vdrig/fitting/obsmap.hpp"

namespace vdrig::fitting {

/// Fit quality per colour channel.
struct FitQuality {
  Vec3d rms = Vec3d::Zero();           // root mean square residual
  Vec3d mean_percent = Vec3d::Zero();  // mean of |residual| / observed * 100 over samples with observed > 0
  int samples = 0;
};

/// Quality of any RGB model (anything with `Vec3d evaluate(const Vec3d&) const`) on observations.
template <typename Model>
FitQuality measure_quality(const Model& model, const TexelObservations& obs) {
  FitQuality q;
  Vec3d sq = Vec3d::Zero(), pct = Vec3d::Zero();
  Eigen::Vector3i pct_n = Eigen::Vector3i::Zero();
  for (size_t i = 0; i < obs.size(); ++i) {
    const Vec3d pred = model.evaluate(obs.direction[i].cast<double>());
    for (int c = 0; c < 3; ++c) {
      const double o = obs.radiance[i][c];
      const double r = pred[c] - o;
      sq[c] += r * r;
      if (o > 0) {
        pct[c] += std::abs(r) / o * 100.0;
        ++pct_n[c];
      }
    }
  }
  q.samples = static_cast<int>(obs.size());
  for (int c = 0; c < 3; ++c) {
    q.rms[c] = obs.size() ? std::sqrt(sq[c] / obs.size()) : 0.0;
    q.mean_percent[c] = pct_n[c] ? pct[c] / pct_n[c] : 0.0;
  }
  return q;
}

}  // namespace vdrig::fitting
