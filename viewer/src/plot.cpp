#include "vdrig/viewer/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/markup.hpp"

namespace vdrig::viewer::plot {

Ticks nice_ticks(double lo, double hi, int max_ticks) {
  Ticks ticks;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo) || max_ticks < 2) {
    ticks.values = {std::isfinite(lo) ? lo : 0.0};
    return ticks;
  }
  // The smallest step of 1, 2 or 5 x 10^k that fits the range in max_ticks ticks.
  const double raw = (hi - lo) / (max_ticks - 1);
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  ticks.step = 10 * decade;
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * decade >= raw * (1 - 1e-9)) {
      ticks.step = m * decade;
      break;
    }
  const double first = std::ceil(lo / ticks.step - 1e-9);
  for (double k = first; k * ticks.step <= hi + 1e-9 * ticks.step && ticks.values.size() <= size_t(max_ticks); ++k)
    ticks.values.push_back(k * ticks.step);
  return ticks;
}

std::string tick_label(double value, double step) {
  char buf[64];
  if (!std::isfinite(value) || !(step > 0) || !std::isfinite(step)) {
    std::snprintf(buf, sizeof buf, "%.3g", value);
    return buf;
  }
  if (std::abs(value) < 1e-6 * step) return "0";
  if (step < 1e-4) {
    // The significant digits that tell the ticks apart.
    const int digits = std::max(1, 1 + int(std::floor(std::log10(std::abs(value) / step))));
    std::snprintf(buf, sizeof buf, "%.*g", digits, value);
    return buf;
  }
  const int decimals = std::max(0, int(std::ceil(-std::log10(step) - 1e-9)));
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

Axis nice_axis(const std::string& label, double lo, double hi, int max_ticks) {
  Axis axis{label, lo, hi, nice_ticks(lo, hi, max_ticks)};
  const double step = axis.ticks.step;
  if (!(step > 0)) return axis;
  // Widened to the ticks around the data, each end labelled.
  axis.lo = std::floor(lo / step + 1e-9) * step;
  axis.hi = std::ceil(hi / step - 1e-9) * step;
  axis.ticks.values.clear();
  for (double k = std::round(axis.lo / step); k * step <= axis.hi + 1e-9 * step; ++k)
    axis.ticks.values.push_back(k * step);
  return axis;
}

Axis stepped_axis(const std::string& label, double lo, double hi, double step) {
  Axis axis{label, lo, hi, {{}, step}};
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; ++k) axis.ticks.values.push_back(k * step);
  return axis;
}

namespace {

constexpr Rgb kInk{40, 40, 40}, kFrame{120, 120, 120}, kGrid{228, 228, 228};
constexpr double kFont = 11, kSmallFont = 10;

Shape text_shape(Vec2d at, std::string text, double size, Shape::Anchor anchor, const std::string& role,
                 bool vertical = false) {
  Shape s;
  s.kind = Shape::Kind::kText;
  s.points = {at};
  s.colour = kInk;
  s.size_px = size;
  s.text = std::move(text);
  s.anchor = anchor;
  s.vertical = vertical;
  s.role = role;
  return s;
}

Shape line_shape(std::vector<Vec2d> points, Rgb colour, double width, const std::string& role) {
  Shape s;
  s.points = std::move(points);
  s.colour = colour;
  s.size_px = width;
  s.role = role;
  return s;
}

Shape mark_shape(Marker marker, Vec2d at, Rgb colour, double radius, const std::string& role) {
  Shape s;
  s.kind = marker == Marker::kCross ? Shape::Kind::kCross : Shape::Kind::kCircle;
  s.points = {at};
  s.colour = colour;
  s.size_px = radius;
  s.role = role;
  return s;
}

/// The part of segment a-b inside the box [x0, x1] x [y0, y1] (Liang-Barsky), false when none is.
bool clip(Vec2d& a, Vec2d& b, double x0, double x1, double y0, double y1) {
  double t0 = 0, t1 = 1;
  const Vec2d d = b - a;
  const double p[4] = {-d.x(), d.x(), -d.y(), d.y()};
  const double q[4] = {a.x() - x0, x1 - a.x(), a.y() - y0, y1 - a.y()};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
  }
  if (t0 > t1) return false;
  const Vec2d a0 = a;
  a = a0 + t0 * d;
  b = a0 + t1 * d;
  return true;
}

