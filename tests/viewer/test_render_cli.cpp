// `vdrig render` checked against independent references: an orbit frame against the CPU evaluation of the model
// (cpu_reference.hpp) pixel by pixel, and a captured view of a simulated session against that view's HDR photograph
// for a map holding the simulator's ground-truth Phong parameters. Plus the tone-mapped PNG and the usage errors.
// Needs an X display with OpenGL 3.3 (xvfb-run in CI); skipped with the reason otherwise.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "../pipeline/small_session.hpp"
#include "../pipeline/truth_map.hpp"
#include "cpu_reference.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/viewer/headless.hpp"
#include "vdrig/viewer/interactive.hpp"

namespace vdrig::viewer {
namespace {
namespace fs = std::filesystem;

using vdrig::test::ProcessRun;

ProcessRun vdrig(const std::string& args) { return vdrig::test::run_vdrig(args, {60}); }

/// A frame of an EXR written by `vdrig render` as BGR CV_32FC3.
cv::Mat read_frame(const fs::path& path) {
  auto exr = read_exr(path);
  EXPECT_TRUE(exr) << exr.error().describe();
  if (!exr) return {};
  cv::Mat bgr;
  cv::merge(
      std::vector<cv::Mat>{exr->channels[exr->find("B")], exr->channels[exr->find("G")], exr->channels[exr->find("R")]},
      bgr);
  return bgr;
}

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!GlContext::create(8, 8, false)) VDRIG_SKIP_WITHOUT_GL() << "no OpenGL 3.3 context (run under xvfb-run)";
  }
  const vdrig::test::TempDir dir_{"render_cli"};
};

TEST_F(RenderCli, OrbitFrameMatchesTheCpuEvaluationOfTheModel) {
  // Phong-1, a diffuse gradient and a lobe whose highlight falls in view.
  constexpr int kS = 16, kT = 12;
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), kS, kT, 400.0, 300.0);
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      fitting::PhongParams p;
      p.kd = Vec3d(0.15 + 0.4 * s / kS, 0.25, 0.1 + 0.5 * t / kT);
      p.lobes.push_back({Vec3d(1.6, 1.3, 1.0), direction_from_spherical(deg_to_rad(210), deg_to_rad(38)), 12.0});
      fitting::set_phong_texel(map, s, t, p);
    }
  ASSERT_TRUE(map.write(dir_ / "map.exr"));
  const ProcessRun r = vdrig("render '" + (dir_ / "map.exr").string() +
                             "' --azimuth 30 --zenith 40 --distance 1200 --size 96x72 --samples 1 --out '" +
                             (dir_ / "frame.exr").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cv::Mat frame = read_frame(dir_ / "frame.exr");
  ASSERT_EQ(frame.cols, 96);
  ASSERT_EQ(frame.rows, 72);

  // The same camera and pose as the command's (the viewer's free camera), evaluated on the CPU.
  const CameraModel camera = default_pinhole(400.0, 300.0, 96, 72);
  const ViewPose pose = orbit_pose(Vec3d::Zero(), deg_to_rad(30), deg_to_rad(40), 1200.0);
  int compared = 0;
  double worst = 0;
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x) {
      const auto p = test::pixel_surface_point(camera, pose, x, y);
      if (!p || std::abs(p->x()) > 198 || std::abs(p->y()) > 148) continue;  // 2 mm off the edges
      const Vec3d want = test::expected_radiance(map, *p, pose.camera_centre());
      const cv::Vec3f got = frame.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[2 - c] - want[c]) / want[c]);
      ++compared;
    }
  EXPECT_GT(compared, 1000);
  EXPECT_LT(worst, 1e-3) << "worst relative difference over " << compared << " pixels";

  // The PNG is the same frame tone mapped.
  ASSERT_EQ(vdrig("render '" + (dir_ / "map.exr").string() +
                  "' --azimuth 30 --zenith 40 --distance 1200 --size 96x72 --samples 1 --gamma 2 --out '" +
                  (dir_ / "frame.png").string() + "'")
                .exit_code,
            0);
  auto png = read_png(dir_ / "frame.png");
  ASSERT_TRUE(png) << png.error().describe();
  cv::Mat diff;
  cv::absdiff(png.value(), tone_map(frame, 2.0), diff);
  double max_diff = 0;
  cv::minMaxLoc(diff.reshape(1), nullptr, &max_diff);
  EXPECT_LE(max_diff, 1.0);
}

