#include "html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/image_codec.hpp"
#include "vdrig/core/image_io.hpp"

namespace vdrig::pipeline::html {

std::string number(const char* printf_format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof buf, printf_format, value);
  return buf;
}

std::string significant(double value, int digits) {
  if (!std::isfinite(value)) return std::isnan(value) ? "nan" : (value > 0 ? "inf" : "-inf");
  if (value == 0) return "0";
  char buf[64];
  const double magnitude = std::abs(value);
  if (magnitude >= 1e-4 && magnitude < 1e6) {
    // Decimals for `digits` significant digits, then trailing zeros dropped ("0.5", not "0.500").
    const int exponent = static_cast<int>(std::floor(std::log10(magnitude)));
    const int decimals = std::max(0, digits - 1 - exponent);
    std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
    std::string s = buf;
    if (s.find('.') != std::string::npos) {
      s.erase(s.find_last_not_of('0') + 1);
      if (s.back() == '.') s.pop_back();
    }
    return s;
  }
  std::snprintf(buf, sizeof buf, "%.*g", std::max(1, digits), value);
  return buf;
}

std::string with_uncertainty(double value, double sigma) {
  if (!(sigma > 0) || !std::isfinite(sigma) || !std::isfinite(value)) return significant(value, 4);
  const int decimals = 1 - static_cast<int>(std::floor(std::log10(sigma)));  // sigma to two significant digits
  if (decimals > 9) return significant(value, 3) + " ± " + significant(sigma, 2);
  char buf[96];
  const int d = std::max(0, decimals);
  std::snprintf(buf, sizeof buf, "%.*f ± %.*f", d, value, d, sigma);
  std::string s = buf;
  // "-0.00000": the value is zero at the precision of its uncertainty.
  if (s.rfind("-", 0) == 0 && s.find_first_not_of("-0.", 0) == s.find(' ')) s.erase(0, 1);
  return s;
}

std::string scale_label(double value, double lo, double hi) {
  const double scale = std::max(std::abs(lo), std::abs(hi));
  if (std::isfinite(value) && scale > 0 && std::abs(value) <= 1e-6 * scale) return "0";
  return significant(value, 3);
}

std::string base64(std::string_view bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    auto at = [&](size_t k) { return uint32_t(static_cast<unsigned char>(bytes[k])); };
    const uint32_t n =
        (at(i) << 16) | (i + 1 < bytes.size() ? at(i + 1) << 8 : 0) | (i + 2 < bytes.size() ? at(i + 2) : 0);
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[n & 63] : '=';
  }
  return out;
}

std::string img_tag(const cv::Mat& image, const std::string& alt, int display_width, int jpeg_quality) {
  auto bytes = jpeg_quality > 0 ? encode_jpeg(image, jpeg_quality) : encode_png(image, PngCompression::kFastest);
  if (!bytes) return missing(alt + " (" + bytes.error().message + ")");
  const int w = display_width > 0 ? display_width : image.cols;
  const int h = static_cast<int>(std::lround(double(image.rows) * w / std::max(1, image.cols)));
  return "<img alt=\"" + escape_html(alt) + "\" width=\"" + std::to_string(w) + "\" height=\"" + std::to_string(h) +
         "\" src=\"data:image/" + (jpeg_quality > 0 ? "jpeg" : "png") + ";base64," + base64(bytes.value()) + "\">";
}

std::string missing(const std::string& what) { return "<p class=\"missing\">Missing: " + what + "</p>\n"; }

std::string viridis(double t) {
  static const cv::Mat table = [] {
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<uint8_t>(0, i) = static_cast<uint8_t>(i);
    cv::Mat colours;
    cv::applyColorMap(ramp, colours, cv::COLORMAP_VIRIDIS);
    return colours;
  }();
  const int i = std::clamp(static_cast<int>(std::lround(std::clamp(t, 0.0, 1.0) * 255)), 0, 255);
  const cv::Vec3b bgr = table.at<cv::Vec3b>(0, i);
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", bgr[2], bgr[1], bgr[0]);
  return buf;
}

