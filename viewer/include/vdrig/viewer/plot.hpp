// One plotting path for vdrig's x-y plots: a plot is described once (Figure: two axes with labels and round tick
// values, series of lines and markers, a legend) and laid out once (layout(): the figure as shapes in pixels: lines,
// markers, texts), and two back ends draw those same shapes: to_svg() for the session report (pipeline/report*) and
// draw() / to_image() for the texel inspector's raster plot (`vdrig inspect`, the viewer's overlay).
//
// Why an in-house description with two back ends rather than one SVG rendered to pixels for both: rasterising SVG
// needs an SVG renderer (librsvg with cairo, or a browser) linked into the viewer, which draws its overlay every time
// a texel is clicked; the shapes here are few (polylines, circles, crosses, text) and OpenCV, which every module
// links already, draws them. No plotting library is packaged for C++ in Debian that writes both SVG and pixels.
// Because both back ends draw the output of one layout, a tick, label or point sits at the same pixel in both.
//
// Tick values are "nice numbers": multiples of 1, 2 or 5 x 10^k (nice_ticks), labelled with the decimals their step
// needs (tick_label), so an axis reads 0 0.01 0.02 0.03, never 0.0275 or 1.7e-18.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vdrig/core/geometry.hpp"

namespace vdrig::viewer::plot {

/// Ticks between lo and hi: multiples of a step of 1, 2 or 5 x 10^k, at most `max_ticks` of them (fewer when the
/// range is narrow), the first at or above lo, the last at or below hi. One tick at lo when the range is empty or
/// not finite.
struct Ticks {
  std::vector<double> values;
  double step = 0;
};
Ticks nice_ticks(double lo, double hi, int max_ticks = 6);

/// A tick's label: `value` with the decimals its step needs ("0.005", "0.01", "25"), 0 for a value that is zero at the
/// step's scale (no "-0" or "1.7e-18"), scientific for steps below 1e-4 ("2e-05").
std::string tick_label(double value, double step);

struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

struct Axis {
  std::string label;  // with its unit ("radiance (HDR units)", "angle from the normal, deg")
  double lo = 0, hi = 1;
  Ticks ticks;
};

/// An axis over the data range [lo, hi] with nice ticks; the range is widened to the ticks around it (0 to 0.87 with
/// a step of 0.2 becomes 0 to 1), so the ends of the axis are labelled.
Axis nice_axis(const std::string& label, double lo, double hi, int max_ticks = 6);

/// An axis from lo to hi with ticks every `step` (angles: every 30 degrees).
Axis stepped_axis(const std::string& label, double lo, double hi, double step);

enum class Marker { kNone, kCircle, kCross };

struct Series {
  std::string name;  // in the legend (empty: not listed)
  Rgb colour;
  std::vector<Vec2d> points;  // data coordinates
  bool line = true;           // joined by a polyline, in the order given
  Marker marker = Marker::kNone;
  double line_width_px = 2;
  double marker_px = 3;  // a marker's radius
};

struct Figure {
  std::string title;
  Axis x, y;
  std::vector<Series> series;
  int width_px = 560, height_px = 360;
};

/// One shape of a laid-out figure, in pixels (origin top left, y down).
struct Shape {
  enum class Kind { kPolyline, kCircle, kCross, kText };
  Kind kind = Kind::kPolyline;
  std::vector<Vec2d> points;  // polyline: its vertices; circle, cross, text: one point (centre; text: its baseline)
  Rgb colour;
  double size_px = 1;  // line width; circle and cross: radius; text: font height
  std::string text;
  enum class Anchor { kStart, kMiddle, kEnd };
  Anchor anchor = Anchor::kStart;  // text: where `points[0]` is along it
  bool vertical = false;           // text: turned 90 degrees counter-clockwise (a y axis label)
  std::string role;                // what it is: "tick x", "tick y", "axis", "grid", "series", "legend", "title"
};

/// The figure as shapes: frame, grid, ticks and their labels, axis labels, title, the series clipped to the axes'
/// ranges, the legend under the x axis label. Both back ends draw exactly these.
std::vector<Shape> layout(const Figure& figure);

/// The figure as an <svg> element (text escaped; each shape's role as its class, ticks "tick x" / "tick y").
std::string to_svg(const Figure& figure);

/// The figure drawn into `area` of a CV_8UC3 (BGR) image, scaled from the figure's own size; to_image: on a white
/// image of the figure's size.
void draw(const Figure& figure, cv::Mat& image, const cv::Rect& area);
cv::Mat to_image(const Figure& figure);

}  // namespace vdrig::viewer::plot
