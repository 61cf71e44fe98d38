// The session's light for a BRDF fit (pipeline/session_light.hpp): recorded by the session (the rig config's lamp,
// rig/lamp.hpp; a simulated rig records its scene's point light), or estimated from the images by the Phong fit's
// shared-lights pass, and what the estimate costs a ggx:iso fit against the true light (docs/models.md, "The light").
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "../fitting/ggx_scene.hpp"
#include "../fitting/rig_observations.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/ggx_model.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/pipeline/session_light.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/lamp.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/sim/texel_recording.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {

using fitting::test_support::ggx_scene;

/// An S x S map from icosahedron:3@85 (camera at 2500 mm), each texel recorded by the 8-bit camera (shot and read
/// noise, rounding; sim::TexelRecording's defaults), as tests/fitting/test_ggx.cpp records it.
fitting::ObservationMap recorded_map(const sim::Scene& scene, int S) {
  static const std::vector<Vec3d> views = fitting::test_support::scheme_directions("icosahedron:3@85");
  fitting::ObservationMap map({S, S, scene.width_mm, scene.height_mm}, static_cast<int>(views.size()));
  for (int t = 0; t < S; ++t)
    for (int s = 0; s < S; ++s) {
      fitting::TexelObservations obs = fitting::test_support::observe_texel(
          scene, texel_centre_mm(s, t, S, S, scene.width_mm, scene.height_mm), views);
      sim::record_texel(obs.radiance, {}, 1000u + static_cast<unsigned>(t * S + s));
      for (size_t v = 0; v < obs.size(); ++v)
        map.set(s, t, static_cast<int>(v), obs.radiance[v], obs.direction[v], fitting::kObsValid);
    }
  return map;
}

struct Fitted {
  double albedo = 0, f0 = 0, alpha = 0;  // mean relative errors over the texels (albedo against max(kd, 0.05))
  double dense = 0;                      // vdrig eval's dense mean relative RMS
};

Fitted fit_under(const fitting::ObservationMap& obs, const sim::Scene& scene, const fitting::SessionLight& light) {
  fitting::MapFitOptions options;
  options.model = fitting::parse_model("ggx:iso").value();
  options.threads = 2;
  options.model_options.edit<fitting::GgxFitOptions>().light = light;
  auto map = fitting::fit_parameter_map(obs, options);
  EXPECT_TRUE(map) << map.error().describe();
  Fitted out;
  if (!map) return out;
  const sim::Material& truth = scene.materials.front();
  const int n = map->texels_s() * map->texels_t();
  for (int t = 0; t < map->texels_t(); ++t)
    for (int s = 0; s < map->texels_s(); ++s) {
      const fitting::GgxMaterial m = fitting::GgxModel::material(map->parameters(s, t));
      for (int c = 0; c < 3; ++c) {
        out.albedo += std::abs(m.albedo[c] - truth.kd[c]) / std::max(truth.kd[c], 0.05) / (3 * n);
        out.f0 += std::abs(m.f0[c] - truth.f0[c]) / truth.f0[c] / (3 * n);
      }
      out.alpha += std::abs(m.roughness * m.roughness - truth.roughness) / truth.roughness / n;
    }
  auto report = evaluate_map(*map, scene, {});
  EXPECT_TRUE(report) << report.error().describe();
  if (report) out.dense = report->materials.front().dense.mean;
  return out;
}

