// The one plotting path (viewer/plot.hpp): tick values are round numbers with short labels, and the SVG of the report
// and the pixels of the inspector are drawn from one layout of one description.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "vdrig/viewer/plot.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::viewer::plot {
namespace {

std::vector<std::string> labels_of(const Ticks& t) {
  std::vector<std::string> out;
  for (double v : t.values) out.push_back(tick_label(v, t.step));
  return out;
}

using Labels = std::vector<std::string>;

TEST(Plot, TicksAreNiceNumbersWithShortLabels) {
  // Reprojection errors of hundredths of a pixel: 0 0.01 0.02 0.03, not 0.0075 steps or 0.030000000000000002.
  EXPECT_EQ(labels_of(nice_ticks(0, 0.031, 5)), (Labels{"0", "0.01", "0.02", "0.03"}));
  EXPECT_EQ(labels_of(nice_ticks(0.011, 0.088, 5)), (Labels{"0.02", "0.04", "0.06", "0.08"}));
  EXPECT_EQ(labels_of(nice_ticks(1, 188, 5)), (Labels{"50", "100", "150"}));
  EXPECT_EQ(labels_of(nice_ticks(-0.37, 0.52, 6)), (Labels{"-0.2", "0", "0.2", "0.4"}));
  EXPECT_EQ(labels_of(nice_ticks(0, 2.2e-05, 5)), (Labels{"0", "1e-05", "2e-05"}));
  EXPECT_EQ(tick_label(-1.7e-18, 0.01), "0") << "zero at the step's scale";
  const Ticks empty = nice_ticks(3, 3);
  EXPECT_EQ(empty.values, std::vector<double>{3});

  // An axis widened to the ticks around its data, both ends labelled.
  const Axis y = nice_axis("radiance", 0, 0.87, 6);
  EXPECT_DOUBLE_EQ(y.lo, 0);
  EXPECT_DOUBLE_EQ(y.hi, 1.0);
  EXPECT_EQ(labels_of(y.ticks), (Labels{"0", "0.2", "0.4", "0.6", "0.8", "1.0"}));
  EXPECT_EQ(labels_of(stepped_axis("deg", -90, 90, 30).ticks), (Labels{"-90", "-60", "-30", "0", "30", "60", "90"}));
}

size_t count_of(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Both back ends draw the layout: every tick label of the layout is in the SVG, in order, with its role; each marker
// sits in the raster at the pixel the layout (and the SVG) put it, in its series' colour; the line runs there too.
TEST(Plot, SvgAndPixelsComeFromOneDescription) {
  Figure f;
  f.title = "two series";
  f.x = nice_axis("angle, deg", -90, 90, 7);
  f.y = nice_axis("radiance", 0, 0.87, 5);
  f.width_px = 480;
  f.height_px = 320;
  Series line{"model", {200, 30, 30}, {}};
  for (int a = -90; a <= 90; a += 5) line.points.emplace_back(a, 0.4 + 0.4 * std::cos(a * 3.14159 / 180));
  Series dots{"observed", {30, 30, 200}, {{-60, 0.2}, {0, 0.5}, {45, 0.7}, {80, 2.0}}};  // the last above the axis
  dots.line = false;
  dots.marker = Marker::kCircle;
  dots.marker_px = 4;
  f.series = {line, dots};

  const std::vector<Shape> shapes = layout(f);
  const std::string svg = to_svg(f);
  const cv::Mat image = to_image(f);
  ASSERT_EQ(image.size(), cv::Size(480, 320));

  std::vector<std::string> layout_ticks, svg_ticks;
  for (const Shape& s : shapes)
    if (s.kind == Shape::Kind::kText && s.role.rfind("tick", 0) == 0) layout_ticks.push_back(s.text);
  for (size_t at = svg.find("<text class=\"tick"); at != std::string::npos; at = svg.find("<text class=\"tick", at + 1))
    svg_ticks.push_back(svg.substr(svg.find('>', at) + 1, svg.find("</text>", at) - svg.find('>', at) - 1));
  EXPECT_EQ(svg_ticks, layout_ticks);
  EXPECT_EQ(layout_ticks.size(), f.x.ticks.values.size() + f.y.ticks.values.size());
  for (const char* label : {">angle, deg</text>", ">radiance</text>", ">model</text>", ">observed</text>"})
    EXPECT_NE(svg.find(label), std::string::npos) << label;

  std::vector<Vec2d> markers;
  for (const Shape& s : shapes)
    if (s.kind == Shape::Kind::kCircle && s.role == "series") markers.push_back(s.points.front());
  ASSERT_EQ(markers.size(), 3u) << "the point above the y axis' range is not drawn";
  EXPECT_EQ(count_of(svg, "<circle class=\"series\""), 3u);
  for (const Vec2d& m : markers) {
    char at[64];
    std::snprintf(at, sizeof at, "cx=\"%.1f\" cy=\"%.1f\"", m.x(), m.y());
    EXPECT_NE(svg.find(at), std::string::npos) << at;
    // The circle's ring in the raster: a pixel 4 px right of the centre has the series' blue.
    const cv::Vec3b ring = image.at<cv::Vec3b>(int(std::lround(m.y())), int(std::lround(m.x())) + 4);
    EXPECT_GT(int(ring[0]), int(ring[2]) + 60) << "blue ring at " << at;
  }
  // The line: the curve's peak (a = 0, radiance 0.8), the top of its polyline in the layout, is red in the raster.
  double best = 1e9;
  Vec2d peak_px = Vec2d::Zero();
  for (const Shape& s : shapes)
    if (s.kind == Shape::Kind::kPolyline && s.role == "series")
      for (const Vec2d& p : s.points)
        if (p.y() < best) best = p.y(), peak_px = p;
  const cv::Vec3b red = image.at<cv::Vec3b>(int(std::lround(peak_px.y())), int(std::lround(peak_px.x())));
  EXPECT_GT(int(red[2]), int(red[0]) + 60) << "the model line at its peak";
  EXPECT_EQ(count_of(svg, "<polyline class=\"series\""), 1u);
}

// The inspector's curve is a Figure: observations within the band on it as circles, held-out views as crosses, the
// angle axis every 30 degrees, the radiance axis with round ticks covering the data.
TEST(Plot, InspectorCurveIsAFigure) {
  TexelInspection r;
  r.band_deg = 10;
  for (int i = 0; i <= 18; ++i) {
    r.curve_deg.push_back(-90 + 10 * i);
    r.curve.push_back(Vec3d(0.1, 0.2, 0.37) * (1 + std::cos((-90 + 10 * i) * 3.14159 / 180)));
  }
  InspectedObservation near, held, far;
  near.circle_deg = 20, near.observed = Vec3d(0.2, 0.3, 0.5);
  held.circle_deg = -40, held.observed = Vec3d(0.2, 0.3, 0.4), held.held_out = true;
  far.circle_deg = 10, far.off_circle_deg = 30, far.observed = Vec3d(1, 1, 1);
  r.observations = {near, held, far};
  const Figure f = curve_figure(r);
  EXPECT_EQ(labels_of(f.x.ticks), (Labels{"-90", "-60", "-30", "0", "30", "60", "90"}));
  EXPECT_DOUBLE_EQ(f.y.lo, 0);
  EXPECT_NEAR(f.y.hi, 0.8, 1e-12) << "0.74 (the model's peak) rounded up to the next tick";
  size_t circles = 0, crosses = 0;
  for (const Shape& s : layout(f)) {
    circles += s.kind == Shape::Kind::kCircle && s.role == "series";
    crosses += s.kind == Shape::Kind::kCross && s.role == "series";
  }
  EXPECT_EQ(circles, 3u) << "the near observation, R G B; the one 30 deg off the circle not";
  EXPECT_EQ(crosses, 3u) << "the held-out view, R G B";
  const cv::Mat pixels = plot_inspection(r, 800, 450);
  EXPECT_EQ(pixels.size(), cv::Size(800, 450));
}

}  // namespace
}  // namespace vdrig::viewer::plot
