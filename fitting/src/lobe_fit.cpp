#include "vdrig/fitting/lobe_fit.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/core/result.hpp"

namespace vdrig::fitting {

double fit_two_terms(std::span<const double> s, std::span<const double> o, double* base, double* scale) {
  const double n = static_cast<double>(s.size());
  double ss = 0, so = 0, s1 = 0, o1 = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    ss += s[i] * s[i];
    so += s[i] * o[i];
    s1 += s[i];
    o1 += o[i];
  }
  const double det = n * ss - s1 * s1;
  double a = o1 / n, b = 0;
  if (std::abs(det) > 1e-12 * std::max(1.0, n * ss)) {
    a = (ss * o1 - s1 * so) / det;
    b = (n * so - s1 * o1) / det;
  }
  if (b < 0) {
    b = 0;
    a = o1 / n;
  }
  if (a < 0) {
    a = 0;
    b = ss > 0 ? std::max(0.0, so / ss) : 0.0;
  }
  double err = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const double r = a + b * s[i] - o[i];
    err += r * r;
  }
  *base = a;
  *scale = b;
  return err;
}

LobeTarget lobe_target(const TexelObservations& obs, const Vec3d& base,
                       const std::function<Vec3d(const Vec3d& v)>& lobes_at) {
  VDRIG_CHECK(obs.size() > 0, "lobe_target needs observations");
  const size_t n = obs.size();
  LobeTarget target;
  for (auto& channel : target.residual) channel.resize(n);
  double best = -1e300;
  for (size_t i = 0; i < n; ++i) {
    const Vec3d lobes = lobes_at(obs.direction[i].cast<double>());
    for (int ch = 0; ch < 3; ++ch) target.residual[static_cast<size_t>(ch)][i] = obs.radiance[i][ch] - lobes[ch];
    // The luminance as float, as observed.
    const double luminance = obs.radiance[i][0] + obs.radiance[i][1] + obs.radiance[i][2];
    const double excess = luminance - base.sum() - lobes.sum();
    if (excess > best) {
      best = excess;
      target.peak = i;
    }
  }
  return target;
}

Vec3d lobe_start_direction(const Vec3d& observation_direction) {
  Vec3d r = observation_direction.normalized();
  if (r.z() < 1e-3) r = Vec3d(r.x(), r.y(), 1e-3).normalized();
  return r;
}

LobeStart search_lobe_width(const LobeTarget& target, std::span<const double> widths,
                            const std::function<void(double width, std::vector<double>& s)>& shape) {
  LobeStart best;
  best.squared_error = 1e300;
  std::vector<double> s(target.residual[0].size());
  for (const double width : widths) {
    shape(width, s);
    double err = 0;
    Vec3d base, scale;
    for (int ch = 0; ch < 3; ++ch)
      err += fit_two_terms(s, target.residual[static_cast<size_t>(ch)], &base[ch], &scale[ch]);
    if (err < best.squared_error) best = {base, scale, width, err};
  }
  return best;
}

std::vector<double> geometric_steps(double first, double last, double ratio) {
  VDRIG_CHECK(first > 0 && ratio > 1, "geometric_steps: first > 0, ratio > 1");
  std::vector<double> steps;
  for (double x = first; x <= last; x *= ratio) steps.push_back(x);
  return steps;
}

}  // namespace vdrig::fitting
