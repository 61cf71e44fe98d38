#include "vdrig/probe/sh_irradiance.hpp"

#include "vdrig/core/sh_basis.hpp"

namespace vdrig::probe {

std::array<double, kSh9Count> sh9_basis(const Vec3d& d) {
  std::array<double, kSh9Count> y{};
  sh_basis(3, d, y.data());
  return y;
}

double sh9_cosine_factor(int band) {
  VDRIG_CHECK(band >= 0 && band <= 2, "SH-9 has bands 0..2");
  constexpr double a[3] = {kPi, 2.0 * kPi / 3.0, kPi / 4.0};
  return a[band];
}

Sh9 project_sh9(const Probe& probe) {
  const int W = probe.width(), H = probe.height();
  Sh9 out;
  for (auto& c : out.coeffs) c.setZero();
  for (int j = 0; j < H; ++j) {
    const double sa = latlong_pixel_solid_angle(j, W, H);
    std::array<Rgb, kSh9Count> row{};
    for (auto& c : row) c.setZero();
    for (int i = 0; i < W; ++i) {
      const Rgb c = probe.pixel(i, j);
      const auto y = sh9_basis(latlong_direction(i, j, W, H));
      for (int k = 0; k < kSh9Count; ++k) row[k] += y[k] * c;
    }
    for (int k = 0; k < kSh9Count; ++k) out.coeffs[k] += sa * row[k];
  }
  return out;
}

Sh9 project_sh9(const std::vector<Vec3d>& directions, const std::vector<Rgb>& radiance_times_sr) {
  VDRIG_CHECK(directions.size() == radiance_times_sr.size(), "one radiance per direction");
  Sh9 out;
  for (auto& c : out.coeffs) c.setZero();
  for (size_t p = 0; p < directions.size(); ++p) {
    const auto y = sh9_basis(directions[p]);
    for (int k = 0; k < kSh9Count; ++k) out.coeffs[k] += y[k] * radiance_times_sr[p];
  }
  return out;
}

Rgb sh9_irradiance(const Sh9& radiance, const Vec3d& normal) {
  const auto y = sh9_basis(normal);
  Rgb e = Rgb::Zero();
  for (int k = 0; k < kSh9Count; ++k) e += sh9_cosine_factor(sh9_band(k)) * y[k] * radiance.coeffs[k];
  return e;
}

Rgb sh9_radiance(const Sh9& radiance, const Vec3d& dir) {
  const auto y = sh9_basis(dir);
  Rgb e = Rgb::Zero();
  for (int k = 0; k < kSh9Count; ++k) e += y[k] * radiance.coeffs[k];
  return e;
}

}  // namespace vdrig::probe
