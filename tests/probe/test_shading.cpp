// A diffuse sphere lit by a probe: the three irradiance modes agree within the errors measured in
// test_median_cut / test_sh_irradiance, closed forms on a uniform map, and the tone mapper.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "probe_support.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/probe/shading.hpp"

namespace vdrig::probe {
namespace {

using testing::load_real_probe;
using testing::synthetic_probe;

// Mean over the sphere's pixels of |luminance(a) - luminance(b)| / luminance(b), and the fraction of pixels covered.
std::pair<double, double> compare(const cv::Mat& a, const cv::Mat& b) {
  double sum = 0;
  long n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      const cv::Vec3f &va = a.at<cv::Vec3f>(y, x), &vb = b.at<cv::Vec3f>(y, x);
      const double la = luminance(from_bgr(va)), lb = luminance(from_bgr(vb));
      if (lb <= 0) continue;
      sum += std::abs(la - lb) / lb;
      ++n;
    }
  return {n ? sum / n : 0.0, static_cast<double>(n) / (a.rows * a.cols)};
}

TEST(Shading, UniformLightGivesTheAlbedo) {
  // L = 1 everywhere: E = pi at every normal, so a Lambertian sphere reflects exactly its albedo.
  const Probe p = synthetic_probe(64, [](const Vec3d&) { return Rgb::Ones(); });
  SphereRenderOptions o;
  o.size_px = 32;
  o.albedo = Rgb(0.2, 0.5, 0.8);
  o.light_count = 256;
  for (ShadingMode m : {ShadingMode::kBruteForce, ShadingMode::kMedianCut, ShadingMode::kSh9}) {
    o.mode = m;
    const cv::Mat img = render_diffuse_sphere(p, o);
    ASSERT_EQ(img.type(), CV_32FC3);
    double worst = 0;
    int inside = 0;
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const cv::Vec3f v = img.at<cv::Vec3f>(y, x);
        if (v[0] == 0) continue;
        ++inside;
        worst = std::max(worst, (from_bgr(v) - o.albedo).cwiseAbs().maxCoeff() / 0.8);
      }
    std::printf("uniform map, %-10s: sphere radiance within %.2e of the albedo\n", to_string(m), worst);
    EXPECT_NEAR(inside, kPi * 16 * 16, 40);  // the disc covers pi r^2 pixels
    EXPECT_LT(worst, m == ShadingMode::kMedianCut ? 0.05 : 1e-3) << to_string(m);
    EXPECT_EQ(img.at<cv::Vec3f>(0, 0)[0], 0.0f);  // corners are outside the sphere
  }
}

TEST(Shading, CentrePixelFacesTheCamera) {
  // With the camera on +y, the centre pixel's normal is +y: its radiance is albedo / pi * E(+y).
  Probe p;
  ASSERT_TRUE(load_real_probe("courtyard", &p, 256));
  SphereRenderOptions o;
  o.size_px = 33;  // odd: a pixel centre on the axis
  o.mode = ShadingMode::kBruteForce;
  o.view_dir = Vec3d::UnitY();
  const cv::Mat img = render_diffuse_sphere(p, o);
  const Rgb expect = o.albedo.cwiseProduct(IrradianceIntegrator(p).irradiance(Vec3d::UnitY())) / kPi;
  const cv::Vec3f got = img.at<cv::Vec3f>(16, 16);
  EXPECT_LT((from_bgr(got) - expect).norm() / expect.norm(), 1e-5);
}

TEST(Shading, ThreeModesAgreeOnRealProbes) {
  for (const char* name : testing::kRealProbes) {
    Probe p;
    ASSERT_TRUE(load_real_probe(name, &p, 512));
    SphereRenderOptions o;
    o.size_px = 32;
    o.brute_width = 256;
    o.light_count = 256;
    o.mode = ShadingMode::kBruteForce;
    const cv::Mat brute = render_diffuse_sphere(p, o);
    o.mode = ShadingMode::kMedianCut;
    const cv::Mat mc = render_diffuse_sphere(p, o);
    o.mode = ShadingMode::kSh9;
    const cv::Mat sh = render_diffuse_sphere(p, o);
    const auto [mc_err, covered] = compare(mc, brute);
    const auto [sh_err, covered_sh] = compare(sh, brute);
    std::printf("%-9s sphere, mean relative difference to brute force: median-cut(256) %.2f %%, SH-9 %.2f %%\n", name,
                100 * mc_err, 100 * sh_err);
    EXPECT_NEAR(covered, kPi / 4, 0.03);
    // The per-normal means measured over the whole sphere of normals were <= 0.6 % (256 lights) and <= 8.7 % (SH);
    // the visible hemisphere is a subset, so allow the same bounds as those tests.
    EXPECT_LT(mc_err, 0.008) << name;
    EXPECT_LT(sh_err, name == std::string("studio") ? 0.105 : 0.06) << name;
  }
}