TEST_F(RenderCli, CapturedViewOfGroundTruthMatchesThePhotograph) {
  const fs::path session_dir = dir_ / "session";
  auto session = pipeline::test::small_merged_session(session_dir);
  ASSERT_TRUE(session) << session.error().describe();
  auto geometry = pipeline::session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();

  // The scene's own Phong parameters at every texel centre: the map a perfect fit would give.
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const fitting::ParameterMap map = vdrig::test::phong_truth_map(scene, 100);
  ASSERT_TRUE(map.write(dir_ / "truth.exr"));

  const int view = static_cast<int>(geometry->poses.size()) - 1;  // the most oblique ring
  const ProcessRun r = vdrig("render '" + (dir_ / "truth.exr").string() + "' --session '" + session_dir.string() +
                             "' --view " + std::to_string(view) + " --out '" + (dir_ / "view.exr").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cv::Mat render = read_frame(dir_ / "view.exr");
  auto photo = calib::read_hdr_exr(session->layout().hdr_file(view));
  ASSERT_TRUE(photo) << photo.error().describe();
  ASSERT_EQ(render.size(), photo->radiance.size());

  // Pixels well inside one material (the same 12 mm around), away from the bumped and printed patches whose
  // texture a 10 mm texel cannot hold.
  std::vector<double> rel;
  for (int y = 0; y < render.rows; ++y)
    for (int x = 0; x < render.cols; ++x) {
      const auto p = test::pixel_surface_point(geometry->camera, geometry->poses[view], x, y);
      if (!p) continue;
      const int m = scene.material_at(p->x(), p->y());
      if (m < 0 || scene.materials[m].bump_slope > 0 || scene.materials[m].printed) continue;
      bool uniform = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          uniform = uniform && scene.material_at(p->x() + 12 * dx, p->y() + 12 * dy) == m;
      if (!uniform) continue;
      const cv::Vec3f a = render.at<cv::Vec3f>(y, x), b = photo->radiance.at<cv::Vec3f>(y, x);
      const double sum_b = b[0] + b[1] + b[2];
      if (sum_b <= 0) continue;
      rel.push_back(std::abs((a[0] + a[1] + a[2]) - sum_b) / sum_b);
    }
  ASSERT_GT(rel.size(), 500u) << "surface pixels compared";
  std::sort(rel.begin(), rel.end());
  const double median = rel[rel.size() / 2], p90 = rel[rel.size() * 9 / 10];
  std::printf("view %d: %zu pixels, relative |render - photo|: median %.4f, 90th percentile %.4f\n", view, rel.size(),
              median, p90);
  EXPECT_LT(median, 0.01);  // measured 0.002 (96 x 72 camera, 100 x 100 texels)
  EXPECT_LT(p90, 0.03);     // measured 0.004
}

TEST_F(RenderCli, RefusesBadArguments) {
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), 4, 4, 100.0, 100.0);
  ASSERT_TRUE(map.write(dir_ / "map.exr"));
  const std::string m = "render '" + (dir_ / "map.exr").string() + "' ";
  EXPECT_EQ(vdrig(m + "--out '" + (dir_ / "x.jpg").string() + "'").exit_code, 2);
  EXPECT_EQ(vdrig(m + "--view 0 --out '" + (dir_ / "x.png").string() + "'").exit_code, 2);
  EXPECT_EQ(vdrig(m + "--zenith 95 --out '" + (dir_ / "x.png").string() + "'").exit_code, 2);
  EXPECT_FALSE(fs::exists(dir_ / "x.png"));
}

}  // namespace
}  // namespace vdrig::viewer
