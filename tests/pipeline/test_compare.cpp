// vdrig compare (pipeline/compare_stage.hpp): the statistics against hand-computed differences, the region split, and
// the accuracy of a Phong-1 fit at views it never saw.
#include <gtest/gtest.h>

#include <filesystem>

#include "small_session.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

TEST(DifferenceStats, MatchesHandComputedValues) {
  cv::Mat a(1, 3, CV_8UC3), b(1, 3, CV_8UC3), mask(1, 3, CV_8UC1);
  a.at<cv::Vec3b>(0, 0) = {10, 20, 30}, b.at<cv::Vec3b>(0, 0) = {12, 20, 26};  // |d| = 2, 0, 4
  a.at<cv::Vec3b>(0, 1) = {0, 0, 0}, b.at<cv::Vec3b>(0, 1) = {6, 6, 6};        // 6, 6, 6
  a.at<cv::Vec3b>(0, 2) = {0, 0, 0}, b.at<cv::Vec3b>(0, 2) = {255, 255, 255};  // masked out
  mask.at<uint8_t>(0, 0) = 255, mask.at<uint8_t>(0, 1) = 128, mask.at<uint8_t>(0, 2) = 0;
  const DifferenceStats d = difference_stats(a, b, mask);
  EXPECT_EQ(d.samples, 6);
  EXPECT_DOUBLE_EQ(d.mean, 4.0);                      // (2 + 0 + 4 + 6 + 6 + 6) / 6
  EXPECT_NEAR(d.stddev, std::sqrt(32.0 / 6), 1e-12);  // squares of deviations: 4 16 0 4 4 4
  EXPECT_EQ(difference_stats(a, b, cv::Mat(1, 3, CV_8UC1, cv::Scalar(0))).samples, 0);
}

TEST(SpreadHoldoutViews, AsFitAndDemoPickThem) {
  EXPECT_EQ(spread_holdout_views(188, 3), (std::vector<int>{47, 94, 141}));
  EXPECT_TRUE(spread_holdout_views(10, 0).empty());
}

// Held-out views are picked among the views the fit gets: one the calibration excluded gives way to its nearest
// usable neighbour (`vdrig inspect` then reports every held-out view asked for).
TEST(SpreadHoldoutViews, NeverPicksAViewTheFitDoesNotGet) {
  std::vector<bool> unusable(188, false);
  EXPECT_EQ(spread_holdout_views(188, 3, unusable), spread_holdout_views(188, 3));
  unusable[47] = unusable[48] = unusable[141] = true;
  EXPECT_EQ(spread_holdout_views(188, 3, unusable), (std::vector<int>{46, 94, 142}));
  // Too few usable views: fewer picks, never view 0, never an unusable one, never one twice.
  EXPECT_EQ(spread_holdout_views(4, 3, {false, true, false, true}), (std::vector<int>{2}));
  EXPECT_TRUE(spread_holdout_views(2, 1, {false, true}).empty());
}

// `vdrig compare --holdout` compares only where every map's fit held the views out: a map fitted without --holdout
// (or with other held-out views) is an error naming it, never a comparison at views it was fitted on.
TEST(CommonHeldOutViews, EveryMapMustHaveHeldOutTheSameViews) {
  const ::vdrig::test::TempDir dir("held_out");
  auto write_map = [&](const std::string& name, const std::string& held_out) {
    fitting::ParameterMap map(fitting::parse_model("phong:1").value(), 4, 4, 1000.0, 1000.0);
    if (!held_out.empty()) map.image().string_attributes["vdrig.held_out_views"] = held_out;
    const fs::path file = dir.path() / (name + ".exr");
    EXPECT_TRUE(map.write(file));
    return file;
  };
  const fs::path a = write_map("a", "12,40"), b = write_map("b", "12,40"), none = write_map("none", ""),
                 other = write_map("other", "13,40");
  auto both = common_held_out_views({a, b});
  ASSERT_TRUE(both) << both.error().describe();
  EXPECT_EQ(both.value(), (std::vector<int>{12, 40}));
  for (const fs::path& bad : {none, other}) {
    auto refused = common_held_out_views({a, bad});
    ASSERT_FALSE(refused) << bad;
    EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.error().message.find(bad.string()), std::string::npos) << refused.error().message;
  }
  auto alone = common_held_out_views({none});
  ASSERT_FALSE(alone);
  EXPECT_NE(alone.error().message.find("without --holdout"), std::string::npos) << alone.error().message;
}

class Compare : public ::testing::Test {
 protected:
  const ::vdrig::test::TempDir dir_{"compare"};
};

