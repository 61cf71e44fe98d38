// The session's light on images vdrig did not render (docs/models.md, "The light"; docs/results.md, section 10): a
// short Blender session of the textured, clearcoated plastic (as fidelity_test_blender_session makes it), whose rig
// config records the lamp the .blend was built with, fitted with ggx:iso by the fit stage under that recorded light
// (no --light) and under the light estimated from the images (--light estimate); the estimate against the .blend's
// light, and both maps' held-out views against the photographs. Skipped when Blender is not installed or without
// an OpenGL display.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "blender_session.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/pipeline/session_light.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

using test_blender::since_s;

TEST(BlenderLight, EstimatedLightPredictsHeldOutViewsAsTheRecordedOne) {
  if (std::system("command -v blender >/dev/null 2>&1") != 0) GTEST_SKIP() << "blender is not installed";
  const test::TempDir dir("blender_light");
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path blend = test_blender::make_sample_blend(dir.path(), "textured_clearcoat_plastic");
  ASSERT_TRUE(fs::exists(blend));
  // The .blend's light (scripts/blender_scenes.py: the built-in scenes' point light), stated as a rig's measured lamp.
  const Vec3d lamp_mm(1500, 1500, 2000);
  CaptureRequest req = test_blender::blender_capture_request(dir.path() / "session", blend, "latlong:3");
  req.rig_config["light"] = {{"backend", "sim"},
                             {"position_mm", {lamp_mm.x(), lamp_mm.y(), lamp_mm.z()}},
                             {"position_source", "scripts/blender_scenes.py"}};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const double capture_s = since_s(t0);
  ASSERT_TRUE(calibrate_session_response(session.value()));
  ASSERT_TRUE(merge_session_hdr(session.value()));
  GeometryCalibrationOptions options;
  options.camera = sim::SimConfig::from_json(req.rig_config["sim"])->camera;  // as a real camera's calibration file
  ASSERT_TRUE(calibrate_session_geometry(session.value(), options));

  const auto fit = [&](const std::string& light, const std::string& name) -> Result<FitStageResult> {
    FitStageOptions stage;
    stage.session = req.out_dir;
    stage.request.model = "ggx:iso";
    stage.request.holdout = 3;
    stage.request.threads = 2;
    stage.request.light = light;
    stage.texels_s = stage.texels_t = 64;
    stage.out = dir.path() / "maps" / (name + ".exr");
    return run_fit_stage(stage);
  };
  const auto fit_start = std::chrono::steady_clock::now();
  auto estimated = fit("estimate", "estimated");
  ASSERT_TRUE(estimated) << estimated.error().describe();
  const double estimate_s = since_s(fit_start);
  auto recorded = fit("", "recorded");
  ASSERT_TRUE(recorded) << recorded.error().describe();
  auto estimated_map = fitting::ParameterMap::read(estimated->map_file);
  ASSERT_TRUE(estimated_map) << estimated_map.error().describe();
  const auto& attributes = estimated_map->image().string_attributes;
  ASSERT_TRUE(attributes.contains("vdrig.session_light_source"));
  EXPECT_NE(attributes.at("vdrig.session_light_source").find("estimated from the images"), std::string::npos);
  auto recorded_map = fitting::ParameterMap::read(recorded->map_file);
  ASSERT_TRUE(recorded_map) << recorded_map.error().describe();
  EXPECT_NE(recorded_map->image().string_attributes.at("vdrig.session_light_source").find("rig config"),
            std::string::npos);
  // The estimate, as the fit stage made it (the same function on the same observations).
  auto obs = fitting::ObsMapReader::open(estimated->obsmap_file);
  ASSERT_TRUE(obs) << obs.error().describe();
  auto estimate = estimate_session_light(obs.value(), estimated->held_out, 2);
  ASSERT_TRUE(estimate) << estimate.error().describe();
  const Vec3d error_mm = estimate->light.position_mm - lamp_mm;
  const double direction_deg =
      rad_to_deg(angle_between(estimate->light.position_mm.normalized(), lamp_mm.normalized()));

  // Both maps in one comparison, so both are scored on the same pixels (the recorded light's map, the first, defines
  // the diffuse and highlight regions; compare_stage.hpp): compared apart, each map's own texels picked its highlight
  // pixels, and the two figures measured different regions.
  CompareOptions compare_options;
  compare_options.out_dir = dir.path() / "compare";
  auto compared =
      compare_maps(session.value(), {recorded->map_file, estimated->map_file}, estimated->held_out, compare_options);
  if (!compared && compared.error().code == ErrorCode::kUnsupported)
    VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << compared.error().message;
  ASSERT_TRUE(compared) << compared.error().describe();
  struct Figures {
    double all = 0, diffuse = 0, highlight = 0;
  };
  const auto figures = [&](const std::string& map_name) {
    Figures f;
    long long an = 0, dn = 0, hn = 0;
    for (const ViewComparison& row : compared->rows) {
      if (row.map_name != map_name) continue;
      f.all += row.all.mean * row.all.samples;
      an += row.all.samples;
      f.diffuse += row.diffuse.mean * row.diffuse.samples;
      dn += row.diffuse.samples;
      f.highlight += row.highlight.mean * row.highlight.samples;
      hn += row.highlight.samples;
    }
    f.all /= std::max(1LL, an);
    f.diffuse /= std::max(1LL, dn);
    f.highlight /= std::max(1LL, hn);
    return f;
  };
  const Figures with_recorded = figures("recorded"), with_estimate = figures("estimated");
  std::printf(
      "capture %.1f s, all %.1f s; %s (fit with the estimate %.1f s)\n  error %.1f mm, direction %.3f deg, "
      "distance %.1f mm; held out, recorded / estimated light: %.2f / %.2f all, %.2f / %.2f diffuse, %.2f / %.2f "
      "highlight\n",
      capture_s, since_s(t0), estimate->describe().c_str(), estimate_s, error_mm.norm(), direction_deg,
      estimate->light.position_mm.norm() - lamp_mm.norm(), with_recorded.all, with_estimate.all, with_recorded.diffuse,
      with_estimate.diffuse, with_recorded.highlight, with_estimate.highlight);
  // Bounds: 1.5x the figures measured (docs/blender.md): the light 1.25 deg off in direction, 228 mm (8 %) near (the
  // clearcoat's second lobe is outside ggx:iso; the Phong lobes alone put it 350 mm off); held out 2.91 / 2.19 / 5.58
  // codes (all / diffuse / highlight) with the recorded lamp, 2.96 / 2.17 / 5.86 with the estimate. Before the
  // observation map dropped grazing samples (kObsCoarse, 2026-12-05): 0.47 deg and 586 mm, held out 3.43 codes in all
  // with the recorded lamp (the 80 deg ring's blends of neighbouring patches fitted as the texels' own).
  EXPECT_LT(direction_deg, 1.9);
  EXPECT_LT(error_mm.norm(), 340.0);
  EXPECT_LT(with_recorded.all, 4.4);
  EXPECT_LT(with_recorded.diffuse, 3.3);
  EXPECT_LT(with_recorded.highlight, 8.4);
  EXPECT_LT(with_estimate.all, 1.1 * with_recorded.all);
  EXPECT_LT(with_estimate.highlight, 1.1 * with_recorded.highlight);
}

}  // namespace
}  // namespace vdrig::pipeline
