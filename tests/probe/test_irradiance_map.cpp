// Irradiance maps (irradiance_map.hpp): the white furnace for every method on lat-long and cube maps, the method
// parser, the output layout, hybrid against median cut and SH-9 on a real probe, and every method on the three real
// probes against the brute-force convolution (issue 28).
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "probe_support.hpp"
#include "vdrig/probe/irradiance_map.hpp"

namespace vdrig::probe {
namespace {

using testing::load_real_probe;
using testing::synthetic_probe;

// The white-furnace methods and their bounds on the mean |E / (pi L) - 1|, lat-long and cube: about 1.5x the measured
// values (docs/probe.md's table). hybrid:16's lights are 16 regions of 0.8 sr, whose shapes (lat-long rectangles,
// some with a corner at a pole) a cap only approximates: their remainder over SH-9 does not quite cancel.
struct FurnaceCase {
  const char* method;
  double latlong_bound, cube_bound;
};
const FurnaceCase kMethods[] = {{"exact", 2.6e-5, 3.3e-5},          // measured 0.0017, 0.0022 %
                                {"sh9", 2.4e-5, 1e-6},              // 0.0016, 0.0000 %
                                {"mediancut:256", 0.0019, 0.0016},  // 0.127, 0.103 %
                                {"hybrid:16", 0.0134, 0.0154},      // 0.89, 1.02 %
                                {"hybrid:64", 0.0059, 0.0052},      // 0.39, 0.34 %
                                {"soft:64", 0.00038, 0.00044}};     // 0.025, 0.029 %

IrradianceMethodSpec method(const std::string& text) {
  auto m = parse_irradiance_method(text);
  VDRIG_CHECK(static_cast<bool>(m), text);
  return *m;
}

// Mean and max |E / (pi L) - 1| over the pixels of a lat-long map or the texels of a cube (luminance).
struct Furnace {
  double mean = 0, max = 0;
  void add(const Rgb& e, double expected, double weight) {
    const double d = std::abs(luminance(e) / expected - 1);
    mean += weight * d;
    max = std::max(max, d);
  }
};

TEST(IrradianceMap, WhiteFurnaceLatLong) {
  const double L = 0.7;
  const Probe white = synthetic_probe(128, [L](const Vec3d&) { return Rgb::Constant(L); });
  for (const FurnaceCase& c : kMethods) {
    const char* text = c.method;
    const Probe e = irradiance_latlong(IrradianceModel::build(white, method(text)), 64);
    Furnace f;
    for (int j = 0; j < e.height(); ++j)
      for (int i = 0; i < e.width(); ++i) f.add(e.pixel(i, j), kPi * L, 1.0 / (e.width() * e.height()));
    std::printf("white furnace, lat-long, %-14s mean %.4f %%, max %.4f %%\n", text, 100 * f.mean, 100 * f.max);
    EXPECT_LT(f.mean, c.latlong_bound) << text;
  }
}

TEST(IrradianceMap, WhiteFurnaceCube) {
  const double L = 2.5;
  CubeMap white = make_cube_map(32);
  for (cv::Mat& face : white.faces) face.setTo(cv::Scalar::all(L));
  for (const FurnaceCase& c : kMethods) {
    const char* text = c.method;
    const CubeMap e = irradiance_cube(IrradianceModel::build(white, method(text)), 16);
    Furnace f;
    for (int face = 0; face < kCubeFaceCount; ++face)
      for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i)
          f.add(e.texel(static_cast<CubeFace>(face), i, j), kPi * L, cube_texel_solid_angle(i, j, 16) / (4 * kPi));
    std::printf("white furnace, cube,     %-14s mean %.4f %%, max %.4f %%\n", text, 100 * f.mean, 100 * f.max);
    EXPECT_LT(f.mean, c.cube_bound) << text;
  }
}

TEST(IrradianceMap, ParsesMethodsAndRejectsBadOnes) {
  for (const char* text : {"exact", "sh9", "mediancut:64", "hybrid:3", "soft:16"})
    EXPECT_EQ(to_string(method(text)), text);
  EXPECT_EQ(method("hybrid:3").light_count, 3);
  for (const char* bad :
       {"", "brute", "mediancut", "mediancut:", "mediancut:48", "hybrid:0", "hybrid:x", "sh9:4", "soft:-2"}) {
    auto m = parse_irradiance_method(bad);
    ASSERT_FALSE(m) << bad;
    EXPECT_EQ(m.error().code, ErrorCode::kInvalidArgument) << bad;
  }
}

TEST(IrradianceMap, PixelsHoldIrradianceAtTheirNormalInTheInputLayout) {
  // A map lit from one small patch: E peaks at the pixel looking at the patch, and each output pixel is E at its
  // own centre direction.
  const Vec3d sun = Vec3d(0.3, -0.5, 0.6).normalized();
  const Probe p = synthetic_probe(64, [&](const Vec3d& d) { return Rgb::Constant(d.dot(sun) > 0.99 ? 100.0 : 0.1); });
  const IrradianceModel model = IrradianceModel::build(p, method("exact"));
  const Probe e = irradiance_latlong(model, 32);
  ASSERT_EQ(e.width(), 32);
  ASSERT_EQ(e.height(), 16);
  for (int j = 0; j < 16; j += 5)
    for (int i = 0; i < 32; i += 7) {
      const Rgb want = model.irradiance(latlong_direction(i, j, 32, 16));
      EXPECT_NEAR(e.pixel(i, j).x(), want.x(), 1e-5 * want.x());
    }
  const BrightestPixel b = brightest_pixel(e);
  EXPECT_GT(b.direction.dot(sun), std::cos(12 * kPi / 180));
}

TEST(IrradianceMap, HybridBeatsSh9AndKeepsMedianCutsAccuracyOnTheInterior) {
  Probe p;
  ASSERT_TRUE(load_real_probe("interior", &p, 256));
  const std::vector<Vec3d> normals = fibonacci_directions(256);
  const std::vector<Rgb> ref = reference_irradiance(p, normals);
  auto stats = [&](const char* text) {
    const IrradianceModel m = IrradianceModel::build(p, method(text));
    const IrradianceErrorStats s = irradiance_error(
        normals, [&](const Vec3d& n) { return m.irradiance(n); }, ref);
    std::printf("interior 256 x 128, %-14s mean %.2f %%, max %.2f %%\n", text, 100 * s.mean, 100 * s.max);
    return s;
  };
  const IrradianceErrorStats sh9 = stats("sh9"), hybrid = stats("hybrid:8"), mc = stats("mediancut:8");
  EXPECT_LT(hybrid.mean, 0.5 * sh9.mean);
  EXPECT_LT(hybrid.mean, mc.mean);
  EXPECT_LT(stats("exact").max, 1e-5);
}

// Every method on the three real probes (loaded at 256 x 128) against the brute-force convolution of the same map,
// at the centre normal of every pixel of a 64 x 32 map: solid-angle-weighted mean of |Y - Y_ref| / Y_ref (the measure
// of bench_probe_irradiance, which runs it on the full 1024 x 512 maps for docs/probe.md). Bounds about 1.5x the
// measured value (courtyard, interior, studio; measured values in the comments).
TEST(IrradianceMap, EveryMethodOnTheRealProbesAgainstTheBruteForceConvolution) {
  struct Case {
    const char* method;
    double bound[3];
  };
  // clang-format off
  const Case cases[] = {
      {"sh9", {0.071, 0.075, 0.13}},             // measured 4.71, 4.96, 8.69 %
      {"mediancut:16", {0.054, 0.076, 0.12}},    // 3.61, 5.07, 8.02 %
      {"mediancut:64", {0.027, 0.014, 0.012}},   // 1.83, 0.94, 0.78 %
      {"hybrid:16", {0.026, 0.016, 0.029}},      // 1.72, 1.04, 1.95 % (before issue 28: 3-7 %)
      {"hybrid:64", {0.011, 0.0051, 0.0047}},    // 0.76, 0.34, 0.31 % (before: 1.4-7.5 %)
      {"soft:16", {0.017, 0.030, 0.0081}},       // 1.10, 1.98, 0.54 %
      {"soft:64", {0.0043, 0.0080, 0.011}},      // 0.29, 0.53, 0.71 %
  };
  // clang-format on
  const int W = 64, H = 32;
  std::vector<Vec3d> normals;
  std::vector<double> weights;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      normals.push_back(latlong_direction(i, j, W, H));
      weights.push_back(latlong_pixel_solid_angle(j, W, H) / (4 * kPi));
    }
  std::map<std::string, std::vector<double>> measured;
  for (int k = 0; k < 3; ++k) {
    Probe p;
    ASSERT_TRUE(load_real_probe(testing::kRealProbes[k], &p, 256));
    const std::vector<Rgb> ref = reference_irradiance(p, normals);
    for (const Case& c : cases) {
      const IrradianceModel m = IrradianceModel::build(p, method(c.method));
      double mean = 0;
      for (size_t n = 0; n < normals.size(); ++n)
        mean += weights[n] * std::abs(luminance(m.irradiance(normals[n])) / luminance(ref[n]) - 1);
      std::printf("%-10s %-14s mean %.3f %% (bound %.2f %%)\n", testing::kRealProbes[k], c.method, 100 * mean,
                  100 * c.bound[k]);
      EXPECT_LT(mean, c.bound[k]) << c.method << " on " << testing::kRealProbes[k];
      measured[c.method].push_back(mean);
    }
    // What issue 28 asked: the hybrid beats median cut at equal light count on every real probe.
    for (const char* n : {"16", "64"})
      EXPECT_LT(measured[std::string("hybrid:") + n][k], measured[std::string("mediancut:") + n][k])
          << n << " lights on " << testing::kRealProbes[k];
  }
  const auto& h = measured["hybrid:64"];
  EXPECT_LT((h[0] + h[1] + h[2]) / 3, 0.01) << "hybrid:64 must stay under 1 % on average";
}

}  // namespace
}  // namespace vdrig::probe
