// vdrig report (pipeline/report.hpp): a session with missing parts, a damaged session, and the page loaded in a real
// browser (Debian's chromium, headless), which must show every section, decode every image, log nothing to its
// console and fetch nothing.
#include <gtest/gtest.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "small_session.hpp"
#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/pipeline/report.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

const char* const kSections[] = {"coverage", "views", "calibration", "maps", "eval", "compare", "texels", "provenance"};

/// The text of <section id="id"> ... </section>.
std::string section_of(const std::string& html, const std::string& id) {
  const auto start = html.find("<section id=\"" + id + "\">");
  if (start == std::string::npos) return "";
  return html.substr(start, html.find("</section>", start) - start);
}

class Report : public ::testing::Test {
 protected:
  const ::vdrig::test::TempDir dir_{"report"};
};

TEST_F(Report, SessionWithMissingPartsShowsWhatIsThereAndNamesWhatIsMissing) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  fs::remove(session->layout().camera_file());  // the geometric calibration is one of the missing parts
  fs::remove(session->layout().views_file());
  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  for (const char* id : kSections) EXPECT_NE(section_of(*html, id), "") << id;
  EXPECT_NE(section_of(*html, "coverage").find("<circle"), std::string::npos) << "the directions are plotted";
  EXPECT_EQ(section_of(*html, "coverage").find("Missing"), std::string::npos) << "every view was captured";
  for (const char* id : {"calibration", "maps", "compare", "texels"})
    EXPECT_NE(section_of(*html, id).find("Missing:"), std::string::npos) << id;
  EXPECT_NE(section_of(*html, "maps").find("vdrig fit"), std::string::npos) << "names the command that makes it";
  EXPECT_EQ(html->find("http://"), std::string::npos);
  EXPECT_EQ(html->find("https://"), std::string::npos);

  // A damaged map is reported in its section; the rest of the page is still there.
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(write_file_atomic(session->layout().parameter_map_file("phong:1"), "not an EXR"));
  auto damaged = build_report_html(dir_ / "session");
  ASSERT_TRUE(damaged) << damaged.error().describe();
  EXPECT_NE(section_of(*damaged, "maps").find("Missing: a readable map"), std::string::npos);
  EXPECT_NE(section_of(*damaged, "texels").find("Missing: a readable fitted map"), std::string::npos);
  EXPECT_NE(section_of(*damaged, "coverage").find("<circle"), std::string::npos);
}

// What a reader sees: dashes written once (a literal "&#8211;" showed where &#8211; was escaped twice), numbers to a
// few significant digits (no "2.2193484540451628e-05"), a colour bar from 0 where its minimum is 0 at the scale shown
// (not "2.201e-17"), and fit timings the fit recorded rather than the span of the maps' write times.
TEST_F(Report, DashesOnceNumbersReadableTimingsRecorded) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const double w = session->manifest().surface_width_mm, h = session->manifest().surface_height_mm;
  fitting::ParameterMap old_map(fitting::parse_model("phong:1").value(), 8, 8, w, h);  // no held-out views
  fitting::ParameterMap timed(fitting::parse_model("phong:1").value(), 8, 8, w, h);
  for (int t = 0; t < 8; ++t)
    for (int s = 0; s < 8; ++s)
      for (const char* c : {"rms.R", "rms.G", "rms.B"})
        timed.at(c, s, t) = s + t == 0 ? 2.201e-17f : 0.04f * (s + 1) / 8;
  timed.image().number_attributes[fitting::kFitSecondsAttribute] = 51.0437;
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(old_map.write(session->layout().parameter_map_file("old")));
  ASSERT_TRUE(timed.write(session->layout().parameter_map_file("timed")));

  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  EXPECT_EQ(html->find("&amp;#"), std::string::npos) << "an entity escaped twice";
  EXPECT_NE(section_of(*html, "maps").find("held-out views: &#8211;"), std::string::npos) << section_of(*html, "maps");
  EXPECT_EQ(html->find("e-17"), std::string::npos) << "the colour bar's minimum is 0 at its scale";
  const std::string provenance = section_of(*html, "provenance");
  EXPECT_NE(provenance.find("<td>51</td>"), std::string::npos) << provenance;
  EXPECT_NE(provenance.find("not recorded (an older map)"), std::string::npos) << provenance;
  // No number printed with more digits than anyone reads (a raw double has 15 to 17); inline images left out.
  std::string text = *html;
  for (size_t at = text.find("base64,"); at != std::string::npos; at = text.find("base64,", at))
    text.erase(at, text.find('"', at) - at);
  // A digit, a point and nine or more digits (no std::regex: GCC 12's fails the ASan build, -Wmaybe-uninitialized).
  std::string raw;
  for (size_t at = text.find('.'); at != std::string::npos && raw.empty(); at = text.find('.', at + 1)) {
    size_t digits = 0;
    while (at + 1 + digits < text.size() && std::isdigit(static_cast<unsigned char>(text[at + 1 + digits]))) ++digits;
    if (at > 0 && std::isdigit(static_cast<unsigned char>(text[at - 1])) && digits >= 9)
      raw = text.substr(at - 1, digits + 2);
  }
  EXPECT_TRUE(raw.empty()) << "a raw number: " << raw;
}