std::string colour_bar(double lo, double hi, const std::string& label, bool hi_clipped) {
  static int id = 0;
  const std::string gid = "cb" + std::to_string(++id);
  constexpr double x0 = 8, bar_w = 244;
  std::string svg =
      "<svg class=\"colourbar\" width=\"260\" height=\"46\" viewBox=\"0 0 260 46\"><defs><linearGradient "
      "id=\"" +
      gid + "\">";
  for (int k = 0; k <= 8; ++k)
    svg += "<stop offset=\"" + number("%.3f", k / 8.0) + "\" stop-color=\"" + viridis(k / 8.0) + "\"/>";
  svg += "</linearGradient></defs><text x=\"" + number("%.0f", x0) + "\" y=\"11\" font-size=\"11\">" +
         escape_html(label) + "</text>";
  svg += "<rect x=\"" + number("%.0f", x0) + "\" y=\"15\" width=\"" + number("%.0f", bar_w) +
         "\" height=\"12\" fill=\"url(#" + gid + ")\"/>";
  const Ticks ticks = nice_ticks(lo, hi, 5);
  for (double v : ticks.values) {
    const double x = hi > lo ? x0 + bar_w * (v - lo) / (hi - lo) : x0;
    const std::string text = tick_label(v, ticks.step);
    // Labels at the ends are anchored inside the bar's width so they are not cut off.
    const char* anchor = x < x0 + 12 ? "start" : (x > x0 + bar_w - 12 ? "end" : "middle");
    svg += "<line class=\"tick\" x1=\"" + number("%.1f", x) + "\" x2=\"" + number("%.1f", x) +
           "\" y1=\"27\" y2=\"31\" stroke=\"#333\"/><text class=\"tick\" x=\"" + number("%.1f", x) +
           "\" y=\"43\" font-size=\"10\" text-anchor=\"" + anchor + "\">" + text + "</text>";
  }
  // The ends of the scale, when no tick is near them (a capture order from 1 to 188 with ticks at 50, 100, 150), to a
  // tenth of the step (0 when zero at that precision). The top end of a clipped scale is labelled above the bar.
  if (hi > lo && ticks.step > 0) {
    const auto end_label = [&](double v) {
      const std::string text = tick_label(v, ticks.step / 10);
      return std::strtod(text.c_str(), nullptr) == 0 ? std::string("0") : text;  // "0.000" is 0
    };
    if (ticks.values.front() - lo > 0.2 * (hi - lo))
      svg += "<text class=\"tick end\" x=\"" + number("%.0f", x0) + "\" y=\"43\" font-size=\"10\">" + end_label(lo) +
             "</text>";
    if (!hi_clipped && hi - ticks.values.back() > 0.2 * (hi - lo))
      svg += "<text class=\"tick end\" x=\"" + number("%.0f", x0 + bar_w) +
             "\" y=\"43\" font-size=\"10\" text-anchor=\"end\">" + end_label(hi) + "</text>";
  }
  if (hi_clipped && hi > lo)  // the top end of the scale is a clipping point, not the maximum
    svg += "<text x=\"" + number("%.0f", x0 + bar_w) + "\" y=\"11\" font-size=\"10\" text-anchor=\"end\">&#8805; " +
           escape_html(scale_label(hi, lo, hi)) + " shown as top</text>";
  return svg + "</svg>";
}

PlaneRange plane_range(const cv::Mat& plane) {
  std::vector<float> values;
  values.reserve(plane.total() * plane.channels());
  const cv::Mat flat = plane.reshape(1, 1);
  cv::Mat f;
  flat.convertTo(f, CV_32F);
  for (int i = 0; i < f.cols; ++i)
    if (std::isfinite(f.at<float>(0, i))) values.push_back(f.at<float>(0, i));
  PlaneRange r;
  if (values.empty()) return r;
  std::sort(values.begin(), values.end());
  r.any = true;
  r.min = values.front();
  r.max = values.back();
  r.p99 = values[std::min(values.size() - 1, static_cast<size_t>(0.99 * double(values.size())))];
  return r;
}

namespace {

/// "min 0.012, max 0.34 units" for a caption, to the precision of the range.
std::string range_text(const PlaneRange& r, const std::string& units) {
  if (!r.any) return "no finite values";
  return "range " + scale_label(r.min, r.min, r.max) + " to " + scale_label(r.max, r.min, r.max) +
         (units.empty() ? "" : " " + units);
}

/// A plane reduced to at most `width` columns (area average), or itself.
cv::Mat at_most(const cv::Mat& image, int width) {
  if (width <= 0 || image.cols <= width) return image;
  cv::Mat out;
  cv::resize(image, out, {width, std::max(1, int(std::lround(double(image.rows) * width / image.cols)))}, 0, 0,
             cv::INTER_AREA);
  return out;
}

std::string figure(const std::string& img, const std::string& label, const std::string& what, const std::string& range,
                   const std::string& bar) {
  return "<figure class=\"mapimage\">" + img + "<figcaption><b>" + escape_html(label) + "</b>" +
         (what.empty() ? "" : ": " + what) + "<br>" + range + (bar.empty() ? "" : "<br>" + bar) +
         "</figcaption></figure>";
}

}  // namespace

