#include "vdrig/probe/median_cut.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/probe/cap_lights.hpp"

namespace vdrig::probe {
namespace {

// Summed-area table of the pixel energies, (H + 1) x (W + 1), in double: a region sum is four look-ups.
class EnergyTable {
 public:
  explicit EnergyTable(const Probe& p) : W_(p.width()), H_(p.height()), sat_((W_ + 1) * static_cast<size_t>(H_ + 1)) {
    for (int j = 0; j < H_; ++j) {
      const double sa = latlong_pixel_solid_angle(j, W_, H_);
      double row = 0;
      for (int i = 0; i < W_; ++i) {
        row += luminance(p.pixel(i, j)) * sa;
        at(i + 1, j + 1) = at(i + 1, j) + row;
      }
    }
  }
  double sum(int x0, int y0, int x1, int y1) const { return at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0); }
  double sum(const MedianCutRegion& r) const { return sum(r.x0, r.y0, r.x1, r.y1); }

 private:
  double& at(int x, int y) { return sat_[static_cast<size_t>(y) * (W_ + 1) + x]; }
  double at(int x, int y) const { return sat_[static_cast<size_t>(y) * (W_ + 1) + x]; }
  int W_, H_;
  std::vector<double> sat_;
};

// Boundary in (lo, hi) whose prefix energy is closest to half; `prefix(b)` is the energy of [lo, b).
template <typename Prefix>
int best_cut(int lo, int hi, double total, Prefix prefix) {
  if (total <= 0) return (lo + hi) / 2;  // no energy: halve geometrically
  int a = lo + 1, b = hi - 1;            // smallest boundary with prefix >= total / 2, clamped into [lo+1, hi-1]
  while (a < b) {
    const int m = (a + b) / 2;
    if (prefix(m) >= 0.5 * total)
      b = m;
    else
      a = m + 1;
  }
  if (a > lo + 1 && std::abs(prefix(a - 1) - 0.5 * total) <= std::abs(prefix(a) - 0.5 * total)) --a;
  return a;
}

// Splits r in two; false if it is a single pixel.
bool split(const EnergyTable& t, const MedianCutRegion& r, int H, MedianCutRegion* a, MedianCutRegion* b) {
  const int w = r.x1 - r.x0, h = r.y1 - r.y0;
  if (w < 2 && h < 2) return false;
  const double middle_zenith = kPi * 0.5 * (r.y0 + r.y1) / H;
  const bool across_columns = h < 2 || (w >= 2 && w * std::sin(middle_zenith) > h);
  *a = r;
  *b = r;
  if (across_columns) {
    const int c = best_cut(r.x0, r.x1, r.energy, [&](int x) { return t.sum(r.x0, r.y0, x, r.y1); });
    a->x1 = c;
    b->x0 = c;
  } else {
    const int c = best_cut(r.y0, r.y1, r.energy, [&](int y) { return t.sum(r.x0, r.y0, r.x1, y); });
    a->y1 = c;
    b->y0 = c;
  }
  a->energy = t.sum(*a);
  b->energy = t.sum(*b);
  return true;
}

DirectionalLight make_light(const Probe& p, const MedianCutRegion& r) {
  const int W = p.width(), H = p.height();
  DirectionalLight light;
  light.region = r;
  Vec3d weighted = Vec3d::Zero(), geometric = Vec3d::Zero();
  for (int j = r.y0; j < r.y1; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    for (int i = r.x0; i < r.x1; ++i) {
      const Rgb c = p.pixel(i, j);
      const Vec3d d = latlong_direction(i, j, W, H);
      light.power += c * sa;
      light.solid_angle_sr += sa;
      weighted += luminance(c) * sa * d;
      geometric += sa * d;
    }
  }
  // The energy centroid as a mean direction (wraps and handles the poles, unlike a centroid in pixel coordinates);
  // a dark region, or one whose directions cancel, falls back to its solid-angle centroid, then to its middle.
  const double nw = weighted.norm(), ng = geometric.norm();
  if (nw > 1e-12 * std::max(r.energy, 1e-300)) {
    light.direction = weighted / nw;
    light.cap_cos_half_angle = cap_cos_half_angle_for_mean_length(r.energy > 0 ? nw / r.energy : 1.0);
  } else if (ng > 1e-12)
    light.direction = geometric / ng;
  else
    light.direction = latlong_direction(0.5 * (r.x0 + r.x1) - 0.5, 0.5 * (r.y0 + r.y1) - 0.5, W, H);
  return light;
}

}  // namespace

std::vector<DirectionalLight> median_cut(const Probe& probe, int count) {
  VDRIG_CHECK(is_power_of_two(count), "median cut needs a power-of-two light count");
  return median_cut_any_count(probe, count);
}

std::vector<DirectionalLight> median_cut_any_count(const Probe& probe, int count) {
  VDRIG_CHECK(count >= 1, "median cut needs at least one light");
  const EnergyTable table(probe);
  std::vector<MedianCutRegion> regions{{0, 0, probe.width(), probe.height(), 0.0}};
  regions[0].energy = table.sum(regions[0]);
  // floor(log2(count)) rounds, each splitting every region once (Debevec's recursion, breadth first).
  for (int round = 1; 2 * round <= count; round *= 2) {
    std::vector<MedianCutRegion> next;
    next.reserve(2 * regions.size());
    for (const auto& r : regions) {
      MedianCutRegion a, b;
      if (split(table, r, probe.height(), &a, &b)) {
        next.push_back(a);
        next.push_back(b);
      } else {
        next.push_back(r);
      }
    }
    if (next.size() == regions.size()) break;  // every region is a single pixel
    regions = std::move(next);
  }
  // A count that is not a power of two, or rounds that met single-pixel regions, left fewer than `count`: split the
  // most energetic splittable regions until the count is reached, which keeps the energies as even as the pixel grid
  // allows.
  while (static_cast<int>(regions.size()) < count) {
    int best = -1;
    MedianCutRegion a, b;
    for (int k = 0; k < static_cast<int>(regions.size()); ++k) {
      const MedianCutRegion& r = regions[k];
      if ((r.x1 - r.x0 > 1 || r.y1 - r.y0 > 1) && (best < 0 || r.energy > regions[best].energy)) best = k;
    }
    if (best < 0 || !split(table, regions[best], probe.height(), &a, &b)) break;  // a map of fewer pixels than lights
    regions[best] = a;
    regions.push_back(b);
  }
  std::vector<DirectionalLight> lights;
  lights.reserve(regions.size());
  for (const auto& r : regions) lights.push_back(make_light(probe, r));
  return lights;
}

Rgb irradiance_from_lights(const std::vector<DirectionalLight>& lights, const Vec3d& normal) {
  Rgb e = Rgb::Zero();
  for (const auto& l : lights) e += l.power * std::max(0.0, normal.dot(l.direction));
  return e;
}

}  // namespace vdrig::probe