/// The inline images of `html` (data: URIs) with their alt texts, decoded (empty Mat: not decodable).
std::vector<std::pair<std::string, cv::Mat>> images_of(const std::string& html) {
  std::vector<std::pair<std::string, cv::Mat>> images;
  for (size_t at = html.find("<img"); at != std::string::npos; at = html.find("<img", at + 1)) {
    const std::string tag = html.substr(at, html.find('>', at) - at);
    const auto alt = tag.find("alt=\""), data = tag.find(";base64,");
    std::string name = alt == std::string::npos ? "" : tag.substr(alt + 5, tag.find('"', alt + 5) - alt - 5);
    std::vector<uchar> bytes;
    if (data != std::string::npos) {
      // RFC 4648 base64 decoding, '=' padding ends it.
      uint32_t bits = 0;
      int count = 0;
      for (size_t i = data + 8; i < tag.size() && tag[i] != '"' && tag[i] != '='; ++i) {
        const char c = tag[i];
        const int v = c >= 'A' && c <= 'Z'   ? c - 'A'
                      : c >= 'a' && c <= 'z' ? c - 'a' + 26
                      : c >= '0' && c <= '9' ? c - '0' + 52
                      : c == '+'             ? 62
                                             : 63;
        bits = (bits << 6) | uint32_t(v);
        if ((count += 6) >= 8) bytes.push_back(uchar((bits >> (count -= 8)) & 0xff));
      }
    }
    images.emplace_back(name, bytes.empty() ? cv::Mat() : cv::imdecode(bytes, cv::IMREAD_UNCHANGED));
  }
  return images;
}

/// The texts of the colour bars' and axes' tick labels (<text class="tick ...">) in `html`; `kind` "x" or "y" keeps
/// only an axis' own.
std::vector<std::string> tick_labels(const std::string& html, const std::string& kind = "") {
  std::vector<std::string> labels;
  const std::string open = "<text class=\"tick" + (kind.empty() ? "" : " " + kind + "\"");
  for (size_t at = html.find(open); at != std::string::npos; at = html.find(open, at + 1)) {
    const auto start = html.find('>', at) + 1;
    labels.push_back(html.substr(start, html.find("</text>", start) - start));
  }
  return labels;
}

/// A tick label a reader reads at a glance: a plain number of at most 6 characters ("0.005", "12", "-0.4").
bool readable_tick(const std::string& label) {
  if (label.empty() || label.size() > 6) return false;
  size_t used = 0;
  try {
    (void)std::stod(label, &used);
  } catch (const std::exception&) {
    return false;
  }
  return used == label.size() && label.find('e') == std::string::npos;
}

