// The real calibration chain on images vdrig did not render: a short session of the "blender" camera (Cycles, the
// simulator's sensor model on its linear render) on the simulated stage, then response recovery from the brackets,
// HDR merge, extrinsics from the corner markers and the kinematic fit (intrinsics given, as a real camera's come from
// its calibration file), observation map, Phong fit with held-out views, and `vdrig compare` on those views. No
// simulator truth reaches the pipeline; the test reads the truth only to measure the extrinsics. Figures and bounds:
// docs/blender.md. Skipped when Blender is not installed or without an OpenGL display.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "blender_session.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

using test_blender::since_s;

TEST(BlenderSession, CalibratedChainPredictsHeldOutViews) {
  if (std::system("command -v blender >/dev/null 2>&1") != 0) GTEST_SKIP() << "blender is not installed";
  const test::TempDir dir("blender_session");
  const auto t0 = std::chrono::steady_clock::now();
  // The issue's target sample: a textured, clearcoated plastic, a .blend of Principled BSDF (scripts/blender_scenes.py)
  // whose clearcoat lobe and Fresnel no vdrig model has.
  const fs::path blend = test_blender::make_sample_blend(dir.path(), "textured_clearcoat_plastic");
  ASSERT_TRUE(fs::exists(blend));
  CaptureRequest req = test_blender::blender_capture_request(dir.path() / "session", blend, "latlong:3");
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 20);
  ASSERT_EQ(session->completed_view_count(), n);
  const double capture_s = since_s(t0);

  auto response = calibrate_session_response(session.value());
  ASSERT_TRUE(response) << response.error().describe();
  ASSERT_TRUE(merge_session_hdr(session.value()));
  const auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
  ASSERT_TRUE(sc);
  GeometryCalibrationOptions options;
  options.camera = sc->camera;  // the rig config's intrinsics, as a real camera's calibration file
  auto cal = calibrate_session_geometry(session.value(), options);
  ASSERT_TRUE(cal) << cal.error().describe();
  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  // Extrinsics against the truth the Blender scene was rendered with (read here only, to measure them).
  double worst_rot_deg = 0, worst_t_mm = 0;
  for (const auto& rec : cal->views.views) {
    if (!rec.usable()) continue;
    const ViewPose truth = rig::surface_pose(sc->geometry, rec.measured);
    const ViewPose& got = geometry->poses[rec.index];
    worst_rot_deg = std::max(worst_rot_deg, rad_to_deg(Eigen::AngleAxisd(got.R * truth.R.transpose()).angle()));
    worst_t_mm = std::max(worst_t_mm, (got.t - truth.t).norm());
  }

  const std::vector<int> held_out = spread_holdout_views(n, 3);
  auto obs_path = session_obsmap_file(session.value(), 64, 64);
  ASSERT_TRUE(obs_path) << obs_path.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_path.value());
  ASSERT_TRUE(obs) << obs.error().describe();
  fitting::MapFitOptions fit_options;
  fit_options.held_out = held_out;
  auto map = fitting::fit_parameter_map(obs.value(), fit_options);
  ASSERT_TRUE(map) << map.error().describe();
  const fs::path map_path = session->layout().parameter_map_file("phong:1");
  fs::create_directories(map_path.parent_path());
  ASSERT_TRUE(map->write(map_path));
  // Mean |render - photo| over the held-out views' diffuse and highlight pixels, as `vdrig compare` counts them.
  struct Figures {
    double diffuse = 0, highlight = 0;
    long long diffuse_n = 0, highlight_n = 0;
  };
  const auto compare = [&](const fs::path& map_file, const fs::path& out) -> Result<Figures> {
    CompareOptions options;
    options.out_dir = out;
    auto compared = compare_maps(session.value(), {map_file}, held_out, options);
    if (!compared) return compared.error();
    Figures f;
    for (const ViewComparison& row : compared->rows) {
      f.diffuse += row.diffuse.mean * row.diffuse.samples;
      f.diffuse_n += row.diffuse.samples;
      f.highlight += row.highlight.mean * row.highlight.samples;
      f.highlight_n += row.highlight.samples;
    }
    if (f.diffuse_n > 0) f.diffuse /= f.diffuse_n;
    if (f.highlight_n > 0) f.highlight /= f.highlight_n;
    return f;
  };
  auto figures = compare(map_path, dir.path() / "compare");
  if (!figures && figures.error().code == ErrorCode::kUnsupported)
    VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << figures.error().message;
  ASSERT_TRUE(figures) << figures.error().describe();
  ASSERT_GT(figures->diffuse_n, 10000);
  ASSERT_GT(figures->highlight_n, 100);
  std::printf(
      "%d views (capture %.1f s, all %.1f s); response from view %d; %d views posed by markers, worst %.3f "
      "deg %.2f mm; held out %zu views: mean |render - photo| %.2f diffuse, %.2f highlight (8-bit codes)\n",
      n, capture_s, since_s(t0), response->view, cal->usable_views, worst_rot_deg, worst_t_mm, held_out.size(),
      figures->diffuse, figures->highlight);
  // Bounds: 1.5x the figures measured (docs/blender.md): 18 of 31 views posed by their markers (3.8 px discs at this
  // size), worst 0.095 deg and 3.0 mm; 4.40 codes diffuse, 20.3 highlight (phong:1 has no clearcoat lobe).
  EXPECT_GE(cal->usable_views, 12);
  EXPECT_LT(worst_rot_deg, 0.15);
  EXPECT_LT(worst_t_mm, 4.6);
  EXPECT_LT(figures->diffuse, 6.6);
  EXPECT_LT(figures->highlight, 30.5);

  // Sensitive: the same map with Kd 20 % too dark fails the diffuse bound.
  fitting::ParameterMap darker = map.value();
  for (const char* c : {"kd.R", "kd.G", "kd.B"})
    for (int t = 0; t < darker.texels_t(); ++t)
      for (int s = 0; s < darker.texels_s(); ++s) darker.at(c, s, t) *= 0.8f;
  const fs::path darker_path = dir.path() / "darker" / "phong:1.exr";
  fs::create_directories(darker_path.parent_path());
  ASSERT_TRUE(darker.write(darker_path));
  auto worse = compare(darker_path, dir.path() / "compare_darker");
  ASSERT_TRUE(worse) << worse.error().describe();
  std::printf("Kd x0.8: %.2f diffuse\n", worse->diffuse);
  EXPECT_GT(worse->diffuse, 6.6);
}

}  // namespace
}  // namespace vdrig::pipeline
