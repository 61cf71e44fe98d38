// The viewer's generated GLSL of every registered model (ReflectanceModel::glsl) against ParameterMap::evaluate: a
// headless render of a map with different parameters in every texel (the model's sample_parameters) must match,
// pixel by pixel, the same bilinear blend of per-texel radiance computed on the CPU. Needs an OpenGL 3.3 context
// (xvfb-run in CI).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cpu_reference.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::viewer {
namespace {

constexpr int kS = 6, kT = 5;
constexpr double kW = 600.0, kH = 500.0;

/// A map of the model with a different plausible texel in every texel (the model's own sample parameters).
fitting::ParameterMap make_map(const std::string& spec) {
  fitting::ModelPtr model = fitting::parse_model(spec).value();
  if (!model->storable()) model = model->storable_sample();
  fitting::ParameterMap map(model, kS, kT, kW, kH);
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) map.set_parameters(s, t, model->sample_parameters(static_cast<unsigned>(t * kS + s)));
  return map;
}

void check_render(const std::string& spec) {
  SCOPED_TRACE(spec);
  auto ctx = GlContext::create(64, 48, false);
  if (!ctx) VDRIG_SKIP_WITHOUT_GL() << "no OpenGL 3.3 context: " << ctx.error().describe();
  const fitting::ParameterMap map = make_map(spec);
  auto renderer = SurfaceRenderer::create(map);
  ASSERT_TRUE(renderer) << renderer.error().describe();

  CameraModel cam;
  cam.width = 64;
  cam.height = 48;
  cam.fx = cam.fy = 70.0;
  cam.cx = 31.5;
  cam.cy = 23.5;
  // Camera at an oblique direction (zenith ~40 degrees) looking at the surface centre.
  const Vec3d C(700.0, -450.0, 1000.0);
  const Vec3d z = (-C).normalized(), x = Vec3d::UnitY().cross(z).normalized(), y = z.cross(x);
  ViewPose pose;
  pose.R.row(0) = x.transpose();
  pose.R.row(1) = y.transpose();
  pose.R.row(2) = z.transpose();
  pose.t = -pose.R * C;
  RenderSettings settings;
  settings.samples_per_axis = 1;  // one ray through the pixel centre
  auto img = (*renderer)->render_radiance(cam, pose, settings);
  ASSERT_TRUE(img) << img.error().describe();

  int compared = 0;
  double worst = 0.0;
  for (int py = 0; py < cam.height; ++py)
    for (int px = 0; px < cam.width; ++px) {
      const Vec3d ray = pose.R.transpose() * cam.pixel_ray(Vec2d(px, py));
      const Vec3d p = C + (-C.z() / ray.z()) * ray;
      const cv::Vec3f bgr = img->at<cv::Vec3f>(py, px);
      // Pixels whose ray lands near the surface edge could fall either side in float: skip a 2 mm band.
      if (std::abs(p.x()) > 0.5 * kW - 2 || std::abs(p.y()) > 0.5 * kH - 2) continue;
      const Vec3d want = test::expected_radiance(map, p, C);
      for (int c = 0; c < 3; ++c) {
        const double rel = std::abs(bgr[2 - c] - want[c]) / std::abs(want[c]);
        worst = std::max(worst, rel);
        EXPECT_LT(rel, 1e-3) << "pixel " << px << "," << py << " channel " << c << ": " << bgr[2 - c] << " vs "
                             << want[c];
      }
      ++compared;
    }
  EXPECT_GT(compared, 300);
  std::printf("%s: %d pixels compared, worst relative difference %.2e\n", spec.c_str(), compared, worst);
}

// Every example of every registered family (ModelRegistry::examples): a new model is checked without editing this
// file.
TEST(RenderModels, EveryModelsGlslMatchesEvaluate) {
  const std::vector<std::string> names = fitting::model_registry().examples();
  ASSERT_FALSE(names.empty());
  for (const std::string& name : names) check_render(name);
}

}  // namespace
}  // namespace vdrig::viewer