// A map of one Phong texel value everywhere (Kd, one lobe Ks along the normal, m).
fitting::ParameterMap uniform_phong_map(const capture::Session& session, const Vec3d& kd, const Vec3d& ks) {
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), 8, 8, session.manifest().surface_width_mm,
                            session.manifest().surface_height_mm);
  fitting::PhongParams p;
  p.kd = kd;
  p.lobes.push_back({ks, Vec3d::UnitZ(), 20.0});
  for (int t = 0; t < 8; ++t)
    for (int s = 0; s < 8; ++s) fitting::set_phong_texel(map, s, t, p);
  return map;
}

TEST_F(Compare, StatisticsAndImagesMatchAHandComputation) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const fs::path lambert = dir_ / "lambert.exr", shiny = dir_ / "shiny.exr";
  ASSERT_TRUE(uniform_phong_map(session.value(), Vec3d(0.3, 0.2, 0.1), Vec3d::Zero()).write(lambert));
  ASSERT_TRUE(uniform_phong_map(session.value(), Vec3d::Zero(), Vec3d(1.0, 1.0, 1.0)).write(shiny));
  CompareOptions options;
  options.out_dir = dir_ / "out";
  auto report = compare_maps(session.value(), {lambert, shiny}, {0}, options);
  if (!report && report.error().code == ErrorCode::kUnsupported)
    VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << report.error().message;
  ASSERT_TRUE(report) << report.error().describe();
  ASSERT_EQ(report->rows.size(), 2u);
  EXPECT_EQ(report->region_map, "lambert") << "the first Phong map defines the regions";

  // The Lambertian map has no specular term: every counted pixel is diffuse.
  const ViewComparison& row = report->rows[0];
  EXPECT_EQ(row.highlight.samples, 0);
  EXPECT_GT(row.diffuse.samples, 3 * 1000);
  EXPECT_EQ(row.all.samples, row.diffuse.samples);

  // By hand: the photo is the HDR view tone mapped; the render of a uniform map is Kd tone mapped; the statistics
  // are those of |render - photo| over the counted pixels.
  auto hdr = calib::read_hdr_exr(session->layout().hdr_file(0));
  ASSERT_TRUE(hdr);
  const cv::Mat photo = viewer::tone_map(hdr->radiance, 1.0);
  auto photo_png = read_png(row.photo_png);
  ASSERT_TRUE(photo_png);
  EXPECT_EQ(cv::norm(photo_png.value(), photo, cv::NORM_INF), 0.0);
  const cv::Mat kd_pixel(1, 1, CV_32FC3, cv::Scalar(0.1, 0.2, 0.3));  // BGR
  const cv::Vec3b kd_code = viewer::tone_map(kd_pixel, 1.0).at<cv::Vec3b>(0, 0);
  auto render = read_png(row.render_png);
  auto regions = read_png(row.regions_png);
  auto diff = read_png(row.diff_png);
  ASSERT_TRUE(render && regions && diff);
  double sum = 0, sum2 = 0;
  long long n = 0, at_kd = 0;
  for (int y = 0; y < photo.rows; ++y)
    for (int x = 0; x < photo.cols; ++x) {
      if (regions->at<uint8_t>(y, x) == 0) continue;
      const cv::Vec3b r = render->at<cv::Vec3b>(y, x), p = photo.at<cv::Vec3b>(y, x);
      at_kd += r == kd_code;
      for (int c = 0; c < 3; ++c) {
        const int d = std::abs(int(r[c]) - int(p[c]));
        sum += d, sum2 += double(d) * d, ++n;
        EXPECT_EQ(diff->at<cv::Vec3b>(y, x)[c], std::min(255, 8 * d));
      }
    }
  ASSERT_EQ(n, row.diffuse.samples);
  EXPECT_GT(at_kd, n / 3 * 9 / 10) << "the render of a uniform map is Kd on the surface (edges anti-aliased)";
  EXPECT_NEAR(row.diffuse.mean, sum / n, 1e-9);
  EXPECT_NEAR(row.diffuse.stddev, std::sqrt(sum2 / n - (sum / n) * (sum / n)), 1e-9);

  // compare.json reads back as written.
  auto json = read_json_file(report->json_file);
  ASSERT_TRUE(json);
  auto reread = CompareReport::from_json(json.value());
  ASSERT_TRUE(reread) << reread.error().describe();
  EXPECT_EQ(reread->rows.size(), 2u);
  EXPECT_DOUBLE_EQ(reread->rows[1].all.mean, report->rows[1].all.mean);

  // With the pure-lobe map defining the regions, the pixels near the normal view's mirror direction are highlight.
  auto shiny_first = compare_maps(session.value(), {shiny}, {0}, options);
  ASSERT_TRUE(shiny_first);
  EXPECT_GT(shiny_first->rows[0].highlight.samples, 0);
}