TEST(Shading, SphereImageIsTheToneMappedRenderWithItsGamma) {
  // A coloured sky (R, G and B differ, so a channel-order mistake shows) on a small map; SH-9 shading makes the
  // expected centre pixel exact: albedo / pi * E(view_dir), tone mapped with the gamma reported.
  const Probe p = synthetic_probe(32, [](const Vec3d& d) { return Rgb(2.0 + d.z(), 1.0 + 0.5 * d.y(), 0.3); });
  SphereRenderOptions o;
  o.size_px = 33;  // odd: a pixel centre on the axis
  o.albedo = Rgb(0.9, 0.5, 0.2);
  o.mode = ShadingMode::kSh9;
  o.view_dir = Vec3d::UnitY();
  const Rgb centre = o.albedo.cwiseProduct(sh9_irradiance(project_sh9(p), Vec3d::UnitY())) / kPi;
  cv::Mat centre_bgr(1, 1, CV_32FC3);
  centre_bgr.at<cv::Vec3f>(0, 0) = to_bgr(centre);
  for (double gamma : {0.0, 0.7}) {
    auto image = render_sphere_image(p, o, gamma);
    ASSERT_TRUE(image) << image.error().describe();
    ASSERT_EQ(image->bgr8.type(), CV_8UC3);
    ASSERT_EQ(image->bgr8.size(), cv::Size(33, 33));
    const double expect_gamma = gamma > 0 ? gamma : auto_gamma(render_diffuse_sphere(p, o));
    EXPECT_EQ(image->gamma, expect_gamma);
    const cv::Vec3b expect = tone_map_srgb8(centre_bgr, expect_gamma).at<cv::Vec3b>(0, 0);
    const cv::Vec3b got = image->bgr8.at<cv::Vec3b>(16, 16);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], expect[c], 1) << "gamma " << gamma << " channel " << c;
    EXPECT_GT(got[2], got[0]) << "red (more light, higher albedo) lands in OpenCV's third channel";
    EXPECT_EQ(image->bgr8.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));  // outside the sphere
  }
  o.size_px = 0;
  auto bad = render_sphere_image(p, o);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  o.size_px = 33;
  for (double gamma : {-1.0, std::nan("")}) {
    auto bad_gamma = render_sphere_image(p, o, gamma);
    ASSERT_FALSE(bad_gamma) << gamma;
    EXPECT_EQ(bad_gamma.error().code, ErrorCode::kInvalidArgument);
  }
}

TEST(Shading, ToneMapper) {
  cv::Mat bgr(1, 3, CV_32FC3);
  const double gamma = 2.0;
  bgr.at<cv::Vec3f>(0, 0) = to_bgr(Rgb(0, 0, 0));
  bgr.at<cv::Vec3f>(0, 1) = to_bgr(Rgb(std::log(2.0) / gamma, 0, 0));  // red; 1 - exp(-ln 2) = 0.5
  bgr.at<cv::Vec3f>(0, 2) = to_bgr(Rgb(0, 0, 1000));                   // blue
  const cv::Mat out = tone_map_srgb8(bgr, gamma);
  ASSERT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(out.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
  // sRGB(0.5) = 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354 -> 188; red lands in OpenCV's third (R) channel.
  EXPECT_EQ(out.at<cv::Vec3b>(0, 1), cv::Vec3b(0, 0, 188));
  EXPECT_EQ(out.at<cv::Vec3b>(0, 2), cv::Vec3b(255, 0, 0));
  // auto_gamma maps the mean luminance of the lit pixels to 0.5.
  cv::Mat flat(4, 4, CV_32FC3, cv::Scalar(3, 3, 3));
  EXPECT_NEAR(1 - std::exp(-auto_gamma(flat) * 3.0), 0.5, 1e-12);
}

}  // namespace
}  // namespace vdrig::probe