std::string fmt1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string hex(Rgb c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", c.r, c.g, c.b);
  return buf;
}

}  // namespace

std::vector<Shape> layout(const Figure& f) {
  std::vector<Shape> shapes;
  int legend_entries = 0;
  for (const Series& s : f.series) legend_entries += !s.name.empty();
  // Margins: tick labels and the turned y label on the left, tick labels, the x label and the legend below.
  const double left = 62, right = 14, top = f.title.empty() ? 12 : 26;
  const double bottom = 44 + (legend_entries > 0 ? 18 : 0);
  const double x0 = left, x1 = std::max(left + 10, f.width_px - right);
  const double y0 = top, y1 = std::max(top + 10, f.height_px - bottom);
  const auto px = [&](const Vec2d& p) {
    const double u = f.x.hi > f.x.lo ? (p.x() - f.x.lo) / (f.x.hi - f.x.lo) : 0.5;
    const double v = f.y.hi > f.y.lo ? (p.y() - f.y.lo) / (f.y.hi - f.y.lo) : 0.5;
    return Vec2d(x0 + u * (x1 - x0), y1 - v * (y1 - y0));
  };
  const auto inside = [&](double value, const Axis& a) {
    const double slack = 1e-9 * std::max(1.0, std::abs(a.hi - a.lo));
    return value >= a.lo - slack && value <= a.hi + slack;
  };
  // Grid and ticks.
  for (double t : f.y.ticks.values) {
    if (!inside(t, f.y)) continue;
    const double y = px({f.x.lo, t}).y();
    shapes.push_back(line_shape({{x0, y}, {x1, y}}, kGrid, 1, "grid"));
    shapes.push_back(line_shape({{x0 - 4, y}, {x0, y}}, kFrame, 1, "axis"));
    shapes.push_back(
        text_shape({x0 - 6, y + 3.5}, tick_label(t, f.y.ticks.step), kSmallFont, Shape::Anchor::kEnd, "tick y"));
  }
  for (double t : f.x.ticks.values) {
    if (!inside(t, f.x)) continue;
    const double x = px({t, f.y.lo}).x();
    shapes.push_back(line_shape({{x, y0}, {x, y1}}, kGrid, 1, "grid"));
    shapes.push_back(line_shape({{x, y1}, {x, y1 + 4}}, kFrame, 1, "axis"));
    shapes.push_back(
        text_shape({x, y1 + 16}, tick_label(t, f.x.ticks.step), kSmallFont, Shape::Anchor::kMiddle, "tick x"));
  }
  shapes.push_back(line_shape({{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}}, kFrame, 1, "axis"));
  shapes.push_back(text_shape({(x0 + x1) / 2, y1 + 32}, f.x.label, kFont, Shape::Anchor::kMiddle, "label x"));
  shapes.push_back(text_shape({14, (y0 + y1) / 2}, f.y.label, kFont, Shape::Anchor::kMiddle, "label y", true));
  if (!f.title.empty()) shapes.push_back(text_shape({x0, 16}, f.title, kFont, Shape::Anchor::kStart, "title"));
  // Series: lines clipped to the axes, markers inside them.
  for (const Series& s : f.series) {
    if (s.line && s.points.size() > 1) {
      std::vector<Vec2d> run;
      for (size_t i = 1; i < s.points.size(); ++i) {
        Vec2d a = px(s.points[i - 1]), b = px(s.points[i]);
        if (!std::isfinite(a.x() + a.y() + b.x() + b.y()) || !clip(a, b, x0, x1, y0, y1)) {
          if (run.size() > 1) shapes.push_back(line_shape(run, s.colour, s.line_width_px, "series"));
          run.clear();
          continue;
        }
        if (run.empty() || (run.back() - a).norm() > 1e-9) {
          if (run.size() > 1) shapes.push_back(line_shape(run, s.colour, s.line_width_px, "series"));
          run = {a};
        }
        run.push_back(b);
      }
      if (run.size() > 1) shapes.push_back(line_shape(run, s.colour, s.line_width_px, "series"));
    }
    if (s.marker != Marker::kNone)
      for (const Vec2d& p : s.points)
        if (std::isfinite(p.x() + p.y()) && inside(p.x(), f.x) && inside(p.y(), f.y))
          shapes.push_back(mark_shape(s.marker, px(p), s.colour, s.marker_px, "series"));
  }
  // Legend: a sample of each named series and its name, in a row under the x label.
  double lx = x0;
  const double ly = f.height_px - 8.0;
  for (const Series& s : f.series) {
    if (s.name.empty()) continue;
    if (s.line) shapes.push_back(line_shape({{lx, ly - 4}, {lx + 16, ly - 4}}, s.colour, s.line_width_px, "legend"));
    if (s.marker != Marker::kNone)
      shapes.push_back(mark_shape(s.marker, {lx + 8, ly - 4}, s.colour, s.marker_px, "legend"));
    shapes.push_back(text_shape({lx + 20, ly}, s.name, kSmallFont, Shape::Anchor::kStart, "legend"));
    lx += 30 + 6.6 * static_cast<double>(s.name.size());  // at least the width of 10 px text, SVG or Hershey
  }
  return shapes;
}

