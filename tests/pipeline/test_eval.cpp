// vdrig eval's library half (pipeline/eval_stage.hpp): a Phong map made from the scene's own truth scores zero, the
// same map with Kd scaled by 1.1 scores exactly 10 % on the diffuse texels (and a Kd error of 10 %), the error map
// holds the per-texel figures, and the dense directions cover the upper hemisphere uniformly.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "truth_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/scene_file.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig::pipeline {
namespace {

using vdrig::test::phong_truth_map;  // the truth at the texel centres, Kd scaled

const MaterialEval& row(const EvalReport& report, const std::string& name) {
  for (const auto& m : report.materials)
    if (m.name == name) return m;
  ADD_FAILURE() << "no row for " << name;
  return report.materials.front();
}

TEST(Eval, TheTruthItselfScoresZero) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  EvalOptions options;
  options.dense_directions = 300;
  const auto report = evaluate_map(phong_truth_map(scene, 40, 1.0), scene, options);
  ASSERT_TRUE(report.is_ok()) << report.error().message;
  ASSERT_FALSE(report->materials.empty());
  for (const auto& m : report->materials) {
    EXPECT_GT(m.texels, 0) << m.name;
    EXPECT_LT(m.dense.p95, 1e-5) << m.name;  // float storage of the parameters
    ASSERT_TRUE(m.has_phong) << m.name;
    EXPECT_LT(m.phong.kd_rel, 1e-5) << m.name;
  }
}

TEST(Eval, KdScaledByTenPercentGivesTenPercentOnDiffuseTexels) {
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const auto report = evaluate_map(phong_truth_map(scene, 50, 1.1), scene, EvalOptions{});
  ASSERT_TRUE(report.is_ok()) << report.error().message;
  EXPECT_EQ(report->dense_directions, 1000);
  const MaterialEval& cloth = row(*report, "red cloth");  // Lambertian
  EXPECT_GT(cloth.texels, 200);
  EXPECT_NEAR(cloth.dense.mean, 0.1, 1e-5);
  EXPECT_NEAR(cloth.dense.p95, 0.1, 1e-5);
  ASSERT_TRUE(cloth.has_phong);
  EXPECT_NEAR(cloth.phong.kd_rel, 0.1, 1e-5);
  EXPECT_TRUE(std::isnan(cloth.phong.ks_rel));  // no lobe in the truth
  // Kd 1.1x is not a uniform factor of the radiance (Ks is kept): the scale, a median of the materials' votes, is
  // near 1.1, and the red cloth, Lambertian, is nearly right after it (measured 0.28 %).
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(report->scale[c], 1.1, 0.01) << c;
  EXPECT_LT(cloth.dense_scaled.mean, 0.005);
  // Glossy texels: the lobe is exact, so the error is below 10 % but not zero; the lobe's parameters are exact.
  const MaterialEval& glossy = row(*report, "glossy plastic");
  EXPECT_GT(glossy.dense.mean, 0.01);
  EXPECT_LT(glossy.dense.mean, 0.1);
  EXPECT_NEAR(glossy.phong.kd_rel, 0.1, 1e-5);
  EXPECT_LT(glossy.phong.ks_rel, 1e-5);
  EXPECT_LT(glossy.phong.shininess_rel, 1e-5);

  // The error map: one value per texel; the table and the JSON carry the same figures.
  const ExrImage& e = report->error_map;
  ASSERT_EQ(e.width, 50);
  ASSERT_GE(e.find("rel_rms"), 0);
  ASSERT_GE(e.find("material"), 0);
  EXPECT_LT(e.find("rel_rms.session"), 0);  // no session given
  const cv::Mat& rel = e.channels[e.find("rel_rms")];
  const cv::Mat& material = e.channels[e.find("material")];
  int cloth_texels = 0;
  for (int t = 0; t < 50; ++t)
    for (int s = 0; s < 50; ++s)
      if (material.at<float>(t, s) == 1.0f) {  // red cloth is material 1
        ++cloth_texels;
        EXPECT_NEAR(rel.at<float>(t, s), 0.1, 1e-5);
      }
  EXPECT_EQ(cloth_texels, cloth.texels);
  test::TempDir dir("eval_map");
  ASSERT_TRUE(write_exr(dir.path() / "err.exr", e).is_ok());
  const auto back = read_exr(dir.path() / "err.exr");
  ASSERT_TRUE(back.is_ok());
  EXPECT_GE(back->find("rel_rms"), 0);  // OpenEXR stores channels sorted by name
  EXPECT_GE(back->find("material"), 0);
  const auto j = report->to_json();
  EXPECT_EQ(j["model"], "phong:1");
  EXPECT_NE(report->table().find("red cloth"), std::string::npos);
  bool found = false;
  for (const auto& r : j["materials"])
    if (r["material"] == "red cloth") {
      found = true;
      EXPECT_NEAR(r["rel_rms_mean"].get<double>(), 0.1, 1e-5);
      EXPECT_TRUE(r["ks_rel_error"].is_null());
    }
  EXPECT_TRUE(found);
}

