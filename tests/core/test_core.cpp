// core: conventions, camera model, response curve and file I/O.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "vdrig/core/camera.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/response.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;

TEST(Geometry, SphericalRoundTripAndConventions) {
  const Vec3d d = direction_from_spherical(deg_to_rad(30), deg_to_rad(60));
  EXPECT_NEAR(d.norm(), 1.0, 1e-15);
  EXPECT_GT(d.y(), 0);  // azimuth runs from +x toward +y
  const SphericalDir s = spherical_from_direction(d);
  EXPECT_NEAR(rad_to_deg(s.azimuth_rad), 30, 1e-12);
  EXPECT_NEAR(rad_to_deg(s.zenith_rad), 60, 1e-12);
  EXPECT_NEAR(rad_to_deg(spherical_from_direction({0, -1, 0}).azimuth_rad), 270, 1e-12);
}

TEST(Geometry, LatLongSolidAnglesCoverTheSphere) {
  const int W = 64, H = 32;
  double total = 0;
  for (int j = 0; j < H; ++j) total += W * latlong_pixel_solid_angle(j, W, H);
  EXPECT_NEAR(total, 4 * kPi, 1e-12);
  EXPECT_NEAR(latlong_direction(0, 0, W, H).z(), std::cos(kPi * 0.5 / H), 1e-12);  // row 0 looks along +z
}

TEST(Geometry, TexelCentresFollowTheDesignNotes) {
  const Vec3d c = texel_centre_mm(0, 0, 4, 2, 1000, 500);
  EXPECT_DOUBLE_EQ(c.x(), 125 - 500);
  EXPECT_DOUBLE_EQ(c.y(), 125 - 250);
}

TEST(CameraModel, UndistortInvertsDistortAndProjectMatchesRay) {
  CameraModel cam{640, 480, 536, 536, 342, 235, -0.266, -0.0386, 0.0018, -0.00028, 0.238};
  for (double x = -0.5; x <= 0.5; x += 0.1)
    for (double y = -0.4; y <= 0.4; y += 0.1) {
      const Vec2d u(x, y);
      EXPECT_LT((cam.undistort(cam.distort(u)) - u).norm(), 1e-9);
    }
  const Vec3d p(120, -80, 900);
  const Vec2d px = cam.project(p);
  EXPECT_LT(angle_between(cam.pixel_ray(px), p.normalized()), 1e-9);
}

TEST(CameraModel, YamlRoundTripAndBadFiles) {
  const test::TempDir d("core_yaml");
  CameraModel cam{640, 480, 536, 530, 342, 235, -0.2, 0.05, 0.001, -0.002, 0.1};
  ASSERT_TRUE(cam.save_yaml(d / "camera.yml", 0.3));
  auto back = CameraModel::load_yaml(d / "camera.yml");
  ASSERT_TRUE(back) << back.error().describe();
  EXPECT_DOUBLE_EQ(back->fy, 530);
  EXPECT_DOUBLE_EQ(back->k3, 0.1);
  EXPECT_EQ(CameraModel::load_yaml(d / "missing.yml").error().code, ErrorCode::kNotFound);
  std::ofstream(d / "bad.yml") << "%YAML:1.0\n---\nimage_width: 10\n";
  EXPECT_EQ(CameraModel::load_yaml(d / "bad.yml").error().code, ErrorCode::kCorrupt);
}

TEST(ResponseCurve, SCurveIsMonotonicAndInverts) {
  const ResponseCurve r = ResponseCurve::s_curve(8);
  EXPECT_EQ(r.forward(0, 0.0), 0.0);
  EXPECT_EQ(r.forward(0, 2.0), 255.0);
  for (int k = 1; k < 255; ++k) {
    ASSERT_GT(r.inverse(0, k), r.inverse(0, k - 1));
    EXPECT_NEAR(r.forward(0, r.inverse(0, k)), k, 1e-9);
  }
  auto j = ResponseCurve::from_json(r.to_json());
  ASSERT_TRUE(j);
  EXPECT_DOUBLE_EQ(j->inverse(1, 100.5), r.inverse(1, 100.5));
  std::array<std::vector<double>, 3> bad{std::vector<double>(256, 0.5), std::vector<double>(256, 0.5),
                                         std::vector<double>(10, 0.0)};
  EXPECT_FALSE(ResponseCurve::from_inverse(8, bad));
}

TEST(ImageIo, ExrRoundTripKeepsChannelsAndAttributes) {
  const test::TempDir d("core_exr");
  ExrImage img;
  cv::Mat a(3, 5, CV_32FC1), b(3, 5, CV_32FC1);
  cv::randu(a, -10, 1e4);
  cv::randu(b, 0, 1);
  img.add("kd.R", a);
  img.add("m", b);
  img.string_attributes["vdrig.model"] = "phong";
  img.number_attributes["vdrig.lobes"] = 2;
  for (ExrPixelType type : {ExrPixelType::kFloat, ExrPixelType::kHalf}) {
    ASSERT_TRUE(write_exr(d / "x.exr", img, type));
    auto back = read_exr(d / "x.exr");
    ASSERT_TRUE(back) << back.error().describe();
    ASSERT_EQ(back->find("m"), 1);
    const double tol = type == ExrPixelType::kFloat ? 0.0 : 1e-3;  // half: 11-bit mantissa
    EXPECT_LE(cv::norm(back->channels[1], b, cv::NORM_INF), tol);
    EXPECT_LE(cv::norm(back->channels[0], a, cv::NORM_INF | cv::NORM_RELATIVE), tol);
    EXPECT_EQ(back->string_attributes.at("vdrig.model"), "phong");
    EXPECT_EQ(back->number_attributes.at("vdrig.lobes"), 2);
  }
  // A truncated file is an error value, not a crash.
  const auto size = fs::file_size(d / "x.exr");
  fs::resize_file(d / "x.exr", size / 2);
  EXPECT_EQ(read_exr(d / "x.exr").error().code, ErrorCode::kCorrupt);
  std::ofstream(d / "text.exr") << "not an exr";
  EXPECT_EQ(read_exr(d / "text.exr").error().code, ErrorCode::kCorrupt);
  EXPECT_EQ(read_exr(d / "none.exr").error().code, ErrorCode::kNotFound);
}

TEST(ImageIo, AtomicWriteLeavesNoTemporaryAndReportsBadFolders) {
  const test::TempDir d("core_atomic");
  ASSERT_TRUE(write_file_atomic(d / "a.txt", "hello"));
  ASSERT_TRUE(write_file_atomic(d / "a.txt", "world"));
  std::ifstream in(d / "a.txt");
  std::string s;
  in >> s;
  EXPECT_EQ(s, "world");
  int files = 0;
  for (const auto& e : fs::directory_iterator(d)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  EXPECT_FALSE(write_file_atomic(d / "no" / "such" / "dir.txt", "x"));
  EXPECT_FALSE(write_png(d / "empty.png", cv::Mat()));
}

}  // namespace
}  // namespace vdrig
