// A fitted map judged where the viewer looks, on the whole chain a rig runs: a sparse session of the simulated rig
// with sensor noise (shot and read noise, 8-bit codes, an HDR merge of three exposures), the geometry calibrated from
// the images' corner markers, its observation map, the Phong fits as `vdrig fit` makes them, evaluated toward 600
// directions spread over the hemisphere (between the views and beyond the last ring) against the scene's true
// radiance (docs/models.md, "Between the samples").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig::pipeline {
namespace {

/// The most a map is brighter than the truth over the texels of a material and the directions, relative to the
/// material's largest true radiance there (so 0.01 is one code of an exposure that puts it at 100 codes).
double worst_excess(const fitting::ParameterMap& map, const sim::Scene& scene, const std::string& material,
                    const std::vector<Vec3d>& directions) {
  double worst = 0.0;
  for (int t = 0; t < map.texels_t(); ++t)
    for (int s = 0; s < map.texels_s(); ++s) {
      const Vec3d p = texel_centre_mm(s, t, map.texels_s(), map.texels_t(), map.width_mm(), map.height_mm());
      // The texel and a margin all of that material: a view at 75 deg zenith sees a footprint of ~25 mm per pixel
      // here, and texels nearer a patch edge see the neighbour at grazing views (that is resolution, not the fit).
      const double half = 0.5 * map.width_mm() / map.texels_s() + 60.0;
      bool pure = true;
      for (double dx : {-half, half})
        for (double dy : {-half, half}) {
          const int m = scene.material_at(p.x() + dx, p.y() + dy);
          pure = pure && m >= 0 && scene.materials[static_cast<size_t>(m)].name == material;
        }
      if (!pure) continue;
      for (const Vec3d& v : directions) {
        const Vec3d truth = scene.radiance(p, v);
        const double e = (map.evaluate(s, t, v) - truth).maxCoeff() / truth.maxCoeff();
        worst = std::max(worst, e);
      }
    }
  return worst;
}

TEST(BetweenTheViews, ANoisySparseSessionOfADiffusePatchInventsNoHighlight) {
  const test::TempDir dir("between");
  CaptureRequest req;
  req.out_dir = dir / "session";
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"},
                                        {"seed", 3},
                                        {"camera",
                                         {{"width", 320},
                                          {"height", 240},
                                          {"fx", 400.0},
                                          {"fy", 400.0},
                                          {"full_well_e", 20000.0},
                                          {"read_noise_e", 8.0}}}});
  req.scheme = "latlong:3";
  req.exposures_s = {1.0, 0.25, 0.0625};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  // The response and the intrinsics are the simulator's (write_true_calibration); the poses are calibrated below.
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));
  ASSERT_TRUE(merge_session_hdr(session.value()));
  // The geometry as a user gets it: each view's pose from the corner markers in its HDR image and the rig kinematics
  // fitted to them (the intrinsics are the simulator's: a simulated session has no chessboard views of its own).
  GeometryCalibrationOptions calibration;
  calibration.camera = sim::SimConfig::from_json(req.rig_config["sim"]).value().camera;
  auto calibrated = calibrate_session_geometry(session.value(), calibration);
  ASSERT_TRUE(calibrated) << calibrated.error().describe();
  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  ASSERT_EQ(geometry->source, "calibrated");
  auto obs = build_session_obsmap(session.value(), 20, 20);
  ASSERT_TRUE(obs) << obs.error().describe();
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::vector<Vec3d> directions = hemisphere_directions(600);

  for (const char* model : {"phong:1", "phong:auto"}) {
    fitting::MapFitOptions guarded;
    guarded.model = fitting::parse_model(model).value();
    fitting::MapFitOptions unguarded = guarded;
    unguarded.model_options.edit<fitting::PhongFitOptions>().lobe_support = 0;
    unguarded.model_options.edit<fitting::PhongFitOptions>().significant_lobes_only = false;
    auto map = fitting::fit_parameter_map(obs.value(), guarded);
    ASSERT_TRUE(map) << map.error().describe();
    auto before = fitting::fit_parameter_map(obs.value(), unguarded);
    ASSERT_TRUE(before) << before.error().describe();
    const double excess = worst_excess(map.value(), scene, "red cloth", directions);
    const double excess_before = worst_excess(before.value(), scene, "red cloth", directions);
    std::printf(
        "%s, red cloth, latlong:3 with sensor noise: at most %.2f %% brighter than the truth over 600 "
        "directions (%.1f %% without the support cap and the lobe-count choice)\n",
        model, 100 * excess, 100 * excess_before);
    // Measured 0.44 % on the calibrated geometry (half a code where the cloth is exposed at 100 codes; 0.30 % on the
    // simulator's true geometry); 93.7 % without the rules.
    EXPECT_LT(excess, 0.006) << model;
    EXPECT_GT(excess_before, 0.05) << model;
  }
}

}  // namespace
}  // namespace vdrig::pipeline
