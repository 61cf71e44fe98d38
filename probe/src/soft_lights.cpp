#include "vdrig/probe/soft_lights.hpp"

#include <algorithm>
#include <cmath>

namespace vdrig::probe {

double sh9_clamped_cosine(double t) { return 0.25 + 0.5 * t + 5.0 * (3.0 * t * t - 1.0) / 32.0; }

Rgb SoftLights::irradiance(const Vec3d& normal) const {
  Rgb e = sh9_irradiance(sh9, normal);
  for (const DirectionalLight& l : lights) {
    const double t = normal.dot(l.direction);
    e += l.power * (std::max(0.0, t) - sh9_clamped_cosine(t));
  }
  return e;
}

SoftLights soft_lights(const Probe& probe, const SoftLightOptions& options) {
  VDRIG_CHECK(options.count >= 1 && options.kappa > 0, "soft lights need count >= 1 and kappa > 0");
  const int K = options.count, W = probe.width(), H = probe.height();
  const std::vector<Vec3d> centres = fibonacci_directions(K);
  std::vector<Rgb> power(K, Rgb::Zero());
  std::vector<Vec3d> centroid(K, Vec3d::Zero());
  std::vector<double> solid_angle(K, 0.0), share(K);
  for (int j = 0; j < H; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    for (int i = 0; i < W; ++i) {
      const Vec3d d = latlong_direction(i, j, W, H);
      const Rgb L = probe.pixel(i, j) * sa;
      const double y = luminance(L);
      double sum = 0;
      for (int k = 0; k < K; ++k) sum += share[k] = std::exp(options.kappa * (d.dot(centres[k]) - 1.0));
      for (int k = 0; k < K; ++k) {
        const double w = share[k] / sum;
        power[k] += w * L;
        centroid[k] += (w * y) * d;
        solid_angle[k] += w * sa;
      }
    }
  }
  SoftLights out;
  out.sh9 = project_sh9(probe);
  out.lights.resize(K);
  for (int k = 0; k < K; ++k) {
    DirectionalLight& l = out.lights[k];
    // A dark share has no centroid: keep the light at its centre direction (its power is 0 anyway).
    l.direction =
        centroid[k].norm() > 1e-12 * std::max(1.0, luminance(power[k])) ? centroid[k].normalized() : centres[k];
    l.power = power[k];
    l.solid_angle_sr = solid_angle[k];
  }
  return out;
}

}  // namespace vdrig::probe