// Each fitted map shows its parameters as images (Phong: kd, ks and m per lobe; HSH: its first coefficients) beside
// the fit's quality, at the map's own resolution, each with a caption saying what it is and its range, and colour
// bars with round tick values.
TEST_F(Report, MapsShowTheirParametersAsImages) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const double w = session->manifest().surface_width_mm, h = session->manifest().surface_height_mm;
  fitting::ParameterMap phong(fitting::parse_model("phong:1").value(), 8, 8, w, h);
  fitting::ParameterMap hsh(fitting::parse_model("hsh:2").value(), 8, 8, w, h);
  fitting::ParameterMap ptm(fitting::parse_model("ptm:rgb").value(), 8, 8, w, h);
  for (int t = 0; t < 8; ++t)
    for (int s = 0; s < 8; ++s) {
      phong.at("kd.R", s, t) = 0.05f * float(s);  // red grows to the right
      phong.at("kd.G", s, t) = 0.2f;
      phong.at("kd.B", s, t) = 0.1f;
      for (const char* c : {"ks0.R", "ks0.G", "ks0.B"}) phong.at(c, s, t) = 0.4f;
      phong.at("m", s, t) = 5.0f + float(t);  // shininess grows downwards
      for (const char* c : {"rms.R", "rms.G", "rms.B"}) phong.at(c, s, t) = 0.0023f * float(s + t);
      phong.set_holdout_rms(s, t, Vec3d(0.01, 0.012, 0.011) * (1 + s));
      for (const char* c : {"hsh.R.00", "hsh.G.00", "hsh.B.00"}) hsh.at(c, s, t) = 0.3f;
      for (const char* c : {"hsh.R.01", "hsh.G.01", "hsh.B.01"}) hsh.at(c, s, t) = -0.02f * float(s);
      for (const char* c : {"ptm.R.5", "ptm.G.5", "ptm.B.5"}) ptm.at(c, s, t) = 0.5f;
    }
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(phong.write(session->layout().parameter_map_file("phong:1")));
  ASSERT_TRUE(hsh.write(session->layout().parameter_map_file("hsh:2")));
  ASSERT_TRUE(ptm.write(session->layout().parameter_map_file("ptm:rgb")));

  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  const std::string maps = section_of(*html, "maps");
  std::map<std::string, cv::Mat> by_alt;  // the two maps' "fit residual RMS" share a key
  const auto images = images_of(maps);
  EXPECT_EQ(images.size(), 5u + 5u + 4u)
      << "phong: kd, ks0, m, rms, held-out rms; hsh: coefficients 0 to 3, rms; ptm: terms 5, 3, 4, rms";
  for (const auto& [alt, image] : images) {
    EXPECT_FALSE(image.empty()) << alt << " does not decode";
    if (image.empty()) continue;
    EXPECT_EQ(image.cols, 8) << alt << ": at the map's own resolution (the page scales it)";
    by_alt[alt] = image;
  }
  for (const char* alt :
       {"kd", "ks0", "m", "fit residual RMS", "held-out RMS", "HSH coefficient 0", "HSH coefficient 1",
        "HSH coefficient 2", "HSH coefficient 3", "PTM term 5", "PTM term 3", "PTM term 4"})
    EXPECT_EQ(by_alt.count(alt), 1u) << alt << " in " << maps.substr(0, 3000);
  if (by_alt.count("kd") && by_alt["kd"].type() == CV_8UC3) {
    const cv::Mat& kd = by_alt["kd"];
    EXPECT_LT(kd.at<cv::Vec3b>(0, 1)[2] + 40, kd.at<cv::Vec3b>(0, 7)[2]) << "kd.R grows to the right";
    EXPECT_EQ(kd.at<cv::Vec3b>(0, 1)[1], kd.at<cv::Vec3b>(7, 1)[1]) << "kd.G is uniform";
  }
  if (by_alt.count("m")) {  // viridis: dark blue at the low end, yellow at the top
    const cv::Mat& m = by_alt["m"];
    EXPECT_LT(m.at<cv::Vec3b>(0, 3)[1] + 100, m.at<cv::Vec3b>(7, 3)[1]) << "m grows downwards";
  }
  // Captions say what each image is and its range in units.
  EXPECT_NE(maps.find("shininess shared by the lobes (Phong exponent)<br>range 5 to 12 unitless"), std::string::npos)
      << maps;
  EXPECT_NE(maps.find("diffuse colour (R, G, B)<br>range 0 to 0.35 radiance (HDR units)"), std::string::npos);
  const std::vector<std::string> ticks = tick_labels(maps);
  EXPECT_GE(ticks.size(), 2u * by_alt.size() - 4) << "two or more ticks per false-colour image";
  for (const std::string& label : ticks) EXPECT_TRUE(readable_tick(label)) << "tick label " << label;
  // The held-out RMS runs from 0.01 to 0.09: ticks 0.02, 0.04, ..., not 0.011 or 0.088.
  EXPECT_NE(maps.find(">0.02</text>"), std::string::npos);
  EXPECT_NE(maps.find(">0.08</text>"), std::string::npos);
}

