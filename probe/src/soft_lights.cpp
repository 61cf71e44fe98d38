#include "vdrig/probe/soft_lights.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/probe/cap_lights.hpp"

namespace vdrig::probe {

double sh9_clamped_cosine(double t) { return 0.25 + 0.5 * t + 5.0 * (3.0 * t * t - 1.0) / 32.0; }

Rgb SoftLights::irradiance(const Vec3d& normal) const {
  Rgb e = sh9_irradiance(sh9, normal);
  for (const DirectionalLight& l : lights) {
    const double t = normal.dot(l.direction);
    e += l.power * (cap_clamped_cosine(t, l.cap_cos_half_angle) - cap_sh9_clamped_cosine(t, l.cap_cos_half_angle));
  }
  return e;
}

namespace {

// The sums of soft_lights over any quadrature: directions, radiance x solid angle and solid angle, paired.
SoftLights soft_lights_impl(const std::vector<Vec3d>& dirs, const std::vector<Rgb>& weighted,
                            const std::vector<double>& solid_angles, const SoftLightOptions& options) {
  VDRIG_CHECK(options.count >= 1 && options.kappa > 0, "soft lights need count >= 1 and kappa > 0");
  const int K = options.count;
  const std::vector<Vec3d> centres = fibonacci_directions(K);
  std::vector<Rgb> power(K, Rgb::Zero());
  std::vector<Vec3d> centroid(K, Vec3d::Zero());
  std::vector<double> solid_angle(K, 0.0), share(K);
  // Shares below exp(-kCutoff) of the largest are dropped (< 1e-13 of the pixel: below double rounding of the sums);
  // with 64 lights that leaves a handful of exp() per pixel instead of 64.
  constexpr double kCutoff = 30.0;
  std::vector<double> dot(K);
  std::vector<int> active;
  active.reserve(K);
  for (size_t p = 0; p < dirs.size(); ++p) {
    const Vec3d& d = dirs[p];
    const Rgb& L = weighted[p];
    const double sa = solid_angles[p];
    const double y = luminance(L);
    double best = -2;
    for (int k = 0; k < K; ++k) best = std::max(best, dot[k] = d.dot(centres[k]));
    active.clear();
    double sum = 0;
    for (int k = 0; k < K; ++k)
      if (options.kappa * (dot[k] - best) > -kCutoff) {
        active.push_back(k);
        sum += share[k] = std::exp(options.kappa * (dot[k] - 1.0));
      }
    for (int k : active) {
      const double w = share[k] / sum;
      power[k] += w * L;
      centroid[k] += (w * y) * d;
      solid_angle[k] += w * sa;
    }
  }
  SoftLights out;  // the caller sets out.sh9
  out.lights.resize(K);
  for (int k = 0; k < K; ++k) {
    DirectionalLight& l = out.lights[k];
    // A dark share has no centroid: keep the light at its centre direction (its power is 0 anyway).
    const double length = centroid[k].norm(), y = luminance(power[k]);
    l.direction = length > 1e-12 * std::max(1.0, y) ? centroid[k] / length : centres[k];
    // The share's spread as a cap (cap_lights.hpp): continuous in the map like the rest, so it adds no flicker.
    if (options.cap_spread && y > 0) l.cap_cos_half_angle = cap_cos_half_angle_for_mean_length(length / y);
    l.power = power[k];
    l.solid_angle_sr = solid_angle[k];
  }
  return out;
}

}  // namespace

SoftLights soft_lights(const Probe& probe, const SoftLightOptions& options) {
  const int W = probe.width(), H = probe.height();
  std::vector<Vec3d> dirs;
  std::vector<Rgb> weighted;
  std::vector<double> sas;
  dirs.reserve(static_cast<size_t>(W) * H);
  weighted.reserve(dirs.capacity());
  sas.reserve(dirs.capacity());
  for (int j = 0; j < H; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    for (int i = 0; i < W; ++i) {
      dirs.push_back(latlong_direction(i, j, W, H));
      weighted.push_back(probe.pixel(i, j) * sa);
      sas.push_back(sa);
    }
  }
  SoftLights out = soft_lights_impl(dirs, weighted, sas, options);
  out.sh9 = project_sh9(probe);
  return out;
}

SoftLights soft_lights(const CubeMap& cube, const SoftLightOptions& options) {
  std::vector<Vec3d> dirs;
  std::vector<Rgb> weighted;
  cube_quadrature(cube, &dirs, &weighted);
  std::vector<double> sas;
  sas.reserve(dirs.size());
  const int N = cube.size;
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < N; ++j)
      for (int i = 0; i < N; ++i) sas.push_back(cube_texel_solid_angle(i, j, N));
  SoftLights out = soft_lights_impl(dirs, weighted, sas, options);
  out.sh9 = project_sh9(dirs, weighted);
  return out;
}

SoftLights hybrid_lights(const Probe& probe, int count, bool cap_spread) {
  VDRIG_CHECK(count >= 1, "hybrid lights need count >= 1");
  SoftLights out;
  out.sh9 = project_sh9(probe);
  out.lights = median_cut_any_count(probe, count);
  if (!cap_spread)
    for (DirectionalLight& l : out.lights) l.cap_cos_half_angle = 1;
  return out;
}

}  // namespace vdrig::probe
