// Cube maps: the face convention of cube_map.hpp (OpenGL's table on the probe frame), exact texel solid angles,
// lat-long <-> cube round trips, OpenEXR in and out, and the errors on bad files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "probe_support.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::probe {
namespace {

using testing::synthetic_probe;

TEST(CubeMap, DirectionsLandOnTheFaceAndTexelTheTableSays) {
  // One direction per face, with the (s, t) that docs/probe.md's table gives written out by hand.
  struct Case {
    Vec3d dir;
    CubeFace face;
    double s, t;
  };
  const Case cases[] = {
      {{1, 0.2, -0.3}, CubeFace::kPosX, (0.3 + 1) / 2, (-0.2 + 1) / 2},    // sc = -z, tc = -y
      {{-1, 0.2, -0.3}, CubeFace::kNegX, (-0.3 + 1) / 2, (-0.2 + 1) / 2},  // sc = +z, tc = -y
      {{0.2, 1, -0.3}, CubeFace::kPosY, (0.2 + 1) / 2, (-0.3 + 1) / 2},    // sc = +x, tc = +z
      {{0.2, -1, -0.3}, CubeFace::kNegY, (0.2 + 1) / 2, (0.3 + 1) / 2},    // sc = +x, tc = -z
      {{0.2, -0.3, 1}, CubeFace::kPosZ, (0.2 + 1) / 2, (0.3 + 1) / 2},     // sc = +x, tc = -y
      {{0.2, -0.3, -1}, CubeFace::kNegZ, (-0.2 + 1) / 2, (0.3 + 1) / 2},   // sc = -x, tc = -y
  };
  const int N = 16;
  for (const Case& c : cases) {
    for (double scale : {1.0, 3.5}) {
      const CubeCoordinates got = cube_coordinates(scale * c.dir, N);
      EXPECT_EQ(got.face, c.face) << to_string(c.face);
      EXPECT_NEAR(got.x, c.s * N, 1e-12) << to_string(c.face);
      EXPECT_NEAR(got.y, c.t * N, 1e-12) << to_string(c.face);
      // ... and back.
      EXPECT_LT((cube_direction(got.face, got.x, got.y, N) - c.dir.normalized()).norm(), 1e-12);
    }
  }
  // Texel (0, 0) of +Z (up) is the corner toward -x and +y; the centre of every face is its axis.
  EXPECT_GT(cube_direction(CubeFace::kPosZ, 0.5, 0.5, N).y(), 0);
  EXPECT_LT(cube_direction(CubeFace::kPosZ, 0.5, 0.5, N).x(), 0);
  const Vec3d axes[] = {Vec3d::UnitX(),  -Vec3d::UnitX(), Vec3d::UnitY(),
                        -Vec3d::UnitY(), Vec3d::UnitZ(),  -Vec3d::UnitZ()};
  for (int f = 0; f < kCubeFaceCount; ++f)
    EXPECT_LT((cube_direction(static_cast<CubeFace>(f), N / 2.0, N / 2.0, N) - axes[f]).norm(), 1e-12);
}

TEST(CubeMap, RandomDirectionsRoundTripThroughTexelCoordinates) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (int k = 0; k < 2000; ++k) {
    const Vec3d d = Vec3d(g(rng), g(rng), g(rng)).normalized();
    const CubeCoordinates c = cube_coordinates(d, 32);
    ASSERT_LT((cube_direction(c.face, c.x, c.y, 32) - d).norm(), 1e-12);
  }
}

TEST(CubeMap, TexelSolidAnglesAreExact) {
  for (int N : {1, 2, 7, 64, 256}) {
    const CubeMap cube = make_cube_map(N);
    EXPECT_NEAR(total_solid_angle(cube), 4 * kPi, 1e-6) << N;
  }
  // One texel per face: each face is 4 pi / 6. A corner texel of a fine cube is smaller than a centre one by the
  // cube's distortion (cos^3 of the 54.7 deg corner angle: 3^-1.5).
  EXPECT_NEAR(cube_texel_solid_angle(0, 0, 1), 4 * kPi / 6, 1e-12);
  const int N = 512;
  const double ratio = cube_texel_solid_angle(0, 0, N) / cube_texel_solid_angle(N / 2, N / 2, N);
  EXPECT_NEAR(ratio, std::pow(3.0, -1.5), 1e-2);
  // Against a brute subdivision of one off-centre texel.
  const int sub = 200;
  double brute = 0;
  for (int b = 0; b < sub; ++b)
    for (int a = 0; a < sub; ++a) {
      const double u = 2.0 * (3 + (a + 0.5) / sub) / 8 - 1, v = 2.0 * (1 + (b + 0.5) / sub) / 8 - 1;
      brute += (2.0 / 8 / sub) * (2.0 / 8 / sub) / std::pow(1 + u * u + v * v, 1.5);
    }
  EXPECT_NEAR(cube_texel_solid_angle(3, 1, 8), brute, 1e-7);
}

