// The Probe type: lat-long layout, loading (errors, the panorama azimuth of the real files), resampling, lookup,
// power and brute-force irradiance against closed forms.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>

#include "probe_support.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::probe {
namespace {

namespace fs = std::filesystem;
using testing::load_real_probe;
using testing::synthetic_probe;

ExrImage rgb_exr(int W, int H, const std::function<Rgb(int, int)>& f) {
  ExrImage im;
  cv::Mat r(H, W, CV_32FC1), g(H, W, CV_32FC1), b(H, W, CV_32FC1);
  for (int j = 0; j < H; ++j)
    for (int c = 0; c < W; ++c) {
      const Rgb v = f(c, j);
      r.at<float>(j, c) = static_cast<float>(v.x());
      g.at<float>(j, c) = static_cast<float>(v.y());
      b.at<float>(j, c) = static_cast<float>(v.z());
    }
  im.add("R", r);
  im.add("G", g);
  im.add("B", b);
  return im;
}

TEST(Probe, LookupHitsPixelCentresAndWrapsInAzimuth) {
  const Probe p = synthetic_probe(16, [](const Vec3d& d) { return Rgb(d.x() + 1, d.y() + 1, d.z() + 1); });
  ASSERT_EQ(p.width(), 32);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      const Rgb got = radiance_at(p, latlong_direction(i, j, p.width(), p.height()));
      EXPECT_NEAR((got - p.pixel(i, j)).norm(), 0.0, 1e-5) << i << "," << j;
    }
  // Azimuth 0 lies halfway between the last and the first column: the lookup must average across the seam.
  const Vec3d seam = direction_from_spherical(0.0, kPi * 5.5 / 16);
  EXPECT_NEAR((radiance_at(p, seam) - 0.5 * (p.pixel(0, 5) + p.pixel(31, 5))).norm(), 0.0, 1e-5);
}

TEST(Probe, SolidAnglesAndPowerMatchClosedForms) {
  for (int h : {8, 64, 256}) {
    const Probe c = synthetic_probe(h, [](const Vec3d&) { return Rgb(1, 2, 3); });
    EXPECT_NEAR(total_solid_angle(c), 4 * kPi, 1e-12);
    EXPECT_NEAR((total_power(c) - 4 * kPi * Rgb(1, 2, 3)).norm(), 0.0, 1e-5);
  }
  // int (1 + z^2) dw = 4 pi (1 + 1/3): the centre-of-row rule converges as 1 / H^2.
  const Probe q = synthetic_probe(256, [](const Vec3d& d) { return Rgb::Constant(1 + d.z() * d.z()); });
  EXPECT_NEAR(total_power(q).x() / (4 * kPi * 4.0 / 3.0), 1.0, 2e-5);
}

TEST(Probe, BruteForceIrradianceMatchesClosedForms) {
  // L = 1 everywhere: E = pi for every normal. L = 1 + z: E(n) = pi + (2 pi / 3) n_z.
  const Probe one = synthetic_probe(128, [](const Vec3d&) { return Rgb::Ones(); });
  const Probe lin = synthetic_probe(128, [](const Vec3d& d) { return Rgb::Constant(1 + d.z()); });
  const IrradianceIntegrator a(one), b(lin);
  for (const Vec3d& n : fibonacci_directions(50)) {
    EXPECT_NEAR(a.irradiance(n).x(), kPi, 2e-4 * kPi);
    EXPECT_NEAR(b.irradiance(n).y(), kPi + 2 * kPi / 3 * n.z(), 2e-4 * kPi);
  }
}

TEST(Probe, LoadErrorsAreValues) {
  const test::TempDir dir("probe");
  auto missing = load_probe(dir / "nope.exr");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);

  { std::ofstream(dir / "junk.exr") << "this is not an OpenEXR file"; }
  auto junk = load_probe(dir / "junk.exr");
  ASSERT_FALSE(junk);
  EXPECT_EQ(junk.error().code, ErrorCode::kCorrupt) << junk.error().describe();

  ASSERT_TRUE(write_exr(dir / "square.exr", rgb_exr(32, 32, [](int, int) { return Rgb::Ones(); })));
  auto square = load_probe(dir / "square.exr");
  ASSERT_FALSE(square);
  EXPECT_EQ(square.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(square.error().message.find("2:1"), std::string::npos) << square.error().message;

  ExrImage grey;
  grey.add("Y", cv::Mat(16, 32, CV_32FC1, cv::Scalar(1)));
  ASSERT_TRUE(write_exr(dir / "grey.exr", grey));
  auto no_rgb = load_probe(dir / "grey.exr");
  ASSERT_FALSE(no_rgb);
  EXPECT_EQ(no_rgb.error().code, ErrorCode::kCorrupt);

  LoadOptions odd;
  odd.width = 33;
  auto bad_width = load_probe(dir / "square.exr", odd);
  ASSERT_FALSE(bad_width);
  EXPECT_EQ(bad_width.error().code, ErrorCode::kInvalidArgument);
}