size_t count_of(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

/// A calib/views.json for `session` (camera.yml not written): every view posed with an error of 0.010 to 0.030 px,
/// except view `too_far` (1.5 px, excluded at the 1 px threshold) and view `no_pose` (markers not found). The
/// kinematic fit of a views.json already there (the session's true calibration) is kept.
void write_calibration(const capture::Session& session, int too_far, int no_pose) {
  calib::ViewsFile file;
  if (fs::exists(session.layout().views_file())) {
    auto earlier = calib::read_views_json(session.layout().views_file());
    ASSERT_TRUE(earlier) << earlier.error().describe();
    file.kinematics = earlier->kinematics;
  }
  file.layout = calib::MarkerLayout::corners(session.manifest().surface_width_mm, session.manifest().surface_height_mm);
  for (const capture::PlannedView& planned : session.manifest().views) {
    calib::ViewRecord v;
    v.index = planned.index;
    if (v.index == no_pose) {
      v.error = "no dark blob (contrast too low)";
    } else {
      calib::ViewExtrinsics e;
      e.reprojection_error_px = v.index == too_far ? 1.5 : 0.010 + 0.005 * (v.index % 5);
      e.excluded = e.reprojection_error_px > file.max_error_px;
      e.markers_px.assign(4, Vec2d(10, 10));
      v.extrinsics = e;
    }
    file.views.push_back(v);
  }
  fs::create_directories(session.layout().views_file().parent_path());
  ASSERT_TRUE(write_views_json(session.layout().views_file(), file));
}

// The views are shown as a grid of thumbnails labelled with their numbers; views held out of a fit and views the
// calibration excluded are marked there and on the coverage plot, which has a legend.
TEST_F(Report, ViewsThumbnailsAndCoverageMarkHeldOutAndExcludedViews) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 5);
  write_calibration(session.value(), 2, n - 1);
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), 8, 8, session->manifest().surface_width_mm,
                            session->manifest().surface_height_mm);
  map.image().string_attributes["vdrig.held_out_views"] = "1,3";
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(map.write(session->layout().parameter_map_file("phong:1")));

  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  const std::string coverage = section_of(*html, "coverage");
  EXPECT_EQ(count_of(coverage, "class=\"mark-held-out\""), 2u) << "views 1 and 3 ringed";
  EXPECT_EQ(count_of(coverage, "class=\"mark-excluded\""), 2u) << "views 2 and " << n - 1 << " crossed out";
  EXPECT_NE(coverage.find("class=\"legend\""), std::string::npos);
  for (const char* key : {"held out of a fit", "excluded by the calibration", "not captured"})
    EXPECT_NE(coverage.find(key), std::string::npos) << key;

  const std::string views = section_of(*html, "views");
  EXPECT_EQ(count_of(views, "<figure class=\"thumb"), size_t(n)) << "one thumbnail per merged view";
  EXPECT_EQ(count_of(views, "<figure class=\"thumb held-out\""), 2u);
  EXPECT_EQ(count_of(views, "<figure class=\"thumb excluded\""), 2u);
  EXPECT_NE(views.find("<figcaption>3 held out</figcaption>"), std::string::npos);
  EXPECT_NE(views.find("<figcaption>2 excluded</figcaption>"), std::string::npos);
  EXPECT_NE(views.find("<figcaption>0</figcaption>"), std::string::npos) << "every thumbnail has its view number";
  const auto thumbnails = images_of(views);
  ASSERT_EQ(thumbnails.size(), size_t(n));
  for (const auto& [alt, image] : thumbnails) {
    ASSERT_FALSE(image.empty()) << alt << " does not decode";
    EXPECT_EQ(image.cols, 96) << alt;
    EXPECT_EQ(image.rows, 72) << alt << ": the camera's 4:3";
    EXPECT_GT(cv::mean(image)[1], 10) << alt << ": the tone-mapped surface, not black";
  }
  EXPECT_EQ(thumbnails[3].first, "view 3");
}

