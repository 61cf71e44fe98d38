#include "vdrig/probe/cap_lights.hpp"

#include <algorithm>
#include <cmath>

#include "vdrig/core/geometry.hpp"

namespace vdrig::probe {
namespace {

// Above this cosine (half-angle 1e-4 rad) the cap is a point to the precision of the quantities used.
constexpr double kPointCos = 1.0 - 5e-9;
// cos 88 deg: the closed form needs a < 90 deg.
const double kMinCos = std::cos(88.0 * kPi / 180.0);

}  // namespace

double cap_cos_half_angle_for_mean_length(double mean_length) {
  const double c = std::clamp(2.0 * mean_length - 1.0, kMinCos, 1.0);
  return c > kPointCos ? 1.0 : c;
}

double cap_clamped_cosine(double t, double cos_half_angle) {
  t = std::clamp(t, -1.0, 1.0);
  if (cos_half_angle > kPointCos) return std::max(0.0, t);
  // No trigonometry on the common paths: a renderer calls this per light and pixel.
  const double cos_a = std::max(cos_half_angle, kMinCos), sin_a = std::sqrt(1.0 - cos_a * cos_a);
  if (t >= sin_a) return 0.5 * (1.0 + cos_a) * t;  // wholly above the horizon: the first moment
  if (t <= -sin_a) return 0.0;                     // wholly below
  // The horizon cuts the cap (Snyder 1996, "Area light sources for real-time graphics"; the form of Lagarde & de
  // Rousiers 2014, "Moving Frostbite to PBR", eq. 21): integral of max(0, n . w) over the cap, then / its solid angle.
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - t * t));
  const double x = cos_a / sin_a;
  const double y = std::clamp(-x * t / sin_t, -1.0, 1.0);
  const double q = sin_t * std::sqrt(std::max(0.0, 1.0 - y * y));
  const double integral = (t * std::acos(y) - x * q) * sin_a * sin_a + std::atan(q / x);
  return std::max(0.0, integral / (2.0 * kPi * (1.0 - cos_a)));
}

double cap_sh9_clamped_cosine(double t, double cos_half_angle) {
  const double c = cos_half_angle > kPointCos ? 1.0 : std::max(cos_half_angle, kMinCos);
  const double c1 = 0.5 * (1.0 + c), c2 = c * c1;
  return 0.25 + c1 * 0.5 * t + c2 * 5.0 * (3.0 * t * t - 1.0) / 32.0;
}

}  // namespace vdrig::probe