std::string to_svg(const Figure& f) {
  std::string svg = "<svg class=\"plot\" width=\"" + std::to_string(f.width_px) + "\" height=\"" +
                    std::to_string(f.height_px) + "\" viewBox=\"0 0 " + std::to_string(f.width_px) + " " +
                    std::to_string(f.height_px) + "\">";
  for (const Shape& s : layout(f)) {
    const std::string cls = " class=\"" + core::escape_html(s.role) + "\"";
    const std::string colour = hex(s.colour);
    const Vec2d& p = s.points.front();
    switch (s.kind) {
      case Shape::Kind::kPolyline: {
        svg += "<polyline" + cls + " fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"" + fmt1(s.size_px) +
               "\" stroke-linejoin=\"round\" points=\"";
        for (size_t i = 0; i < s.points.size(); ++i)
          svg += (i ? " " : "") + fmt1(s.points[i].x()) + "," + fmt1(s.points[i].y());
        svg += "\"/>";
        break;
      }
      case Shape::Kind::kCircle:
        svg += "<circle" + cls + " cx=\"" + fmt1(p.x()) + "\" cy=\"" + fmt1(p.y()) + "\" r=\"" + fmt1(s.size_px) +
               "\" fill=\"none\" stroke=\"" + colour + "\"/>";
        break;
      case Shape::Kind::kCross: {
        const double a = s.size_px;
        svg += "<path" + cls + " d=\"M" + fmt1(p.x() - a) + " " + fmt1(p.y() - a) + "L" + fmt1(p.x() + a) + " " +
               fmt1(p.y() + a) + "M" + fmt1(p.x() - a) + " " + fmt1(p.y() + a) + "L" + fmt1(p.x() + a) + " " +
               fmt1(p.y() - a) + "\" stroke=\"" + colour + "\" stroke-width=\"2\"/>";
        break;
      }
      case Shape::Kind::kText: {
        const char* anchor = s.anchor == Shape::Anchor::kStart    ? "start"
                             : s.anchor == Shape::Anchor::kMiddle ? "middle"
                                                                  : "end";
        svg += "<text" + cls + " x=\"" + fmt1(p.x()) + "\" y=\"" + fmt1(p.y()) + "\" font-size=\"" + fmt1(s.size_px) +
               "\" fill=\"" + colour + "\" text-anchor=\"" + anchor + "\"" +
               (s.vertical ? " transform=\"rotate(-90 " + fmt1(p.x()) + " " + fmt1(p.y()) + ")\"" : "") + ">" +
               core::escape_html(s.text) + "</text>";
        break;
      }
    }
  }
  return svg + "</svg>";
}