TEST(SessionLight, EstimatedFromTheImagesAndFittedUnder) {
  // One GGX material over the whole of `bands` (a 12 x 12 map, 83 mm texels) from icosahedron:3@85 under 8-bit
  // sensor noise: the light estimated from the images against the scene's (1500, 1500, 2000) mm, and ggx:iso under
  // the estimate against ggx:iso under the true light. Measured: metal: the lobes' light 481 mm off (z 480 mm low),
  // refined to 0.3 mm (1-sigma 0.5 mm); albedo / f0 / alpha / dense 2.96 / 0.27 / 0.16 / 0.267 % (true light: 2.96 /
  // 0.27 / 0.16 / 0.266 %); plastic: 249 mm, refined to 0.9 mm (0.8 mm); 0.16 / 0.53 / 0.25 / 0.179 % (0.16 / 0.53 /
  // 0.26 / 0.178 %).
  struct Case {
    const char* name;
    Vec3d kd, f0;
    double alpha;
    double position_tol_mm, dense_tol;
  };
  const Case cases[] = {
      {"metal alpha 0.25", Vec3d::Constant(0.05), Vec3d(0.9, 0.7, 0.4), 0.25, 1.5, 0.004},
      {"plastic alpha 0.15", Vec3d(0.6, 0.25, 0.1), Vec3d::Constant(0.04), 0.15, 1.5, 0.0027},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const sim::Scene scene = ggx_scene(c.kd, c.f0, c.alpha);
    const fitting::ObservationMap obs = recorded_map(scene, 12);
    const auto start = std::chrono::steady_clock::now();
    auto estimate = estimate_session_light(obs, {}, 2);
    const double estimate_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(estimate) << estimate.error().describe();
    const Vec3d truth_mm = scene.lights.front().position_mm;
    const Vec3d error_mm = estimate->light.position_mm - truth_mm;
    const double sigma_mm = std::sqrt(estimate->covariance_mm2.trace());
    const double direction_deg =
        rad_to_deg(angle_between(estimate->light.position_mm.normalized(), truth_mm.normalized()));
    const Fitted given = fit_under(obs, scene, session_light_of(scene).value());
    const Fitted estimated = fit_under(obs, scene, estimate->session_light);
    std::printf(
        "%s: %s (%.2f s)\n  error (%.1f, %.1f, %.1f) mm = %.1f mm (%.2f %% of the distance, direction %.3f "
        "deg, distance %.1f mm), 1-sigma %.1f mm\n",
        c.name, estimate->describe().c_str(), estimate_s, error_mm.x(), error_mm.y(), error_mm.z(), error_mm.norm(),
        100 * error_mm.norm() / truth_mm.norm(), direction_deg, estimate->light.position_mm.norm() - truth_mm.norm(),
        sigma_mm);
    std::printf(
        "  ggx:iso mean relative error, true light / estimated: albedo %.2f / %.2f %%, f0 %.2f / %.2f %%, alpha "
        "%.2f / %.2f %%; vdrig eval dense mean %.3f / %.3f %%\n",
        100 * given.albedo, 100 * estimated.albedo, 100 * given.f0, 100 * estimated.f0, 100 * given.alpha,
        100 * estimated.alpha, 100 * given.dense, 100 * estimated.dense);
    EXPECT_LT(error_mm.norm(), c.position_tol_mm);
    EXPECT_LT(error_mm.norm(), 4 * sigma_mm + 0.5);  // the stated uncertainty covers the error (noise only here)
    EXPECT_GT((estimate->phong_position_mm - truth_mm).norm(), 150.0);  // what the refinement corrects
    EXPECT_LT(estimated.dense, c.dense_tol);
    EXPECT_LT(estimated.dense, 1.05 * given.dense);
    EXPECT_LT(std::abs(estimated.albedo - given.albedo), 0.005);
    EXPECT_LT(std::abs(estimated.f0 - given.f0), 0.005);
    EXPECT_LT(std::abs(estimated.alpha - given.alpha), 0.005);
  }
}