// The calibration chart: one bar per view on a scale fitted to the kept views' errors (hundredths of a pixel, not the
// 1 px threshold), round tick values with the unit, view numbers under the bars, an excluded view's bar clipped
// with a mark, a view without a pose crossed under the axis.
TEST_F(Report, CalibrationChartFitsItsScaleAndLabelsTheViews) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 5);
  write_calibration(session.value(), 2, n - 1);
  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  const std::string calibration = section_of(*html, "calibration");
  EXPECT_EQ(tick_labels(calibration, "y"), (std::vector<std::string>{"0", "0.01", "0.02", "0.03"})) << calibration;
  const std::vector<std::string> x = tick_labels(calibration, "x");
  ASSERT_EQ(x.size(), size_t(n)) << "a few views: each labelled";
  for (int i = 0; i < n; ++i) EXPECT_EQ(x[i], std::to_string(i));
  EXPECT_EQ(count_of(calibration, "<rect class=\"bar"), size_t(n - 1)) << "a bar per posed view";
  EXPECT_EQ(count_of(calibration, "class=\"clipped\""), 1u) << "view 2's 1.5 px bar is above the scale";
  EXPECT_EQ(count_of(calibration, "class=\"no-pose\""), 1u);
  EXPECT_EQ(count_of(calibration, "class=\"threshold\""), 0u) << "1 px is far off a 0.03 px scale";
  EXPECT_NE(calibration.find("far above this scale"), std::string::npos);
  EXPECT_NE(calibration.find(">reprojection error, px</text>"), std::string::npos);
  EXPECT_NE(calibration.find(">view</text>"), std::string::npos);
  EXPECT_NE(calibration.find(std::to_string(n - 2) + " of " + std::to_string(n) + " views usable"), std::string::npos);
}

// A simulated session's maps are evaluated against the truth, the figures `vdrig eval MAP --scene S --session S`
// prints (evaluate_map with its defaults: 1000 directions and the session's views); a session the simulator did not
// capture has no truth, and the section says so without a table.
TEST_F(Report, SimulatedSessionShowsTheErrorAgainstTheTruthAsVdrigEval) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  auto obs_file = session_obsmap_file(session.value(), 8, 8);
  ASSERT_TRUE(obs_file) << obs_file.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_file.value());
  ASSERT_TRUE(obs);
  auto map = fitting::fit_parameter_map(obs.value(), fitting::MapFitOptions{});
  ASSERT_TRUE(map) << map.error().describe();
  fs::create_directories(session->layout().maps_dir());
  ASSERT_TRUE(map->write(session->layout().parameter_map_file("phong:1")));
  // An older fit, first by name: the texels are those of the latest fit.
  const fs::path older = session->layout().parameter_map_file("a_older");
  ASSERT_TRUE(map->write(older));
  fs::last_write_time(older,
                      fs::last_write_time(session->layout().parameter_map_file("phong:1")) - std::chrono::hours(1));

  auto html = build_report_html(dir_ / "session");
  ASSERT_TRUE(html) << html.error().describe();
  const std::string texels = section_of(*html, "texels");
  EXPECT_NE(texels.find("Map <code>phong:1.exr</code> (the most recently fitted)"), std::string::npos) << texels;
  // Each texel (the worst and the median) with the inspector's curve plot, as SVG, and its parameters as a table.
  EXPECT_EQ(count_of(texels, "<svg class=\"plot\""), 2u);
  EXPECT_NE(texels.find("<th>kd (R, G, B)</th>"), std::string::npos) << texels;
  EXPECT_EQ(texels.find("kd.R "), std::string::npos) << "no wall of name-value pairs";
  const std::string eval = section_of(*html, "eval");
  EXPECT_NE(eval.find("scene <code>patchwork</code>"), std::string::npos) << eval;
  EXPECT_NE(eval.find("vdrig eval MAP --scene patchwork --session"), std::string::npos) << eval;
  auto scene = sim::make_scene("patchwork");
  ASSERT_TRUE(scene);
  EvalOptions options;  // vdrig eval's defaults, with --session
  options.session_dir = dir_ / "session";
  auto expected = evaluate_map(map.value(), scene.value(), options);
  ASSERT_TRUE(expected) << expected.error().describe();
  ASSERT_FALSE(expected->materials.empty());
  ASSERT_GT(expected->session_views, 0);
  for (const MaterialEval& m : expected->materials) {
    char row[512];
    std::snprintf(row, sizeof row,
                  "<tr><td>%s</td><td>%d</td><td>%.2f</td><td>%.2f</td><td>%.2f</td><td>%.2f</td><td>%.2f</td>"
                  "<td>%.2f</td>",
                  m.name.c_str(), m.texels, 100 * m.dense.mean, 100 * m.dense.p95, 100 * m.dense.p99, 100 * m.dense.max,
                  100 * m.session.mean, 100 * m.session.p95);
    EXPECT_NE(eval.find(row), std::string::npos) << "the row vdrig eval prints: " << row << "\nin " << eval;
  }
  const auto images = images_of(eval);
  ASSERT_EQ(images.size(), 2u) << "the per-texel error map of each map";
  EXPECT_EQ(images[0].first, "relative RMS error");
  EXPECT_EQ(images[0].second.cols, 8);

  // The same session as a real rig's (its rig config without a "sim" section): no truth, no table.
  auto manifest = read_json_file(session->layout().manifest_file());
  ASSERT_TRUE(manifest);
  (*manifest)["rig_config"] = {{"backend", "v4l2"}};
  ASSERT_TRUE(write_file_atomic(session->layout().manifest_file(), manifest->dump(2)));
  auto real = build_report_html(dir_ / "session");
  ASSERT_TRUE(real) << real.error().describe();
  const std::string no_truth = section_of(*real, "eval");
  EXPECT_NE(no_truth.find("No truth to compare with"), std::string::npos) << no_truth;
  EXPECT_EQ(no_truth.find("<table"), std::string::npos);
}

