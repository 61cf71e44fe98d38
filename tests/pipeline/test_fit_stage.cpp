// The fit stage (pipeline/fit_stage.hpp): `vdrig fit`'s options turned into fit options, the checks made before a
// fit and its summary, called as a library.
#include <gtest/gtest.h>

#include <filesystem>

#include "small_session.hpp"
#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/fitting/hsh.hpp"
#include "vdrig/fitting/phong.hpp"
#include "vdrig/pipeline/compare_stage.hpp"
#include "vdrig/pipeline/fit_stage.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

TEST(FitStage, OptionsFromARequest) {
  FitRequest r;
  r.model = "phong:2";
  r.holdout = 3;
  r.residual = "relative";
  r.threads = 2;
  r.shared_lights = true;
  auto o = fit_options_for(r, 40);
  ASSERT_TRUE(o.is_ok()) << o.error().describe();
  EXPECT_EQ(o->model->name(), "phong:2");
  EXPECT_EQ(o->held_out, spread_holdout_views(40, 3));
  EXPECT_EQ(o->model_options.get<fitting::PhongFitOptions>().residual, fitting::ResidualMode::kRelative);
  EXPECT_EQ(o->threads, 2);
  EXPECT_TRUE(o->shared_lights);
  EXPECT_TRUE(o->model_options.get<fitting::PhongFitOptions>().significant_lobes_only);
}

TEST(FitStage, HeldOutViewsAreOnlyViewsTheFitGets) {
  FitRequest r;
  r.holdout = 3;
  std::vector<bool> unusable(40, false);
  for (int v : spread_holdout_views(40, 3)) unusable[v] = true;  // the calibration excluded every usual pick
  auto o = fit_options_for(r, 40, unusable);
  ASSERT_TRUE(o.is_ok()) << o.error().describe();
  ASSERT_EQ(o->held_out.size(), 3u);
  for (int v : o->held_out) EXPECT_FALSE(unusable[v]) << "view " << v << " is not in the fit";
  // Too few usable views for --holdout: an error that says so, not fewer held out.
  std::vector<bool> most(10, true);
  most[0] = most[4] = false;
  r.holdout = 2;
  auto refused = fit_options_for(r, 10, most);
  ASSERT_FALSE(refused.is_ok());
  EXPECT_NE(refused.error().message.find("--holdout 2: only 1 usable"), std::string::npos) << refused.error().message;
}

TEST(FitStage, SmoothingDefaultsToTheBasisFitsThatRing) {
  FitRequest r;
  r.model = "hsh:3";
  auto o = fit_options_for(r, 10);
  ASSERT_TRUE(o.is_ok()) << o.error().describe();
  EXPECT_EQ(o->model_options.get<fitting::HshFitOptions>().smoothing, 1e-4);
  EXPECT_EQ(default_smoothing(*fitting::parse_model("phong:1").value()), 0.0);
}

TEST(FitStage, SolidAngleWeightsForAdaptiveSessions) {
  auto weighted = [](const std::string& weights, const std::string& scheme) {
    FitRequest r;
    r.weights = weights;
    auto o = fit_options_for(r, 40, {}, scheme);
    EXPECT_TRUE(o.is_ok()) << o.error().describe();
    return o.is_ok() && o->model_options.get<fitting::PhongFitOptions>().solid_angle_weights;
  };
  EXPECT_TRUE(weighted("auto", "adaptive:60,batch=8"));
  EXPECT_FALSE(weighted("auto", "spiral:60:5@85"));
  EXPECT_FALSE(weighted("none", "adaptive:60"));
  EXPECT_TRUE(weighted("solid-angle", "icosahedron:2@85"));
  FitRequest r;
  r.weights = "voronoi";
  EXPECT_NE(fit_options_for(r, 10).error().message.find("--weights"), std::string::npos);
  r.weights = "solid-angle";
  r.model = "hsh:3";
  EXPECT_NE(fit_options_for(r, 10).error().message.find("--weights solid-angle does not apply"), std::string::npos);
}

TEST(FitStage, BadRequestsNameTheOption) {
  auto error_of = [](FitRequest r, int views = 10) {
    auto o = fit_options_for(r, views);
    EXPECT_FALSE(o.is_ok());
    return o.is_ok() ? std::string() : o.error().message;
  };
  FitRequest r;
  r.residual = "squared";
  EXPECT_NE(error_of(r).find("--residual"), std::string::npos);
  r = {};
  r.holdout = 10;
  EXPECT_NE(error_of(r).find("--holdout"), std::string::npos);
  r = {};
  r.threads = -1;
  EXPECT_NE(error_of(r).find("--threads"), std::string::npos);
  r = {};
  r.smoothing = 1e-3;  // Phong is not a basis expansion
  EXPECT_NE(error_of(r).find("--smoothing does not apply to phong models"), std::string::npos);
  r = {};
  r.model = "sh-ls:4";
  r.residual = "relative";  // the basis fits share one unweighted operator
  EXPECT_NE(error_of(r).find("--residual does not apply to sh-ls models"), std::string::npos);
  r = {};
  r.model = "no-such-model:1";
  error_of(r);
}