TEST(SessionLight, ASimulatedRigRecordsItsScenesLamp) {
  const nlohmann::json rc = sim::sim_rig_config({{"scene", "bands"}});
  const sim::Scene scene = sim::make_scene("bands").value();
  auto lamp = rig::lamp_from_light_section(rc["light"]);
  ASSERT_TRUE(lamp) << lamp.error().describe();
  ASSERT_TRUE(lamp.value());
  EXPECT_EQ(lamp.value()->position_mm, scene.lights.front().position_mm);
  EXPECT_LT((*lamp.value()->intensity - scene.lights.front().intensity).norm(), 1e-3);  // recorded to 1e-3
  // The registry takes the lamp's keys beside the backend's own (which would refuse them) and shows them back.
  const rig::ConfigCheck check = rig::check_rig_config(rc, sim::simulator_and_hardware_backends());
  EXPECT_TRUE(check.problems.empty()) << check.problems.front();
  EXPECT_TRUE(check.effective["light"].contains("position_mm")) << check.effective.dump();
  EXPECT_TRUE(sim::simulator_and_hardware_backends().make_rig(rc));
  // No single point light (two lights, an area light): nothing recorded.
  EXPECT_FALSE(sim::sim_rig_config({{"scene", "lights2"}})["light"].contains("position_mm"));
  EXPECT_FALSE(sim::sim_rig_config({{"scene", "softbox"}})["light"].contains("position_mm"));
  // A malformed lamp is refused naming the key.
  nlohmann::json bad = rc;
  bad["light"]["position_mm"] = {1, 2};
  bad["light"]["position_frame"] = "world";
  const rig::ConfigCheck refused = rig::check_rig_config(bad, sim::simulator_and_hardware_backends());
  ASSERT_EQ(refused.problems.size(), 1u);
  EXPECT_NE(refused.problems.front().find("position_mm"), std::string::npos) << refused.problems.front();
  EXPECT_NE(refused.problems.front().find("position_frame"), std::string::npos) << refused.problems.front();

  // The session's recorded light is the scene's, as --light-scene gives it.
  test::TempDir dir("session_light");
  capture::Manifest manifest;
  manifest.rig_config = rc;
  manifest.views.push_back({});
  auto session = capture::Session::create(dir / "s", manifest);
  ASSERT_TRUE(session) << session.error().describe();
  auto recorded = recorded_session_light(session.value());
  ASSERT_TRUE(recorded) << recorded.error().describe();
  ASSERT_TRUE(recorded.value());
  const fitting::SessionLight expected = session_light_of(scene).value();
  EXPECT_LT((recorded.value()->light.position_m - expected.position_m).norm(), 1e-12);
  EXPECT_LT((recorded.value()->light.intensity - expected.intensity).norm(), 1e-9 * expected.intensity.norm());
  // `bands` lights its centre to irradiance 1: the gauge used without a stated intensity gives the same light.
  EXPECT_LT((unit_centre_irradiance_light(expected.position_m).intensity - expected.intensity).norm(), 1e-6);

  // A lamp measured on the platter: the surface's offset on it taken off (the stated geometry, no calibration yet).
  manifest.rig_config["light"] = {{"backend", "sim"}, {"position_mm", {100, 200, 1500}}, {"position_frame", "platter"}};
  manifest.rig_config["geometry"] = {{"distance_mm", 2500}, {"surface_offset_mm", {0, 0, 20}}};
  auto platter = capture::Session::create(dir / "p", manifest);
  ASSERT_TRUE(platter) << platter.error().describe();
  auto from_platter = recorded_session_light(platter.value());
  ASSERT_TRUE(from_platter && from_platter.value()) << from_platter.error().describe();
  EXPECT_LT((from_platter.value()->light.position_m - Vec3d(0.1, 0.2, 1.48)).norm(), 1e-12);

  // No lamp: nothing recorded (the fit stage then refuses, naming --light, --light estimate and --light-scene).
  manifest.rig_config["light"] = {{"backend", "sim"}};
  auto none = capture::Session::create(dir / "n", manifest);
  ASSERT_TRUE(none) << none.error().describe();
  auto nothing = recorded_session_light(none.value());
  ASSERT_TRUE(nothing) << nothing.error().describe();
  EXPECT_FALSE(nothing.value());
  // ... before it builds the observation map (this session has no images to build it from).
  FitStageOptions stage;
  stage.session = dir / "n";
  stage.request.model = "ggx:iso";
  stage.texels_s = stage.texels_t = 4;
  auto refused_fit = run_fit_stage(stage);
  ASSERT_FALSE(refused_fit);
  EXPECT_EQ(refused_fit.error().code, ErrorCode::kInvalidArgument);
  for (const char* named : {"recorded none", "--light X,Y,Z", "--light estimate", "--light-scene"})
    EXPECT_NE(refused_fit.error().message.find(named), std::string::npos) << refused_fit.error().message;
  // --light estimate on a view-only model is refused like any option the model does not read.
  stage.request.model = "phong:1";
  stage.request.light = "estimate";
  auto view_only = run_fit_stage(stage);
  ASSERT_FALSE(view_only);
  EXPECT_NE(view_only.error().message.find("--light does not apply"), std::string::npos) << view_only.error().message;
}

}  // namespace
}  // namespace vdrig::pipeline