TEST_F(Report, DamagedSessionIsAClearError) {
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session);
  ASSERT_TRUE(write_file_atomic(session->layout().manifest_file(), "{ not json"));
  auto html = build_report_html(dir_ / "session");
  ASSERT_FALSE(html);
  EXPECT_NE(html.error().message.find("cannot read session"), std::string::npos) << html.error().message;
  EXPECT_FALSE(build_report_html(dir_ / "nowhere"));

#ifdef VDRIG_CLI_PATH
  const auto r = vdrig::test::run_vdrig("report " + vdrig::test::shell_quote((dir_ / "session").string()) + " --out " +
                                        vdrig::test::shell_quote((dir_ / "r.html").string()));
  EXPECT_TRUE(r.exit_code != 0 && r.signal == 0 && !r.timed_out) << "exit " << r.exit_code;
  const std::string& message = r.err;
  EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1) << "one line: " << message;
  EXPECT_NE(message.find("manifest"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir_ / "r.html"));
#endif
}

/// Debian's chromium, or empty when not installed.
std::string find_chromium() {
  for (const char* candidate : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(candidate)) return candidate;
  return "";
}

/// Checks run inside the page once it has loaded: every section present, every <img> decoded, no error event, no
/// console.error, no fetched resource and no src/href other than inline data: URIs and in-page anchors. The verdict is
/// written into the DOM as JSON, which --dump-dom prints.
constexpr const char* kCheckScript = R"(<script>
window.vdrigProblems = [];
window.addEventListener('error', e => vdrigProblems.push('error event: ' + (e.message || (e.target && e.target.outerHTML
  ? e.target.outerHTML.slice(0, 80) : '?'))), true);