std::string false_colour(const cv::Mat& plane, const std::string& label, int width, const std::string& what,
                         const std::string& units) {
  const PlaneRange r = plane_range(plane);
  const double lo = r.min, hi = r.p99;
  const cv::Mat small = at_most(plane, width);
  const cv::Mat finite = small == small;  // not NaN
  cv::Mat scaled;
  small.convertTo(scaled, CV_8U, hi > lo ? 255.0 / (hi - lo) : 0.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  cv::Mat colours;
  cv::applyColorMap(scaled, colours, cv::COLORMAP_VIRIDIS);
  colours.setTo(cv::Scalar(128, 128, 128), ~finite);
  return figure(img_tag(colours, label, std::max(width, 1)), label, what, escape_html(range_text(r, units)),
                colour_bar(lo, hi, units, r.max > hi));
}

std::string colour_image(const cv::Mat& bgr, const std::string& label, int width, const std::string& what,
                         const std::string& units) {
  const PlaneRange r = plane_range(bgr);
  const double white = r.p99 > 0 ? r.p99 : (r.max > 0 ? r.max : 1.0);
  const cv::Mat small = at_most(bgr, width);
  cv::Mat out(small.size(), CV_8UC3);
  for (int y = 0; y < small.rows; ++y)
    for (int x = 0; x < small.cols; ++x) {
      const cv::Vec3f v = small.at<cv::Vec3f>(y, x);
      cv::Vec3b& o = out.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(v[c])) {
          o = cv::Vec3b(128, 128, 128);
          break;
        }
        // sRGB encoding of the linear value relative to the white point.
        const double l = std::clamp(double(v[c]) / white, 0.0, 1.0);
        const double e = l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
        o[c] = static_cast<uchar>(std::lround(255 * e));
      }
    }
  const std::string range =
      escape_html(range_text(r, units)) + "; white " + escape_html(significant(white, 3)) + " (99th percentile), sRGB";
  return figure(img_tag(out, label, std::max(width, 1)), label, what, range, "");
}