// A smooth map with some colour: 1 + 0.5 x + 0.3 y z, in three different shades.
Rgb smooth(const Vec3d& d) { return Rgb(1 + 0.5 * d.x() + 0.3 * d.y() * d.z(), 0.8 + 0.2 * d.z(), 0.5 + 0.4 * d.y()); }

TEST(CubeMap, LatLongToCubeToLatLongRoundTrip) {
  const Probe p = synthetic_probe(128, smooth);
  const CubeMap cube = latlong_to_cube(p, 64);
  // Texels hold the function at their centre within the resampling error.
  double worst_texel = 0;
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i) {
        const Rgb want = smooth(cube_direction(static_cast<CubeFace>(f), i + 0.5, j + 0.5, 64));
        worst_texel = std::max(worst_texel, (cube.texel(static_cast<CubeFace>(f), i, j) - want).cwiseAbs().maxCoeff());
      }
  const Probe back = cube_to_latlong(cube, 128);
  double worst = 0, mean = 0;
  for (int j = 0; j < back.height(); ++j)
    for (int i = 0; i < back.width(); ++i) {
      const double e = (back.pixel(i, j) - p.pixel(i, j)).cwiseAbs().maxCoeff();
      worst = std::max(worst, e);
      mean += e / (back.width() * back.height());
    }
  std::printf("lat-long 256 x 128 -> cube 6 x 64^2 -> lat-long: texel max %.2e, round trip mean %.2e, max %.2e\n",
              worst_texel, mean, worst);
  EXPECT_LT(worst_texel, 2e-3);
  EXPECT_LT(mean, 5e-4);
  EXPECT_LT(worst, 5e-3);
  // Power is kept through both conversions.
  EXPECT_NEAR(total_power(cube).x(), total_power(p).x(), 2e-3 * total_power(p).x());
  EXPECT_NEAR(total_power(back).x(), total_power(p).x(), 2e-3 * total_power(p).x());
}

TEST(CubeMap, ExrRoundTripIsExactAndBadFilesAreErrors) {
  const test::TempDir dir("cube");
  CubeMap cube = latlong_to_cube(synthetic_probe(32, smooth), 8);
  ASSERT_TRUE(save_cube_map(dir / "cube.exr", cube).is_ok());
  auto back = load_cube_map(dir / "cube.exr");
  ASSERT_TRUE(back) << back.error().describe();
  ASSERT_EQ(back->size, 8);
  for (int f = 0; f < kCubeFaceCount; ++f) EXPECT_EQ(cv::norm(back->faces[f], cube.faces[f], cv::NORM_INF), 0) << f;
  // The file is a strip with +x first: texel (0, 0) of face -x sits at column 8.
  auto exr = read_exr(dir / "cube.exr");
  ASSERT_TRUE(exr);
  EXPECT_EQ(exr->width, 48);
  EXPECT_EQ(exr->channels[exr->find("R")].at<float>(0, 8), static_cast<float>(cube.texel(CubeFace::kNegX, 0, 0).x()));

  EXPECT_EQ(load_cube_map(dir / "missing.exr").error().code, ErrorCode::kNotFound);
  ExrImage wrong;
  for (const char* c : {"R", "G", "B"}) wrong.add(c, cv::Mat(8, 40, CV_32FC1, cv::Scalar(1)));
  ASSERT_TRUE(write_exr(dir / "wrong.exr", wrong).is_ok());
  auto w = load_cube_map(dir / "wrong.exr");
  ASSERT_FALSE(w);
  EXPECT_EQ(w.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(w.error().message.find("6 x height"), std::string::npos) << w.error().message;
  ExrImage nan;
  for (const char* c : {"R", "G", "B"}) nan.add(c, cv::Mat(4, 24, CV_32FC1, cv::Scalar(1)));
  nan.channels[1].at<float>(2, 13) = std::numeric_limits<float>::quiet_NaN();
  ASSERT_TRUE(write_exr(dir / "nan.exr", nan).is_ok());
  auto n = load_cube_map(dir / "nan.exr");
  ASSERT_FALSE(n);
  EXPECT_EQ(n.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(n.error().message.find("face -y at texel (1, 2)"), std::string::npos) << n.error().message;
}

}  // namespace
}  // namespace vdrig::probe