const vdrigConsoleError = console.error;
console.error = (...args) => {
  vdrigProblems.push('console.error: ' + args.join(' '));
  vdrigConsoleError.apply(console, args);
};
window.addEventListener('load', () => {
  const problems = vdrigProblems.slice();
  for (const img of document.images)
    if (!img.complete || img.naturalWidth === 0) problems.push('image not decoded: ' + img.alt);
  for (const id of SECTIONS)
    if (!document.querySelector('section#' + id)) problems.push('missing section ' + id);
  for (const r of performance.getEntriesByType('resource')) problems.push('fetched: ' + r.name);
  // Nothing runs off the page at the window's width (1280 px): long cells wrap, wide tables scroll inside it.
  const width = document.documentElement.scrollWidth;
  if (width > window.innerWidth) problems.push('wider than the window: ' + width + ' px > ' + window.innerWidth + ' px');
  for (const e of document.querySelectorAll('[src], [href]')) {
    const url = e.getAttribute('src') || e.getAttribute('href');
    if (!url.startsWith('data:') && !url.startsWith('#')) problems.push('external reference: ' + url);
  }
  const pre = document.createElement('pre');
  pre.id = 'vdrig-check';
  pre.textContent = JSON.stringify({problems: problems, images: document.images.length,
                                    svgs: document.querySelectorAll('svg').length,
                                    thumbnails: [...document.querySelectorAll('figure.thumb img')]
                                      .filter(i => i.naturalWidth === 96).length,
                                    held: document.querySelectorAll('figure.thumb.held-out').length,
                                    rings: document.querySelectorAll('#coverage .mark-held-out').length,
                                    crosses: document.querySelectorAll('#coverage .mark-excluded').length,
                                    excluded: document.querySelectorAll('figure.thumb.excluded').length});
  document.body.appendChild(pre);
});
</script>)";

struct BrowserVerdict {
  bool ran = false;
  std::string failure;  // why it did not run
  nlohmann::json problems = nlohmann::json::array();
  int images = 0, svgs = 0;
  nlohmann::json counts;  // the verdict's other numbers: thumbnails (decoded, 96 px), held, rings, crosses, excluded
  std::string console_lines;  // chromium's log lines of console messages (any level)
};

/// Loads `html` (written to DIR/page.html with kCheckScript injected at the top of <head>) in headless chromium and
/// reads the verdict back from the dumped DOM.
BrowserVerdict load_in_browser(const std::string& chromium, const std::string& html, const fs::path& dir) {
  BrowserVerdict verdict;
  std::string sections = "[";
  for (const char* id : kSections) sections += std::string(sections.size() > 1 ? "," : "") + "'" + id + "'";
  std::string script = kCheckScript;
  script.replace(script.find("SECTIONS"), 8, sections + "]");
  std::string checked = html;
  const auto head = checked.find("<head>");
  if (head == std::string::npos) return verdict.failure = "no <head>", verdict;
  checked.insert(head + 6, script);
  const fs::path page = dir / "page.html";
  if (!write_file_atomic(page, checked)) return verdict.failure = "cannot write " + page.string(), verdict;
  // Headless chromium as root needs --no-sandbox; its own profile folder keeps it away from $HOME.
  const std::vector<std::string> argv = {chromium,
                                         "--headless",
                                         "--no-sandbox",
                                         "--disable-gpu",
                                         "--no-first-run",
                                         "--user-data-dir=" + (dir / "profile").string(),
                                         "--enable-logging=stderr",
                                         "--v=0",
                                         "--virtual-time-budget=5000",
                                         "--window-size=1280,1024",  // the width the issue read the report at
                                         "--dump-dom",
                                         "file://" + fs::absolute(page).string()};
  const vdrig::test::ProcessRun run = vdrig::test::run_process(argv, {60});
  const std::string& out = run.out;  // the DOM; chromium's log is run.err
  if (run.exit_code != 0) {
    verdict.failure = "chromium exited " + std::to_string(run.exit_code) + ":";
    for (const auto& a : argv) verdict.failure += " " + a;
    return verdict.failure += "\n" + run.err, verdict;
  }
  const std::string open = "<pre id=\"vdrig-check\">";
  const auto start = out.find(open);
  if (start == std::string::npos)
    return verdict.failure = "the checks did not run:\n" + out.substr(0, 2000) + run.err, verdict;
  std::string text = out.substr(start + open.size(), out.find("</pre>", start) - start - open.size());
  for (const auto& [entity, plain] : {std::pair{"&lt;", "<"}, std::pair{"&gt;", ">"}, std::pair{"&amp;", "&"}})
    for (size_t at = text.find(entity); at != std::string::npos; at = text.find(entity, at + 1))
      text.replace(at, std::string(entity).size(), plain);
  const auto result = nlohmann::json::parse(text, nullptr, false);
  if (result.is_discarded()) return verdict.failure = "unreadable verdict: " + text, verdict;
  verdict.ran = true;
  verdict.problems = result["problems"];
  verdict.images = result["images"].get<int>();
  verdict.svgs = result["svgs"].get<int>();
  verdict.counts = result;
  // Console messages of any level appear in chromium's log as "CONSOLE" lines; the report has no script of its own.
  std::istringstream lines(run.err);
  for (std::string line; std::getline(lines, line);)
    if (line.find(":CONSOLE") != std::string::npos) verdict.console_lines += line + "\n";
  return verdict;
}

