// The fit stage (pipeline/fit_stage.hpp): `vdrig fit`'s options turned into fit options, the checks made before a
// fit and its summary, called as a library.
#include <gtest/gtest.h>

#include <filesystem>

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

}  // namespace
}  // namespace vdrig::pipeline
