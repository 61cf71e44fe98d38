// Median-cut lights (Debevec 2005): power conservation, equal-energy regions, light directions, and the shading
// check that matters, irradiance from 64 / 256 lights against brute-force integration over the map.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "probe_support.hpp"
#include "vdrig/probe/median_cut.hpp"

namespace vdrig::probe {
namespace {

using testing::load_real_probe;
using testing::synthetic_probe;

double region_solid_angle(const MedianCutRegion& r, int W, int H) {
  double s = 0;
  for (int j = r.y0; j < r.y1; ++j) s += (r.x1 - r.x0) * latlong_pixel_solid_angle(j, W, H);
  return s;
}

void expect_partition_and_power(const Probe& p, const std::vector<DirectionalLight>& lights) {
  Rgb sum = Rgb::Zero();
  double area = 0;
  for (const auto& l : lights) {
    EXPECT_NEAR(l.direction.norm(), 1.0, 1e-12);
    EXPECT_LT(l.region.x0, l.region.x1);
    EXPECT_LT(l.region.y0, l.region.y1);
    sum += l.power;
    area += region_solid_angle(l.region, p.width(), p.height());
  }
  const Rgb total = total_power(p);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c] / total[c], 1.0, 1e-6) << "channel " << c;
  EXPECT_NEAR(area, 4 * kPi, 1e-9);  // the regions tile the sphere
}

// max / mean and min / mean of the region energies.
std::pair<double, double> energy_spread(const std::vector<DirectionalLight>& lights) {
  double mean = 0, lo = 1e300, hi = 0;
  for (const auto& l : lights) {
    mean += l.region.energy / lights.size();
    lo = std::min(lo, l.region.energy);
    hi = std::max(hi, l.region.energy);
  }
  return {hi / mean, lo / mean};
}

TEST(MedianCut, UniformMapGivesEqualSolidAngles) {
  // Equal energy on a uniform map means equal solid angle: a median cut without solid-angle weighting would give
  // the polar regions far more than 4 pi / 64 sr.
  const Probe p = synthetic_probe(256, [](const Vec3d&) { return Rgb::Ones(); });
  const auto lights = median_cut(p, 64);
  ASSERT_EQ(lights.size(), 64u);
  expect_partition_and_power(p, lights);
  double worst = 0;
  for (const auto& l : lights)
    worst = std::max(worst, std::abs(region_solid_angle(l.region, p.width(), p.height()) / (4 * kPi / 64) - 1));
  std::printf("uniform map, 64 regions: solid angle within %.2f %% of 4 pi / 64\n", 100 * worst);
  EXPECT_LT(worst, 0.05);
}

TEST(MedianCut, SmoothMapRegionsHaveEqualEnergy) {
  const Probe p = synthetic_probe(256, [](const Vec3d& d) {
    const double sky = 1 + 3 * std::max(0.0, d.z()),
                 blob = 20 * std::exp(-8 * (d - Vec3d(0.6, 0.0, 0.8)).squaredNorm());
    return Rgb(sky + blob, sky + 0.5 * blob, 0.5 * sky + 0.2 * blob);
  });
  for (int count : {4, 64, 256}) {
    const auto lights = median_cut(p, count);
    ASSERT_EQ(lights.size(), static_cast<size_t>(count));
    expect_partition_and_power(p, lights);
    const auto [hi, lo] = energy_spread(lights);
    std::printf("smooth map, %3d regions: energy max/mean %.3f, min/mean %.3f\n", count, hi, lo);
    EXPECT_LT(hi, 1.1);
    EXPECT_GT(lo, 0.9);
  }
}

TEST(MedianCut, SunGetsTheBrightestLight) {
  // A dim sky and a one-pixel sun holding 98 % of the energy: the sun's region cannot be halved below one pixel, so
  // its light carries far more than the mean power and points at the sun's pixel centre; all 64 lights are still
  // produced (the other regions are split further instead).
  Probe p = synthetic_probe(128, [](const Vec3d&) { return Rgb::Constant(0.1); });
  p.set_pixel(70, 40, Rgb(2e5, 1.6e5, 1.2e5));
  const Vec3d sun = latlong_direction(70, 40, 256, 128);
  const auto lights = median_cut(p, 64);
  ASSERT_EQ(lights.size(), 64u);
  expect_partition_and_power(p, lights);
  const auto brightest = std::max_element(lights.begin(), lights.end(), [](const auto& a, const auto& b) {
    return luminance(a.power) < luminance(b.power);
  });
  EXPECT_LT(rad_to_deg(angle_between(brightest->direction, sun)), 0.01);
  EXPECT_GT(luminance(brightest->power) / luminance(total_power(p)), 0.9);
}

