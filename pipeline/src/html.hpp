// The HTML/SVG toolkit of the session report (report.cpp holds its sections): numbers formatted for text, inline PNG
// images, viridis colours and colour bars, false-colour maps of a float plane, polar plots of the hemisphere, and
// the section frame. Everything returns markup as a string; text is escaped with escape_html (core/markup.hpp).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "vdrig/core/geometry.hpp"
#include "vdrig/core/markup.hpp"
#include "vdrig/viewer/plot.hpp"

namespace vdrig::pipeline {
using core::escape_html;  // the report's and its helpers' one escaping, shared with the plots
}  // namespace vdrig::pipeline

namespace vdrig::pipeline::html {

/// `value` through a printf format with one double conversion ("%.4g").
std::string number(const char* printf_format, double value);

/// `value` to `digits` significant digits for a reader: plain decimals between 1e-4 and 1e6 ("0.000512", "12.3"),
/// scientific notation outside ("2.22e-05"), no trailing zeros; "nan" / "inf" as such.
std::string significant(double value, int digits = 3);

/// A measured value with its standard deviation, both to the decimals of sigma's two significant digits
/// ("0.00002 ± 0.00051", "12.35 ± 0.21"); a value without a usable sigma (<= 0, not finite) as significant().
std::string with_uncertainty(double value, double sigma);

/// An end label of a scale from lo to hi: `value` to 3 significant digits, but 0 when it is zero at the scale of the
/// range (a colour-bar minimum of 2.2e-17 on a 0..0.04 scale is 0).
std::string scale_label(double value, double lo, double hi);

/// Axis or colour-bar ticks and their labels: the plots' own (viewer/plot.hpp: multiples of 1, 2 or 5 x 10^k,
/// labelled with the decimals of the step), so the report's bars and colour bars tick as its x-y plots and the
/// inspector's do.
using Ticks = viewer::plot::Ticks;
using viewer::plot::nice_ticks;
using viewer::plot::tick_label;

/// RFC 4648 base64 of `bytes` (with '=' padding), for data: URIs.
std::string base64(std::string_view bytes);

/// An <img> of an 8-bit image (BGR or grey) as an inline PNG (or JPEG with `jpeg_quality` > 0: photographs), shown
/// `display_width` pixels wide (0: its own width; the page scales it, pixelated).
std::string img_tag(const cv::Mat& image, const std::string& alt, int display_width = 0, int jpeg_quality = 0);

/// A paragraph saying what is missing from the session, styled as a notice.
std::string missing(const std::string& what);

/// Viridis (OpenCV's table) at t in [0, 1], as "#rrggbb".
std::string viridis(double t);

/// A horizontal colour bar (viridis) from lo to hi, its label above, tick marks with nice_ticks' values and labels
/// below; `hi_clipped`: values above hi are shown as hi (the right end says so).
std::string colour_bar(double lo, double hi, const std::string& label, bool hi_clipped = false);

/// A false-colour image of a float plane (NaN shown grey) at its own resolution, shown `width` pixels wide (a larger
/// plane is reduced to `width` first), with its colour bar and a caption: `label`, then `what` (markup) and the
/// plane's range in `units`. The scale runs from the minimum to the 99th percentile, so that a few outliers do not
/// darken the whole map.
std::string false_colour(const cv::Mat& plane, const std::string& label, int width, const std::string& what = "",
                         const std::string& units = "");

/// A colour image of three float planes (B, G, R order, as OpenCV's), linear values divided by a white point (the
/// 99th percentile of all three; negative values black, NaN grey), sRGB encoded, shown `width` pixels wide, with a
/// caption: `label`, `what` (markup), the range in `units` and the white point.
std::string colour_image(const cv::Mat& bgr, const std::string& label, int width, const std::string& what,
                         const std::string& units);

/// The range of a finite plane, and its 99th percentile (of all channels).
struct PlaneRange {
  double min = 0, max = 0, p99 = 0;
  bool any = false;  // some value is finite
};
PlaneRange plane_range(const cv::Mat& plane);

/// The marks of views held out of a fit and views the calibration excluded, in plots and the thumbnail grid.
inline constexpr const char* kHeldOutColour = "#d62728";
inline constexpr const char* kExcludedColour = "#111111";

struct PolarPoint {
  Vec3d direction;
  std::string fill;  // "none" for a hollow point
  double radius_px = 4;
  std::string title;
  bool held_out = false;  // ringed (class "mark-held-out")
  bool excluded = false;  // crossed out (class "mark-excluded")
};

/// The upper hemisphere seen from above: radius proportional to the zenith angle (0 at the centre, 90 deg at the rim),
/// azimuth counter-clockwise from +x (to the right). `route` (may be empty) is drawn as a polyline under the points.
std::string polar_plot(const std::vector<PolarPoint>& points, const std::vector<Vec3d>& route, int size_px = 360);

/// A legend of polar_plot's symbols: captured, not captured, held out (ringed), excluded (crossed out).
std::string polar_legend();

/// <section id=...><h2>title</h2>body</section>, the frame of every report section (its id is the nav anchor).
std::string section(const std::string& id, const std::string& title, const std::string& body);

}  // namespace vdrig::pipeline::html