TEST(Eval, OverTheDirectionsASessionSampled) {
  // A session captured from a scene file (the sim config's "scene" takes FILE.json like --scene).
  test::TempDir dir("eval_session");
  const sim::Scene scene = sim::make_scene("patchwork").value();
  const std::string scene_file = (dir.path() / "patchwork copy.json").string();
  ASSERT_TRUE(sim::save_scene_file(scene, scene_file).is_ok());
  CaptureRequest req;
  req.out_dir = dir.path() / "session";
  req.rig_config = sim::sim_rig_config(
      {{"scene", scene_file}, {"camera", {{"width", 160}, {"height", 120}, {"fx", 200.0}, {"fy", 200.0}}}});
  req.scheme = "latlong:3";
  req.exposures_s = {0.25};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();

  EvalOptions options;
  options.dense_directions = 200;
  options.session_dir = req.out_dir;
  const auto report = evaluate_map(phong_truth_map(scene, 20, 1.1), scene, options);
  ASSERT_TRUE(report.is_ok()) << report.error().message;
  EXPECT_EQ(report->session_views, session->completed_view_count());
  EXPECT_GE(report->error_map.find("rel_rms.session"), 0);
  const MaterialEval& cloth = row(*report, "red cloth");
  ASSERT_TRUE(cloth.has_session);
  EXPECT_NEAR(cloth.session.mean, 0.1, 1e-5);  // Lambertian: 10 % in every direction
  // Glossy texels: the error depends on the directions (more of them near the highlight in the dense set or not).
  const MaterialEval& glossy = row(*report, "glossy plastic");
  EXPECT_GT(glossy.session.mean, 0.0);
  EXPECT_LT(glossy.session.mean, 0.1);
  EXPECT_NE(glossy.session.mean, glossy.dense.mean);
  EXPECT_NE(report->table().find("sess.mean"), std::string::npos);

  options.session_dir = dir.path() / "no such session";
  EXPECT_FALSE(evaluate_map(phong_truth_map(scene, 4, 1.0), scene, options).is_ok());
}

// `vdrig eval --scene bands` on a map fitted from a patchwork session measures the scenes' difference: the report
// warns, naming both scenes; against its own scene it does not.
TEST(Eval, WarnsWhenTheMapWasFittedFromAnotherScene) {
  test::TempDir dir("eval_mismatch");
  CaptureRequest req;
  req.out_dir = dir.path() / "session";
  req.rig_config = sim::sim_rig_config(
      {{"scene", "patchwork"}, {"camera", {{"width", 80}, {"height", 60}, {"fx", 100.0}, {"fy", 100.0}}}});
  req.scheme = "latlong:2";
  req.exposures_s = {0.25};
  ASSERT_TRUE(capture_session(req));
  const sim::Scene patchwork = sim::make_scene("patchwork").value(), bands = sim::make_scene("bands").value();
  fitting::ParameterMap map = phong_truth_map(patchwork, 8, 1.0);
  map.set_source_session(req.out_dir.string());
  EvalOptions options;
  options.dense_directions = 50;
  long last_done = 0, total = 0;
  options.on_progress = [&](long done, long texels) { last_done = done, total = texels; };

  const auto own = evaluate_map(map, patchwork, options);
  ASSERT_TRUE(own.is_ok()) << own.error().message;
  EXPECT_TRUE(own->warnings.empty()) << own->warnings.front();
  EXPECT_EQ(total, 64);
  EXPECT_EQ(last_done, 64) << "progress reaches every texel";

  const auto other = evaluate_map(map, bands, options);
  ASSERT_TRUE(other.is_ok()) << other.error().message;
  ASSERT_EQ(other->warnings.size(), 1u);
  EXPECT_NE(other->warnings[0].find("\"patchwork\""), std::string::npos) << other->warnings[0];
  EXPECT_NE(other->warnings[0].find("\"bands\""), std::string::npos) << other->warnings[0];
  // --session of the other scene too: one warning per session.
  options.session_dir = req.out_dir;
  const auto both = evaluate_map(map, bands, options);
  ASSERT_TRUE(both.is_ok()) << both.error().message;
  EXPECT_EQ(both->warnings.size(), 2u);
}