TEST_F(Compare, RejectsViewsOutsideTheSessionAndMapsWithoutHoldout) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session);
  const fs::path lambert = dir_ / "lambert.exr";
  const auto map = uniform_phong_map(session.value(), Vec3d(0.3, 0.2, 0.1), Vec3d::Zero());
  ASSERT_TRUE(map.write(lambert));
  auto bad = compare_maps(session.value(), {lambert}, {999});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(held_out_views(map).error().code, ErrorCode::kNotFound);
}

// The Done-when figure of issue 13: a Phong-1 fit, measured at the views it never saw, differs from the
// photographs by less than 2 codes on average on the diffuse region and less than 6 on the highlight region. The
// scene is one glossy material over the whole surface: a map cannot resolve detail finer than its texels (on the
// patchwork scene the patch edges and the printed texture dominate the difference; docs/viewer.md has those figures),
// and this test measures the model, not the map's resolution.
TEST_F(Compare, PhongOneFromHeldOutViewsIsCloseToThePhotographs) {
  const fs::path scene = dir_ / "glossy.json";
  ASSERT_TRUE(write_file_atomic(scene, R"({"format": "vdrig-scene", "version": 1, "name": "glossy",
    "width_mm": 1000.0, "height_mm": 1000.0,
    "materials": [{"name": "glossy paint", "kd": [0.35, 0.25, 0.15], "ks": [0.4, 0.4, 0.4], "shininess": 12.0}],
    "patches": [{"x0_mm": -500.0, "y0_mm": -500.0, "x1_mm": 500.0, "y1_mm": 500.0, "material": 0}],
    "markers": [],
    "lights": [{"position_mm": [1500.0, 1500.0, 2000.0], "intensity": [12390772.8, 12390772.8, 12390772.8]}]})"));
  CaptureRequest req;
  req.out_dir = dir_ / "session";
  req.rig_config = sim::sim_rig_config(
      {{"scene", scene.string()}, {"camera", {{"width", 320}, {"height", 240}, {"fx", 400.0}, {"fy", 400.0}}}});
  req.scheme = "latlong:4";
  req.exposures_s = {1.0, 0.25, 0.0625};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));
  ASSERT_TRUE(merge_session_hdr(session.value()));
  const int n = static_cast<int>(session->manifest().views.size());
  auto obs = build_session_obsmap(session.value(), 32, 32);
  ASSERT_TRUE(obs) << obs.error().describe();
  fitting::MapFitOptions fit;
  // Two views spread over the session and the one nearest the mirror direction of the light at the centre, so that
  // the held-out views see the highlight.
  fit.held_out = spread_holdout_views(n, 2);
  const Vec3d light = Vec3d(1500, 1500, 2000).normalized(), mirror(-light.x(), -light.y(), light.z());
  int nearest = 0;
  for (const auto& v : session->manifest().views)
    if (v.direction.dot(mirror) > session->manifest().views[nearest].direction.dot(mirror)) nearest = v.index;
  if (std::find(fit.held_out.begin(), fit.held_out.end(), nearest) == fit.held_out.end())
    fit.held_out.push_back(nearest);
  std::sort(fit.held_out.begin(), fit.held_out.end());
  auto map = fitting::fit_parameter_map(obs.value(), fit);
  ASSERT_TRUE(map) << map.error().describe();
  const fs::path map_path = session->layout().parameter_map_file("phong:1");
  fs::create_directories(map_path.parent_path());
  ASSERT_TRUE(map->write(map_path));
  auto reread = fitting::ParameterMap::read(map_path);
  ASSERT_TRUE(reread);
  auto held = held_out_views(reread.value());
  ASSERT_TRUE(held) << held.error().describe();
  EXPECT_EQ(held.value(), fit.held_out);

  auto report = compare_maps(session.value(), {map_path}, held.value());
  if (!report && report.error().code == ErrorCode::kUnsupported)
    VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << report.error().message;
  ASSERT_TRUE(report) << report.error().describe();
  std::printf("%s", report->table().c_str());
  long long highlight_samples = 0;
  for (const ViewComparison& row : report->rows) {
    EXPECT_LT(row.diffuse.mean, 2.0) << "view " << row.view;
    if (row.highlight.samples > 0) {
      EXPECT_LT(row.highlight.mean, 6.0) << "view " << row.view;
    }
    highlight_samples += row.highlight.samples;
  }
  EXPECT_GT(highlight_samples, 300) << "the held-out views must see some highlight";
}

}  // namespace
}  // namespace vdrig::pipeline