namespace {

cv::Point to_cv(const Vec2d& p, const cv::Point& offset) {
  return offset + cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
}

cv::Scalar bgr(Rgb c) { return cv::Scalar(c.b, c.g, c.r); }

// OpenCV's Hershey simplex font, scaled so its capital letters are about 0.7 of the font height as in the SVG.
void draw_text(cv::Mat& image, const Shape& s, const cv::Point& offset) {
  const double scale = s.size_px / 26.0;
  int baseline = 0;
  const cv::Size size = cv::getTextSize(s.text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
  const int shift =
      s.anchor == Shape::Anchor::kStart ? 0 : (s.anchor == Shape::Anchor::kMiddle ? size.width / 2 : size.width);
  const cv::Point at = to_cv(s.points.front(), offset);
  if (!s.vertical) {
    cv::putText(image, s.text, at - cv::Point(shift, 0), cv::FONT_HERSHEY_SIMPLEX, scale, bgr(s.colour), 1,
                cv::LINE_AA);
    return;
  }
  // Turned text: drawn flat on white, turned, and its ink copied where it falls inside the image.
  cv::Mat flat(size.height + baseline + 2, size.width + 2, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(flat, s.text, {1, size.height + 1}, cv::FONT_HERSHEY_SIMPLEX, scale, bgr(s.colour), 1, cv::LINE_AA);
  cv::Mat turned;
  cv::rotate(flat, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
  // The baseline runs upward along x = at.x; the anchor is along it.
  const cv::Point origin(at.x - size.height, at.y - (turned.rows - shift));
  for (int y = 0; y < turned.rows; ++y)
    for (int x = 0; x < turned.cols; ++x) {
      const cv::Point q = origin + cv::Point(x, y);
      const cv::Vec3b ink = turned.at<cv::Vec3b>(y, x);
      if (ink == cv::Vec3b(255, 255, 255) || q.x < 0 || q.y < 0 || q.x >= image.cols || q.y >= image.rows) continue;
      image.at<cv::Vec3b>(q) = ink;
    }
}

}  // namespace

void draw(const Figure& figure, cv::Mat& image, const cv::Rect& area) {
  Figure f = figure;
  f.width_px = area.width;
  f.height_px = area.height;
  const cv::Point offset = area.tl();
  for (const Shape& s : layout(f)) {
    const int thickness = std::max(1, static_cast<int>(std::lround(s.size_px)));
    switch (s.kind) {
      case Shape::Kind::kPolyline: {
        std::vector<cv::Point> points;
        for (const Vec2d& p : s.points) points.push_back(to_cv(p, offset));
        cv::polylines(image, points, false, bgr(s.colour), thickness, cv::LINE_AA);
        break;
      }
      case Shape::Kind::kCircle:
        cv::circle(image, to_cv(s.points.front(), offset), thickness, bgr(s.colour), 1, cv::LINE_AA);
        break;
      case Shape::Kind::kCross:
        cv::drawMarker(image, to_cv(s.points.front(), offset), bgr(s.colour), cv::MARKER_TILTED_CROSS,
                       2 * thickness + 1, 2);
        break;
      case Shape::Kind::kText:
        draw_text(image, s, offset);
        break;
    }
  }
}

cv::Mat to_image(const Figure& figure) {
  cv::Mat image(std::max(1, figure.height_px), std::max(1, figure.width_px), CV_8UC3, cv::Scalar(255, 255, 255));
  draw(figure, image, {0, 0, image.cols, image.rows});
  return image;
}

}  // namespace vdrig::viewer::plot