TEST(FitStage, OutputChecks) {
  vdrig::test::TempDir dir{"fit_stage"};
  EXPECT_TRUE(check_fit_output_writable(dir.path() / "maps" / "m.exr").is_ok());
  EXPECT_TRUE(fs::is_directory(dir.path() / "maps")) << "the folder is made when missing";
  EXPECT_FALSE(check_fit_output_writable(dir.path() / "maps").is_ok()) << "a folder is not an output file";
  const auto phong = fitting::parse_model("phong:1").value();
  EXPECT_EQ(map_bytes_at_most(*phong, 4, 2), (phong->channels().size() + 12) * 8 * sizeof(float));
  EXPECT_TRUE(check_map_fits(*phong, 8, 8, dir.path() / "m.exr").is_ok());
  EXPECT_EQ(check_map_fits(*phong, 8192, 8192, dir.path() / "m.exr").error().code, ErrorCode::kInvalidArgument);
}

// The whole stage called as a library, as `vdrig fit`, `vdrig demo` and the daemon share it: the held-out views skip
// the one the calibration excluded, the map is written where `vdrig fit` writes it, and a second fit reuses the
// observation map while it is current.
TEST(FitStage, RunsTheFitOfASession) {
  vdrig::test::TempDir tmp("fit_stage_run");
  auto session = test::small_merged_session(tmp.path() / "s");
  ASSERT_TRUE(session.is_ok()) << session.error().describe();
  const int n_views = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n_views, 6);
  // The calibration excludes the view spread_holdout_views would hold out first.
  const int excluded = spread_holdout_views(n_views, 2).front();
  const fs::path views_file = session->layout().views_file();
  auto views = calib::read_views_json(views_file);
  ASSERT_TRUE(views.is_ok()) << views.error().describe();
  views->exclude_unposed = true;
  for (auto& record : views->views)
    if (record.index == excluded && record.extrinsics) record.extrinsics->excluded = true;
  ASSERT_TRUE(calib::write_views_json(views_file, views.value()).is_ok());

  FitStageOptions o;
  o.session = session->dir();
  o.request.holdout = 2;
  o.texels_s = o.texels_t = 16;
  o.command = "test";
  std::vector<FitStep> steps;
  o.on_step = [&steps](FitStep step, const std::string&) { steps.push_back(step); };
  EXPECT_EQ(o.validate(), "");
  auto fitted = run_fit_stage(o);
  ASSERT_TRUE(fitted.is_ok()) << fitted.error().describe();
  EXPECT_EQ(steps, (std::vector<FitStep>{FitStep::kObsMap, FitStep::kObservations, FitStep::kFit}));
  ASSERT_EQ(fitted->held_out.size(), 2u);
  for (int v : fitted->held_out) {
    EXPECT_NE(v, excluded) << "an excluded view tests nothing";
    EXPECT_NE(v, 0) << "the normal view is never held out";
  }
  EXPECT_EQ(fitted->map_file, session->layout().parameter_map_file("phong:1"));
  EXPECT_EQ(fitted->obsmap_file, session->layout().obsmap_file(16, 16));
  auto map = fitting::ParameterMap::read(fitted->map_file);
  ASSERT_TRUE(map.is_ok()) << map.error().describe();
  EXPECT_EQ(map->texels_s(), 16);
  EXPECT_EQ(map->image().string_attributes["vdrig.command"], "test");
  EXPECT_TRUE(map->has("holdout.R"));
  int texels_fitted = 0;  // 243 of 256 on this session: the surface covers most of the map
  for (int t = 0; t < 16; ++t)
    for (int s = 0; s < 16; ++s) texels_fitted += map->at("n", s, t) > 0 ? 1 : 0;
  EXPECT_GE(texels_fitted, 160);
  // The summary is that of the map written (mostly exact fits here: diffuse patches, noise-free renders).
  EXPECT_EQ(fitted->summary.median_rms, summarize_fit(map.value()).median_rms);
  ASSERT_TRUE(fitted->summary.median_holdout_rms.has_value());

  // A second fit (another model) reuses the current observation map instead of building it again.
  const auto built_at = fs::last_write_time(fitted->obsmap_file);
  o.request.model = "phong:2";
  o.request.holdout = 0;
  auto again = run_fit_stage(o);
  ASSERT_TRUE(again.is_ok()) << again.error().describe();
  EXPECT_EQ(fs::last_write_time(again->obsmap_file), built_at);
  EXPECT_TRUE(fs::exists(session->layout().parameter_map_file("phong:2")));

  // Refused after the output's folder was made (a map vdrig could not read back): the folder is removed again.
  o.out = tmp.path() / "nowhere" / "map.exr";
  o.texels_s = o.texels_t = 60000;
  auto refused = run_fit_stage(o);
  ASSERT_FALSE(refused.is_ok());
  EXPECT_NE(refused.error().message.find("--res 60000x60000"), std::string::npos) << refused.error().message;
  EXPECT_FALSE(fs::exists(tmp.path() / "nowhere"));
  o.texels_s = 0;
  EXPECT_NE(o.validate().find("--res"), std::string::npos);
}

}  // namespace
}  // namespace vdrig::pipeline
