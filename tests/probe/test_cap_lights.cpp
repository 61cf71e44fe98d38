// Lights spread over caps (cap_lights.hpp): the closed-form clamped cosine of a cap and its SH-9 band limit against
// numerical integration over the cap, the cap of a mean direction length, and median cut to any light count.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "probe_support.hpp"
#include "vdrig/probe/cap_lights.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/probe/soft_lights.hpp"

namespace vdrig::probe {
namespace {

// Midpoint quadrature of a cap of half-angle a around +z, n x n cells in (polar angle, azimuth): directions and
// solid angles. Its error on the smooth integrands below is ~1e-6 at n = 300.
void cap_quadrature(double a, int n, std::vector<Vec3d>* dirs, std::vector<double>* sr) {
  for (int i = 0; i < n; ++i) {
    const double g0 = a * i / n, g1 = a * (i + 1) / n, g = 0.5 * (g0 + g1);
    for (int k = 0; k < n; ++k) {
      const double p = 2 * kPi * (k + 0.5) / n;
      dirs->push_back(Vec3d(std::sin(g) * std::cos(p), std::sin(g) * std::sin(p), std::cos(g)));
      sr->push_back((std::cos(g0) - std::cos(g1)) * 2 * kPi / n);
    }
  }
}

TEST(CapLights, ClampedCosineOfACapIsItsIntegral) {
  for (double a_deg : {0.5, 5.0, 20.0, 45.0, 80.0}) {
    const double a = a_deg * kPi / 180;
    std::vector<Vec3d> dirs;
    std::vector<double> sr;
    cap_quadrature(a, 300, &dirs, &sr);
    double omega = 0;
    for (double s : sr) omega += s;
    EXPECT_NEAR(omega, 2 * kPi * (1 - std::cos(a)), 1e-9 * omega);
    for (double t : {-0.99, -0.6, -0.2, -0.05, 0.0, 0.03, 0.2, 0.5, 0.999}) {
      const Vec3d n(std::sqrt(1 - t * t), 0, t);
      double integral = 0;
      for (size_t k = 0; k < dirs.size(); ++k) integral += std::max(0.0, n.dot(dirs[k])) * sr[k];
      EXPECT_NEAR(cap_clamped_cosine(t, std::cos(a)), integral / omega, 2e-5) << "a " << a_deg << " deg, t " << t;
    }
  }
  // A point: the clamped cosine itself.
  for (double t : {-0.5, 0.0, 0.7}) EXPECT_EQ(cap_clamped_cosine(t, 1.0), std::max(0.0, t));
}

TEST(CapLights, Sh9BandLimitIsTheSh9ProjectionOfTheCap) {
  // Radiance 1 / omega over a cap around d (power 1), projected on SH-9 by quadrature: its SH-9 irradiance must be
  // cap_sh9_clamped_cosine(n . d).
  for (double a_deg : {0.0, 10.0, 40.0, 75.0}) {
    const double a = a_deg * kPi / 180;
    std::vector<Vec3d> dirs;
    std::vector<double> sr;
    if (a > 0)
      cap_quadrature(a, 200, &dirs, &sr);
    else
      dirs.push_back(Vec3d::UnitZ()), sr.push_back(1.0);
    double omega = 0;
    for (double s : sr) omega += s;
    std::vector<Rgb> weighted;
    for (double s : sr) weighted.push_back(Rgb::Constant(s / omega));
    const Sh9 sh = project_sh9(dirs, weighted);
    for (const Vec3d& n : fibonacci_directions(40))
      EXPECT_NEAR(sh9_irradiance(sh, n).x(), cap_sh9_clamped_cosine(n.z(), std::cos(a)), 1e-5) << a_deg;
  }
  for (double t : {-0.8, 0.1, 0.9}) EXPECT_NEAR(cap_sh9_clamped_cosine(t, 1.0), sh9_clamped_cosine(t), 1e-15);
}

TEST(CapLights, CapOfAMeanDirectionLength) {
  for (double a_deg : {1.0, 10.0, 30.0, 60.0, 85.0}) {
    const double a = a_deg * kPi / 180;
    EXPECT_NEAR(cap_cos_half_angle_for_mean_length(0.5 * (1 + std::cos(a))), std::cos(a), 1e-12) << a_deg;
  }
  EXPECT_EQ(cap_cos_half_angle_for_mean_length(1.0), 1.0);
  EXPECT_EQ(cap_cos_half_angle_for_mean_length(1.0 - 1e-10), 1.0);                        // a point to double precision
  EXPECT_NEAR(cap_cos_half_angle_for_mean_length(0.1), std::cos(88 * kPi / 180), 1e-12);  // clamped below 90 deg
  // Clamped the same way inside the kernel: a cap of 89 deg is evaluated as one of 88 deg.
  EXPECT_EQ(cap_clamped_cosine(0.3, std::cos(89 * kPi / 180)), cap_clamped_cosine(0.3, std::cos(88 * kPi / 180)));
}

TEST(CapLights, MedianCutToAnyCount) {
  Probe p;
  ASSERT_TRUE(testing::load_real_probe("studio", &p, 128));
  const Rgb total = total_power(p);
  for (int count : {1, 3, 12, 64}) {
    const auto lights = median_cut_any_count(p, count);
    ASSERT_EQ(static_cast<int>(lights.size()), count);
    Rgb sum = Rgb::Zero();
    for (const auto& l : lights) {
      sum += l.power;
      EXPECT_GT(l.cap_cos_half_angle, 0.0);
      EXPECT_LE(l.cap_cos_half_angle, 1.0);
    }
    EXPECT_LT((sum - total).norm(), 1e-6 * total.norm()) << count;
  }
  const auto a = median_cut(p, 64), b = median_cut_any_count(p, 64);
  for (size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k].direction, b[k].direction);
}

}  // namespace
}  // namespace vdrig::probe