TEST_F(Report, LoadsInARealBrowserWithoutErrors) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";

  // A session with every part the report shows: a fit with a held-out view, its observation map, a comparison.
  auto session = test::small_merged_session(dir_ / "session");
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  auto obs_file = session_obsmap_file(session.value(), 8, 8);
  ASSERT_TRUE(obs_file) << obs_file.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_file.value());
  ASSERT_TRUE(obs);
  fitting::MapFitOptions fit;
  fit.held_out = spread_holdout_views(n, 1);
  auto map = fitting::fit_parameter_map(obs.value(), fit);
  ASSERT_TRUE(map) << map.error().describe();
  const fs::path map_path = session->layout().parameter_map_file("phong:1");
  fs::create_directories(map_path.parent_path());
  ASSERT_TRUE(map->write(map_path));
  auto compared = compare_maps(session.value(), {map_path}, fit.held_out);
  if (!compared && compared.error().code == ErrorCode::kUnsupported)
    VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display for the comparison: " << compared.error().message;
  ASSERT_TRUE(compared) << compared.error().describe();

  // Written after the fit and the comparison, which would otherwise pose the views with it.
  write_calibration(session.value(), 2, n - 1);
  ReportOptions options;
  options.texels = {{3, 4}};
  auto html = build_report_html(dir_ / "session", options);
  ASSERT_TRUE(html) << html.error().describe();
  for (const char* id : {"calibration", "maps", "compare", "texels"})
    EXPECT_EQ(section_of(*html, id).find("Missing:"), std::string::npos) << id << ": " << section_of(*html, id);

  const BrowserVerdict verdict = load_in_browser(chromium, html.value(), dir_);
  ASSERT_TRUE(verdict.ran) << verdict.failure;
  EXPECT_TRUE(verdict.problems.empty()) << verdict.problems.dump(2);
  EXPECT_GE(verdict.images, 4 + 2 + 3 + n) << "compare thumbnails, quality and parameter maps, view thumbnails";
  EXPECT_GE(verdict.svgs, 4) << "polar plots and colour bars";
  EXPECT_EQ(verdict.counts.value("thumbnails", -1), n) << "every view's thumbnail decoded, 96 px wide";
  EXPECT_EQ(verdict.counts.value("held", -1), int(fit.held_out.size()));
  EXPECT_EQ(verdict.counts.value("rings", -1), int(fit.held_out.size()));
  EXPECT_EQ(verdict.counts.value("excluded", -1), 2);
  EXPECT_EQ(verdict.counts.value("crosses", -1), 2);
  EXPECT_TRUE(verdict.console_lines.empty()) << verdict.console_lines;
}

// The browser check itself can fail: a page with an image that does not decode, a console error, a fetch and a
// missing section is caught on each count.
TEST_F(Report, BrowserCheckCatchesBrokenPages) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";
  const std::string broken =
      "<!DOCTYPE html><html><head><title>broken</title></head><body><section id=\"coverage\"></section>"
      "<img alt=\"bad\" src=\"data:image/png;base64,AAAA\"><img alt=\"far\" src=\"missing.png\">"
      "<div style=\"width: 3000px\">wide</div><script>console.error('boom')</script></body></html>";
  const BrowserVerdict verdict = load_in_browser(chromium, broken, dir_);
  ASSERT_TRUE(verdict.ran) << verdict.failure;
  const std::string problems = verdict.problems.dump();
  for (const char* expected : {"image not decoded: bad", "image not decoded: far", "console.error: boom",
                               "missing section views", "external reference: missing.png", "wider than the window"})
    EXPECT_NE(problems.find(expected), std::string::npos) << expected << " in " << problems;
  EXPECT_FALSE(verdict.console_lines.empty());
}

}  // namespace
}  // namespace vdrig::pipeline