std::string polar_plot(const std::vector<PolarPoint>& points, const std::vector<Vec3d>& route, int size_px) {
  const double c = size_px / 2.0, r = size_px / 2.0 - 18;
  auto xy = [&](const Vec3d& d) {
    const double zenith = std::acos(std::clamp(d.z(), -1.0, 1.0));
    const double azimuth = std::atan2(d.y(), d.x());
    const double rho = r * zenith / (kPi / 2);
    return std::make_pair(c + rho * std::cos(azimuth), c - rho * std::sin(azimuth));
  };
  std::string svg = "<svg class=\"polar\" width=\"" + std::to_string(size_px) + "\" height=\"" +
                    std::to_string(size_px) + "\" viewBox=\"0 0 " + std::to_string(size_px) + " " +
                    std::to_string(size_px) + "\">";
  for (int ring = 1; ring <= 3; ++ring)
    svg += "<circle cx=\"" + number("%.1f", c) + "\" cy=\"" + number("%.1f", c) + "\" r=\"" +
           number("%.1f", r * ring / 3) + "\" fill=\"none\" stroke=\"#bbb\"/>";
  svg += "<line x1=\"" + number("%.1f", c - r) + "\" y1=\"" + number("%.1f", c) + "\" x2=\"" + number("%.1f", c + r) +
         "\" y2=\"" + number("%.1f", c) + "\" stroke=\"#ddd\"/><line x1=\"" + number("%.1f", c) + "\" y1=\"" +
         number("%.1f", c - r) + "\" x2=\"" + number("%.1f", c) + "\" y2=\"" + number("%.1f", c + r) +
         "\" stroke=\"#ddd\"/>";
  svg += "<text x=\"" + number("%.1f", c + r + 2) + "\" y=\"" + number("%.1f", c - 3) +
         "\" font-size=\"10\" text-anchor=\"end\">+x</text><text x=\"" + number("%.1f", c + 3) +
         "\" y=\"12\" "
         "font-size=\"10\">+y</text><text x=\"" +
         number("%.1f", c + r / 3 + 2) + "\" y=\"" + number("%.1f", c + 11) +
         "\" font-size=\"9\" fill=\"#888\">30&#176;</text><text x=\"" + number("%.1f", c + r + 2) + "\" y=\"" +
         number("%.1f", c + 11) + "\" font-size=\"9\" fill=\"#888\">90&#176;</text>";
  if (route.size() > 1) {
    svg +=
        "<polyline class=\"route\" fill=\"none\" stroke=\"#e07020\" stroke-width=\"1\" stroke-opacity=\"0.7\" "
        "points=\"";
    for (const Vec3d& d : route) {
      const auto [x, y] = xy(d);
      svg += number("%.1f", x) + "," + number("%.1f", y) + " ";
    }
    svg += "\"/>";
  }
  for (const PolarPoint& p : points) {
    const auto [x, y] = xy(p.direction);
    svg += "<circle cx=\"" + number("%.1f", x) + "\" cy=\"" + number("%.1f", y) + "\" r=\"" +
           number("%.1f", p.radius_px) + "\" fill=\"" + p.fill + "\" stroke=\"" + (p.fill == "none" ? "#888" : "#333") +
           "\" stroke-width=\"0.5\"><title>" + escape_html(p.title) + "</title></circle>";
    if (p.held_out)  // a ring around the point
      svg += "<circle class=\"mark-held-out\" cx=\"" + number("%.1f", x) + "\" cy=\"" + number("%.1f", y) + "\" r=\"" +
             number("%.1f", p.radius_px + 3) + "\" fill=\"none\" stroke=\"" + kHeldOutColour +
             "\" stroke-width=\"2\"><title>" + escape_html(p.title) + "</title></circle>";
    if (p.excluded) {  // crossed out
      const double a = p.radius_px + 2;
      svg += "<path class=\"mark-excluded\" d=\"M" + number("%.1f", x - a) + " " + number("%.1f", y - a) + "L" +
             number("%.1f", x + a) + " " + number("%.1f", y + a) + "M" + number("%.1f", x - a) + " " +
             number("%.1f", y + a) + "L" + number("%.1f", x + a) + " " + number("%.1f", y - a) + "\" stroke=\"" +
             kExcludedColour + "\" stroke-width=\"1.5\"><title>" + escape_html(p.title) + "</title></path>";
    }
  }
  return svg + "</svg>";
}

std::string polar_legend() {
  // The symbols as polar_plot draws them, each with its meaning.
  std::string svg = "<svg class=\"legend\" width=\"520\" height=\"22\" viewBox=\"0 0 520 22\">";
  svg += "<circle cx=\"10\" cy=\"11\" r=\"4\" fill=\"" + viridis(0.5) +
         "\" stroke=\"#333\" stroke-width=\"0.5\"/><text x=\"20\" y=\"15\" font-size=\"11\">captured</text>";
  svg +=
      "<circle cx=\"90\" cy=\"11\" r=\"4\" fill=\"none\" stroke=\"#888\" stroke-width=\"0.5\"/><text x=\"100\" "
      "y=\"15\" font-size=\"11\">not captured</text>";
  svg += "<circle cx=\"195\" cy=\"11\" r=\"4\" fill=\"" + viridis(0.5) +
         "\" stroke=\"#333\" stroke-width=\"0.5\"/><circle cx=\"195\" cy=\"11\" r=\"7\" fill=\"none\" stroke=\"" +
         kHeldOutColour + "\" stroke-width=\"2\"/><text x=\"208\" y=\"15\" font-size=\"11\">held out of a fit</text>";
  svg += "<circle cx=\"320\" cy=\"11\" r=\"4\" fill=\"" + viridis(0.5) +
         "\" stroke=\"#333\" stroke-width=\"0.5\"/><path d=\"M314 5L326 17M314 17L326 5\" stroke=\"" + kExcludedColour +
         "\" stroke-width=\"1.5\"/><text x=\"333\" y=\"15\" font-size=\"11\">excluded by the calibration</text>";
  return svg + "</svg>";
}

std::string section(const std::string& id, const std::string& title, const std::string& body) {
  return "<section id=\"" + id + "\">\n<h2>" + escape_html(title) + "</h2>\n" + body + "</section>\n";
}

}  // namespace vdrig::pipeline::html