// The table's columns are apart whatever the values: a 1100-texel row with a 147113.78 % error once printed as
// "1100147113.78".
TEST(Eval, TableColumnsNeverRunTogether) {
  EvalReport report;
  report.model = "phong:1";
  report.dense_directions = 1000;
  MaterialEval m;
  m.name = "cloth";
  m.texels = 1100;
  m.dense = {1471.1378, 2000.0, 99999.0, 123456.789};
  m.has_phong = true;
  m.phong = {12345.6, 0.5, 0.25};
  m.dense_scaled = {2000.0, 99999.0, 0, 0};
  m.phong_scaled = {12345.6, 0.5, 0.25};
  report.materials = {m};
  const std::string table = report.table();
  const size_t row_start = table.find("\ncloth");
  ASSERT_NE(row_start, std::string::npos) << table;
  std::istringstream row(table.substr(row_start + 1, table.find('\n', row_start + 1) - row_start - 1));
  std::vector<std::string> cells;
  for (std::string cell; row >> cell;) cells.push_back(cell);
  EXPECT_EQ(cells, (std::vector<std::string>{"cloth", "1100", "147113.78", "200000.00", "9999900.00", "12345678.90",
                                             "1234560.00", "50.00", "25.00", "200000.00", "9999900.00", "1234560.00",
                                             "50.00"}))
      << table;
}

TEST(Eval, GgxTruthIsModelMismatchForAPhongMap) {
  // The same map against a scene whose glossy patch became GGX: the Phong truth map no longer matches there.
  sim::Scene scene = sim::make_scene("patchwork").value();
  const fitting::ParameterMap map = phong_truth_map(scene, 40, 1.0);
  scene.materials[2].kind = sim::MaterialKind::kGgx;
  scene.materials[2].roughness = 0.2;
  scene.materials[2].f0 = Vec3d::Constant(0.5);
  const auto report = evaluate_map(map, scene, EvalOptions{});
  ASSERT_TRUE(report.is_ok());
  EXPECT_GT(row(*report, "glossy plastic").dense.mean, 0.05);
  EXPECT_FALSE(row(*report, "glossy plastic").has_phong);  // the truth is not of Phong form
  EXPECT_LT(row(*report, "red cloth").dense.mean, 1e-5);
}

TEST(Eval, RejectsAMapOfAnotherSurfaceSize) {
  const sim::Scene scene = sim::make_scene("bands").value();
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), 8, 8, 500.0, 500.0);
  const auto report = evaluate_map(map, scene, EvalOptions{});
  ASSERT_FALSE(report.is_ok());
  EXPECT_EQ(report.error().code, ErrorCode::kInvalidArgument);
}

TEST(Eval, DenseDirectionsCoverTheUpperHemisphereUniformly) {
  const auto dirs = hemisphere_directions(1000);
  ASSERT_EQ(dirs.size(), 1000u);
  Vec3d mean = Vec3d::Zero();
  for (const Vec3d& d : dirs) {
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    EXPECT_GT(d.z(), 0.0);
    mean += d / 1000.0;
  }
  // Uniform in solid angle: E[z] = 1/2, E[x] = E[y] = 0.
  EXPECT_NEAR(mean.z(), 0.5, 1e-3);
  EXPECT_NEAR(mean.x(), 0.0, 5e-3);
  EXPECT_NEAR(mean.y(), 0.0, 5e-3);
}