TEST(Probe, PanoramaFilesAreMirroredIntoTheDesignNotesLayout) {
  // A file in Blender's equirectangular layout (u = 0.5 - atan2(y, x) / 2 pi, row 0 up) storing each pixel's own
  // direction: after loading, every pixel must hold vdrig's direction of its new column.
  const int W = 64, H = 32;
  const test::TempDir dir("probe");
  ASSERT_TRUE(write_exr(dir / "pano.exr", rgb_exr(W, H, [&](int c, int j) {
                          const double u = (c + 0.5) / W, elevation = kPi / 2 - kPi * (j + 0.5) / H;
                          const double azimuth = 2 * kPi * (0.5 - u);  // Blender: atan2(y, x) = 2 pi (0.5 - u)
                          const Vec3d d(std::cos(elevation) * std::cos(azimuth),
                                        std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
                          return Rgb(d.x() + 1, d.y() + 1, d.z() + 1);
                        })));
  auto p = load_probe(dir / "pano.exr");
  ASSERT_TRUE(p) << p.error().describe();
  double worst = 0;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i)
      worst = std::max(worst, (p->pixel(i, j) - latlong_direction(i, j, W, H) - Rgb::Ones()).norm());
  EXPECT_LT(worst, 1e-6);
  // The same file read as already in vdrig's layout is not mirrored.
  LoadOptions as_is;
  as_is.azimuth = FileAzimuth::kDesignNotes;
  auto q = load_probe(dir / "pano.exr", as_is);
  ASSERT_TRUE(q);
  EXPECT_GT((q->pixel(0, 16) - latlong_direction(0, 16, W, H) - Rgb::Ones()).norm(), 0.5);
}

TEST(Probe, SaveLoadRoundTripKeepsPoseAndDepth) {
  Probe p = synthetic_probe(16, [](const Vec3d& d) { return Rgb(d.x() + 1, 2, d.z() + 3); });
  p.position_mm = Vec3d(100, -250.5, 1200);
  p.rotation = Eigen::AngleAxisd(0.3, Vec3d(1, 2, 3).normalized()).toRotationMatrix();
  p.depth_mm = cv::Mat(16, 32, CV_32FC1);
  cv::randu(p.depth_mm, 100, 5000);
  const test::TempDir dir("probe");
  ASSERT_TRUE(save_probe(dir / "p.exr", p));
  LoadOptions o;  // kPanorama: must be ignored for our own files
  auto q = load_probe(dir / "p.exr", o);
  ASSERT_TRUE(q) << q.error().describe();
  EXPECT_EQ(cv::norm(p.radiance, q->radiance, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(p.depth_mm, q->depth_mm, cv::NORM_INF), 0.0);
  EXPECT_LT((p.position_mm - q->position_mm).norm(), 1e-9);
  EXPECT_LT((p.rotation - q->rotation).norm(), 1e-12);
}

TEST(Probe, ResamplingKeepsPowerAndIrradiance) {
  Probe p;
  ASSERT_TRUE(load_real_probe("interior", &p));
  const Rgb full = total_power(p);
  const Probe small = resample(p, 256);
  ASSERT_EQ(small.width(), 256);
  ASSERT_EQ(small.height(), 128);
  const double power_err = (total_power(small) - full).norm() / full.norm();
  std::printf("interior: power %.4f %.4f %.4f; 1024 -> 256 changes it by %.2e\n", full.x(), full.y(), full.z(),
              power_err);
  EXPECT_LT(power_err, 1e-6);  // solid-angle-weighted block means keep it exactly
  // Enlarging a smooth map by bilinear lookup keeps it (to the curvature of the interpolant).
  const Probe smooth = synthetic_probe(32, [](const Vec3d& d) { return Rgb::Constant(2 + d.x() * d.y() + d.z()); });
  const Probe big = resample(smooth, 256);
  EXPECT_NEAR(total_power(big).x() / total_power(smooth).x(), 1.0, 2e-3);

  const IrradianceIntegrator cheap(p, 256);
  EXPECT_EQ(cheap.width(), 256);
  const auto normals = fibonacci_directions(64);
  const auto err = irradiance_error(
      normals, [&](const Vec3d& n) { return cheap.irradiance(n); }, reference_irradiance(p, normals));
  std::printf("interior: brute-force E on a 256-wide map vs 1024: mean %.2e, max %.2e relative\n", err.mean, err.max);
  // Measured 1.1e-3 mean, 3.8e-3 max: the lamp (luminance 3e4 in one pixel) moves by up to 1.5 map pixels.
  EXPECT_LT(err.mean, 2e-3);
  EXPECT_LT(err.max, 6e-3);
}

TEST(Probe, RealProbesAreUpright) {
  // Row 0 must look up: in each file the brightest pixel (the sun, a ceiling lamp, a softbox) is above the horizon.
  for (const char* name : testing::kRealProbes) {
    Probe p;
    ASSERT_TRUE(load_real_probe(name, &p));
    EXPECT_EQ(p.width(), 1024);
    EXPECT_EQ(p.height(), 512);
    const BrightestPixel b = brightest_pixel(p);
    const SphericalDir s = spherical_from_direction(b.direction);
    std::printf("%-9s brightest pixel column %d row %d: azimuth %.1f deg, zenith %.1f deg, luminance %.1f\n", name,
                b.column, b.row, rad_to_deg(s.azimuth_rad), rad_to_deg(s.zenith_rad), luminance(b.radiance));
    EXPECT_LT(s.zenith_rad, kPi / 2) << name;
  }
}

}  // namespace
}  // namespace vdrig::probe
