// Frame time of the viewer's shader at 1280 x 720 for each model on a 512 x 512 map (Mesa llvmpipe here): how the
// per-fragment cost grows with the coefficient count. Each frame is SurfaceRenderer::draw_tone_mapped into the
// invisible window's framebuffer, then glFinish; the median of --frames timed frames after one warm-up frame.
// Usage: bench_viewer [--frames N] [--samples S]  (needs a display: xvfb-run -a bench_viewer).
#include <GL/gl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/viewer/interactive.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace {
using namespace vdrig;

constexpr int kTexels = 512, kWidth = 1280, kHeight = 720;
constexpr double kSurfaceMm = 1000.0;

/// A map of plausible, texel-varying parameters (the shader's cost does not depend on the values).
fitting::ParameterMap make_map(const std::string& spec) {
  fitting::ParameterMap map(fitting::parse_model(spec).value(), kTexels, kTexels, kSurfaceMm, kSurfaceMm);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto* harmonic = dynamic_cast<const fitting::HarmonicModel*>(&map.model());
  for (int t = 0; t < kTexels; ++t)
    for (int s = 0; s < kTexels; ++s) {
      if (harmonic) {
        Eigen::MatrixXd c(harmonic->coefficients_per_channel(), 3);
        for (int i = 0; i < c.rows(); ++i)
          for (int ch = 0; ch < 3; ++ch) c(i, ch) = i == 0 ? 1.0 + u(rng) : 0.2 * (u(rng) - 0.5);
        fitting::set_harmonic_coefficients(map, s, t, c);
      } else {
        fitting::PhongParams p;
        p.kd = Vec3d(u(rng), u(rng), u(rng)) * 0.5;
        const int lobes = map.model().name() == "phong:2" ? 2 : 1;
        for (int k = 0; k < lobes; ++k)
          p.lobes.push_back({Vec3d::Constant(0.5 + u(rng)),
                             direction_from_spherical(2 * kPi * u(rng), deg_to_rad(20 + 30 * u(rng))),
                             5 + 50 * u(rng)});
        fitting::set_phong_texel(map, s, t, p);
      }
    }
  return map;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 5, samples = 2;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--frames")) frames = std::max(1, std::atoi(argv[i + 1]));
    if (!std::strcmp(argv[i], "--samples")) samples = std::clamp(std::atoi(argv[i + 1]), 1, 8);
  }
  auto ctx = viewer::GlContext::create(kWidth, kHeight, false);
  if (!ctx) {
    std::fprintf(stderr, "bench_viewer: %s\n", ctx.error().describe().c_str());
    return 1;
  }
  // The viewer's free camera, 30 degrees off the normal: the surface covers most of the frame.
  const CameraModel camera = viewer::default_pinhole(kSurfaceMm, kSurfaceMm, kWidth, kHeight);
  const ViewPose pose = viewer::orbit_pose(Vec3d::Zero(), deg_to_rad(250), deg_to_rad(30), 2500.0);
  std::printf("bench_viewer: %dx%d frame, %dx%d-texel map, %d sub-samples per pixel, median of %d frames, %s\n", kWidth,
              kHeight, kTexels, kTexels, samples * samples, frames, (*ctx)->renderer().c_str());
  std::printf("%-10s %12s %10s %8s %16s\n", "model", "parameters", "frame ms", "fps", "ms / parameter");
  viewer::RenderSettings settings;
  settings.samples_per_axis = samples;
  for (const char* spec : {"phong:1", "phong:2", "sh-ls:4", "hsh:5", "sh-ls:6", "sh-ls:8", "sh-ls:10"}) {
    const fitting::ParameterMap map = make_map(spec);
    auto renderer = viewer::SurfaceRenderer::create(map);
    if (!renderer) {
      std::fprintf(stderr, "%s: %s\n", spec, renderer.error().describe().c_str());
      return 1;
    }
    std::vector<double> ms;
    for (int f = 0; f <= frames; ++f) {
      const auto start = std::chrono::steady_clock::now();
      glViewport(0, 0, kWidth, kHeight);
      (*renderer)->draw_tone_mapped(camera, pose, settings, 1.0);
      glFinish();
      const double t = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      if (f > 0) ms.push_back(t);  // frame 0 warms up (shader compilation happens at first use)
    }
    std::sort(ms.begin(), ms.end());
    const double median = ms[ms.size() / 2];
    const int parameters = map.model().parameter_count();  // floats per texel (SH-N / HSH-N: 3 N coefficients)
    std::printf("%-10s %12d %10.1f %8.2f %16.3f\n", spec, parameters, median, 1000.0 / median, median / parameters);
  }
  return 0;
}