TEST(MedianCut, RealProbes) {
  for (const char* name : testing::kRealProbes) {
    Probe p;
    ASSERT_TRUE(load_real_probe(name, &p));
    for (int count : {64, 256}) {
      const auto lights = median_cut(p, count);
      EXPECT_EQ(lights.size(), static_cast<size_t>(count));
      expect_partition_and_power(p, lights);
      const auto [hi, lo] = energy_spread(lights);
      // The lights carry (nearly) equal power, so "brightest" means highest mean radiance: the smallest region.
      const auto b = std::max_element(lights.begin(), lights.end(), [](const auto& x, const auto& y) {
        return luminance(x.power) / x.solid_angle_sr < luminance(y.power) / y.solid_angle_sr;
      });
      const double off_deg = rad_to_deg(angle_between(b->direction, brightest_pixel(p).direction));
      const Probe coarse = resample(p, 64);  // 16 x 16-pixel blocks (5.6 deg), about a 64-light region's size
      const double off_block_deg = rad_to_deg(angle_between(b->direction, brightest_pixel(coarse).direction));
      std::printf(
          "%-9s %3d lights: energy max/mean %.2f min/mean %.2f; brightest light (%d x %d px) %.2f deg from "
          "the brightest pixel, %.2f deg from the brightest 5.6-deg block\n",
          name, count, hi, lo, b->region.x1 - b->region.x0, b->region.y1 - b->region.y0, off_deg, off_block_deg);
      const std::string n = name;
      if (n == "courtyard") {
        // No sun disc here (the probe is under a carport roof): the brightest pixel is a one-pixel glint in the
        // foliage (luminance 53) while the sunlit sky and ground near the horizon average 18 over 5.6-deg blocks.
        // Measured at 64 lights: 2.0 deg from the brightest block; energies within 0.83..1.21 of the mean.
        if (count == 64) {
          EXPECT_LT(off_block_deg, 4.0) << "the brightest light must point at the brightest area";
        }
        EXPECT_LT(hi, 1.35);
        EXPECT_GT(lo, 0.7);
      }
      if (n == "interior") {
        // The ceiling lamp is a point source (a few pixels at luminance 3e4, clamped by the file's producer): the
        // sun-like case. Its light sits on the lamp's brightest pixel (measured 0.00 deg).
        EXPECT_LT(off_deg, 0.5) << "the brightest light must point at the lamp";
      }
    }
  }
}

TEST(MedianCut, IrradianceMatchesBruteForce) {
  const auto normals = fibonacci_directions(128);
  for (const char* name : testing::kRealProbes) {
    Probe p;
    ASSERT_TRUE(load_real_probe(name, &p));
    const auto reference = reference_irradiance(p, normals);
    for (int count : {64, 256}) {
      const auto lights = median_cut(p, count);
      const auto err = irradiance_error(
          normals, [&](const Vec3d& n) { return irradiance_from_lights(lights, n); }, reference);
      // The same cut on a map that forgot the solid angle (testing::without_solid_angle_weighting).
      const auto wrong_lights = median_cut(testing::without_solid_angle_weighting(p), count);
      const auto wrong = irradiance_error(
          normals, [&](const Vec3d& n) { return irradiance_from_lights(wrong_lights, n); }, reference);
      std::printf(
          "%-9s %3d lights: E error mean %.2f %%, max %.2f %%, mean |dE| / mean E %.2f %%  (without solid "
          "angle: mean %.1f %%, max %.1f %%)\n",
          name, count, 100 * err.mean, 100 * err.max, 100 * err.of_mean, 100 * wrong.mean, 100 * wrong.max);
      // Measured (1024 x 512 maps, 128 normals): 64 lights mean 0.85-1.84 %, max 5.5-10.2 %; 256 lights mean
      // 0.20-0.57 %, max 1.0-2.4 %. Forgetting the solid angle gives means of 13-29 %, far outside the bounds.
      const double mean_bound = count == 64 ? 0.025 : 0.008, max_bound = count == 64 ? 0.12 : 0.03;
      EXPECT_LT(err.mean, mean_bound) << name;
      EXPECT_LT(err.max, max_bound) << name;
      EXPECT_GT(wrong.mean, 4 * mean_bound) << name << ": the error bound must catch a missing solid angle";
    }
  }
}

}  // namespace
}  // namespace vdrig::probe
