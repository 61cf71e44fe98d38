// Simulated capture cost: render + expose patchwork at 1024x768 (2x2 samples per pixel, the default) for a subset
// of the views of a 289-view hemisphere capture, and extrapolate to all 289. The ray table (per-pixel undistorted
// rays) is built once per camera, as the simulated camera does, and timed separately.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <opencv2/core/utility.hpp>

#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"

using namespace vdrig;

namespace {
double now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
}  // namespace

int main(int argc, char** argv) {
  const int subset = argc > 1 ? std::atoi(argv[1]) : 24;
  const int total_views = 289;
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const CameraModel cam{1024, 768, 1280.0, 1280.0, 511.5, 383.5, -0.08, 0.02, 0.0, 0.0, 0.0};
  const int samples = 2;
  sim::SensorSettings sensor;
  sensor.full_well_e = 20000;
  sensor.read_noise_e = 3;

  double t0 = now_s();
  const sim::RayTable rays(cam, samples);
  const double table_s = now_s() - t0;

  // The subset: evenly spread over a 289-view hemisphere (golden-angle spiral in cos(zenith), zenith <= 80 deg),
  // every (289 / subset)-th view.
  const double cos_max = std::cos(deg_to_rad(80.0));
  double render_s = 0, expose_s = 0;
  int n = 0;
  for (int i = 0; i < total_views && n < subset; i += std::max(1, total_views / subset), ++n) {
    const double cz = 1.0 - (1.0 - cos_max) * (i + 0.5) / total_views;
    const double azimuth = std::fmod(i * 2.399963229728653, 2 * kPi);
    const PanTilt pt{kPi / 2 - azimuth, std::acos(cz)};
    const ViewPose pose = rig::surface_pose({}, pt);
    t0 = now_s();
    const cv::Mat radiance = sim::render_radiance(scene, rays, pose);
    const double t1 = now_s();
    const cv::Mat codes = sim::expose(radiance, 0.5, 1.0, sensor, static_cast<uint64_t>(i));
    render_s += t1 - t0;
    expose_s += now_s() - t1;
  }
  const double per_view = (render_s + expose_s) / n;
  std::printf("bench_sim_render: patchwork, %dx%d, %dx%d samples/pixel, %d threads\n", cam.width, cam.height, samples,
              samples, cv::getNumThreads());
  std::printf("  ray table (once per camera): %.3f s\n", table_s);
  std::printf("  %d of %d views measured: render %.3f s/view, expose %.3f s/view, total %.3f s/view\n", n, total_views,
              render_s / n, expose_s / n, per_view);
  std::printf("  extrapolated 289-view capture (one exposure per view): %.1f s (target < 1 s/view: %s)\n",
              table_s + per_view * total_views, per_view < 1.0 ? "met" : "NOT met");
  return 0;
}