// Issue #26: a session calibrated from its own images (response by Debevec-Malik, `vdrig calib response`) gives maps
// in other units than the simulator's truth (a recovered curve is free up to a factor per channel). eval reports
// that factor and the errors after it, which must be close to those of the same session with the true response;
// the absolute figures still carry the factor, and a map of the wrong shape still fails after it.
TEST(Eval, ScaleOfAResponseRecoveredFromTheImages) {
  const vdrig::test::TempDir dir("eval_scale");
  CaptureRequest req;
  req.out_dir = dir.path() / "session";
  req.rig_config = sim::sim_rig_config(
      {{"scene", "patchwork"}, {"camera", {{"width", 160}, {"height", 120}, {"fx", 200.0}, {"fy", 200.0}}}});
  req.scheme = "latlong:4";
  req.exposures_s = {1.0, 0.25, 0.0625};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const sim::Scene scene = sim::make_scene("patchwork").value();
  constexpr int kTexels = 16;
  // Fits phong:1 from the session's current calib/ and evaluates it.
  const auto fit_and_eval = [&](std::optional<fitting::ParameterMap>* fitted) -> Result<EvalReport> {
    HdrMergeOptions force;
    force.force = true;
    auto merged = merge_session_hdr(session.value(), force);
    if (!merged) return merged.error();
    auto obs = build_session_obsmap(session.value(), kTexels, kTexels);
    if (!obs) return obs.error();
    auto map = fitting::fit_parameter_map(obs.value(), {});
    if (!map) return map.error();
    auto report = evaluate_map(map.value(), scene, EvalOptions{});
    *fitted = std::move(map.value());
    return report;
  };
  // The simulator's truth as calib/ (poses and camera stay true below: the response is what changes).
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));
  std::optional<fitting::ParameterMap> true_map, recovered_map;
  auto with_truth = fit_and_eval(&true_map);
  ASSERT_TRUE(with_truth) << with_truth.error().describe();
  ASSERT_TRUE(calibrate_session_response(session.value()));
  auto recovered = fit_and_eval(&recovered_map);
  ASSERT_TRUE(recovered) << recovered.error().describe();
  // Measured (160 x 120, latlong:4 = 53 views, 16 x 16 texels): scale 1.004 1.009 1.006 with the true response,
  // 1.106 1.104 1.151 recovered. Kd relative error with the true response / recovered after the scale: paper 1.25 /
  // 1.98 %, red cloth (Lambertian) 0.16 / 0.40 %, glossy plastic 0.25 / 1.31 %: the recovered curve's shape (not a
  // scale) adds 0.73 / 0.24 / 1.06 % of Kd, bounded at 1.5 x the largest. (Before the observation map dropped the
  // 80 deg ring's blends of neighbouring patches, kObsCoarse, the true response's own errors were 3.78 / 1.51 / 6.64 %
  // and hid that addition: the bound was 1.5 x the true response's figure.)
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(with_truth->scale[c], 1.0, 0.015) << c;
    EXPECT_GT(recovered->scale[c], 1.05) << c;  // the units of the recovered curve are not the truth's
    EXPECT_LT(recovered->scale[c], 1.25) << c;
  }
  for (const char* name : {"paper", "red cloth", "glossy plastic"}) {
    const MaterialEval& truth_row = row(with_truth.value(), name);
    const MaterialEval& rec = row(recovered.value(), name);
    EXPECT_LT(rec.dense_scaled.mean, 1.5 * truth_row.dense.mean) << name;
    EXPECT_LT(rec.phong_scaled.kd_rel, truth_row.phong.kd_rel + 0.016) << name;
    EXPECT_NEAR(truth_row.dense_scaled.mean, truth_row.dense.mean, 0.01) << name;  // scale ~1: hardly a change
  }
  EXPECT_GT(row(recovered.value(), "red cloth").dense.mean, 0.07) << "the absolute figure keeps the factor";
  const std::string table = recovered->table();
  EXPECT_NE(table.find("scale map/truth (R G B) 1.1"), std::string::npos) << table;
  const nlohmann::json j = recovered->to_json();
  ASSERT_EQ(j["scale"].size(), 3u);
  EXPECT_NEAR(j["scale"][0].get<double>(), recovered->scale[0], 1e-12);

  // Wrong maps still fail after the scale: the red cloth's colour off by 40 % (one material: the scale, a median
  // over the materials, stays), and the glossy plastic without its lobe (a wrong shape).
  fitting::ParameterMap wrong = recovered_map.value();
  for (int t = 0; t < kTexels; ++t)
    for (int s = 0; s < kTexels; ++s) {
      const Vec3d p = texel_centre_mm(s, t, kTexels, kTexels, scene.width_mm, scene.height_mm);
      const int m = scene.material_at(p.x(), p.y());
      if (m < 0 || scene.materials[static_cast<size_t>(m)].name != "glossy plastic") {
        if (m >= 0 && scene.materials[static_cast<size_t>(m)].name == "red cloth")
          for (const char* c : {"kd.R", "kd.G", "kd.B"}) wrong.at(c, s, t) *= 0.6f;
        continue;
      }
      fitting::PhongParams diffuse_only;
      diffuse_only.kd = Vec3d(wrong.at("kd.R", s, t), wrong.at("kd.G", s, t), wrong.at("kd.B", s, t));
      fitting::set_phong_texel(wrong, s, t, diffuse_only);
    }
  auto wrong_report = evaluate_map(wrong, scene, EvalOptions{});
  ASSERT_TRUE(wrong_report) << wrong_report.error().describe();
  EXPECT_NEAR(wrong_report->scale[0], recovered->scale[0], 0.03);
  EXPECT_GT(row(wrong_report.value(), "red cloth").dense_scaled.mean, 0.3);
  // Measured 15.0 % without the lobe (a narrow one, m = 60, over the whole hemisphere) against 6.8 % with it.
  EXPECT_GT(row(wrong_report.value(), "glossy plastic").dense_scaled.mean, 0.1);
}

}  // namespace
}  // namespace vdrig::pipeline
