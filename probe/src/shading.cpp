#include "vdrig/probe/shading.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <thread>
#include <vector>

#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/sh_irradiance.hpp"

namespace vdrig::probe {

const char* to_string(ShadingMode mode) {
  switch (mode) {
    case ShadingMode::kBruteForce:
      return "brute";
    case ShadingMode::kMedianCut:
      return "median-cut";
    case ShadingMode::kSh9:
      return "sh";
  }
  return "?";
}

bool parse_shading_mode(const std::string& name, ShadingMode* mode) {
  for (ShadingMode m : {ShadingMode::kBruteForce, ShadingMode::kMedianCut, ShadingMode::kSh9})
    if (name == to_string(m)) {
      *mode = m;
      return true;
    }
  return false;
}

bool SphereRenderOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (size_px < 1 || size_px > 4096) return fail("sphere image size must be 1..4096 pixels");
  if (!(albedo.minCoeff() >= 0 && albedo.maxCoeff() <= 1)) return fail("albedo must be in [0, 1] per channel");
  if (mode == ShadingMode::kMedianCut && (light_count < 1 || (light_count & (light_count - 1)) != 0))
    return fail("median-cut light count must be a power of two");
  if (mode == ShadingMode::kBruteForce && (brute_width < 2 || brute_width % 2 != 0))
    return fail("brute-force map width must be even and >= 2");
  if (!(view_dir.norm() > 0) || !(up.norm() > 0) || view_dir.normalized().cross(up.normalized()).norm() < 1e-6)
    return fail("view direction and up must be non-zero and not parallel");
  if (threads < 0) return fail("threads must be >= 0");
  return true;
}

cv::Mat render_diffuse_sphere(const Probe& probe, const SphereRenderOptions& o) {
  std::string why;
  VDRIG_CHECK(o.is_valid(&why), why);
  std::function<Rgb(const Vec3d&)> irradiance;
  // Only the chosen mode's precomputation is built; each is read-only afterwards, so rows can run in parallel.
  std::vector<DirectionalLight> lights;
  Sh9 sh;
  std::unique_ptr<IrradianceIntegrator> brute;
  switch (o.mode) {
    case ShadingMode::kBruteForce:
      brute = std::make_unique<IrradianceIntegrator>(probe, o.brute_width);
      irradiance = [&](const Vec3d& n) { return brute->irradiance(n); };
      break;
    case ShadingMode::kMedianCut:
      lights = median_cut(probe, o.light_count);
      irradiance = [&](const Vec3d& n) { return irradiance_from_lights(lights, n); };
      break;
    case ShadingMode::kSh9:
      sh = project_sh9(probe);
      irradiance = [&](const Vec3d& n) { return sh9_irradiance(sh, n); };
      break;
  }
  const Vec3d view = o.view_dir.normalized();
  const Vec3d up = (o.up - o.up.dot(view) * view).normalized();
  const Vec3d right = up.cross(view);
  const int N = o.size_px;
  cv::Mat out(N, N, CV_32FC3, cv::Scalar::all(0));
  auto rows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < N; ++x) {
        const double a = 2.0 * (x + 0.5) / N - 1.0, b = -(2.0 * (y + 0.5) / N - 1.0);
        const double r2 = a * a + b * b;
        if (r2 > 1.0) continue;
        const Vec3d n = (a * right + b * up + std::sqrt(1.0 - r2) * view).normalized();
        const Rgb L = o.albedo.cwiseProduct(irradiance(n)) / kPi;
        out.at<cv::Vec3f>(y, x) = to_bgr(L);
      }
  };
  const int threads =
      std::clamp(o.threads > 0 ? o.threads : static_cast<int>(std::thread::hardware_concurrency()), 1, std::max(1, N));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(rows, N * t / threads, N * (t + 1) / threads);
  for (auto& th : pool) th.join();
  return out;
}

cv::Mat tone_map_srgb8(const cv::Mat& bgr, double gamma) {
  VDRIG_CHECK(bgr.type() == CV_32FC3, "tone mapping expects CV_32FC3 (B, G, R)");
  cv::Mat out(bgr.size(), CV_8UC3);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3f& v = bgr.at<cv::Vec3f>(y, x);
      cv::Vec3b& o = out.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double t = 1.0 - std::exp(-gamma * std::max(0.0f, v[c]));
        const double s = t <= 0.0031308 ? 12.92 * t : 1.055 * std::pow(t, 1.0 / 2.4) - 0.055;
        o[c] = cv::saturate_cast<uchar>(std::lround(255.0 * std::clamp(s, 0.0, 1.0)));
      }
    }
  return out;
}

double auto_gamma(const cv::Mat& bgr) {
  VDRIG_CHECK(bgr.type() == CV_32FC3, "auto_gamma expects CV_32FC3 (B, G, R)");
  double sum = 0;
  long n = 0;
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const double l = luminance(from_bgr(bgr.at<cv::Vec3f>(y, x)));
      if (l > 0) {
        sum += l;
        ++n;
      }
    }
  return n > 0 && sum > 0 ? std::log(2.0) * n / sum : 1.0;
}

Result<SphereImage> render_sphere_image(const Probe& probe, const SphereRenderOptions& options, double gamma) {
  std::string why;
  if (!options.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  if (!(gamma >= 0) || !std::isfinite(gamma))
    return make_error(ErrorCode::kInvalidArgument, "tone-mapping gamma must be >= 0 (0: automatic)");
  const cv::Mat radiance = render_diffuse_sphere(probe, options);
  SphereImage image;
  image.gamma = gamma > 0 ? gamma : auto_gamma(radiance);
  image.bgr8 = tone_map_srgb8(radiance, image.gamma);
  return image;
}

}  // namespace vdrig::probe
