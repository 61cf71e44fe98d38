#include "html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

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

std::string img_tag(const cv::Mat& image, const std::string& alt) {
  auto png = encode_png(image, PngCompression::kFastest);
  if (!png) return missing(alt + " (" + png.error().message + ")");
  return "<img alt=\"" + escape_html(alt) + "\" width=\"" + std::to_string(image.cols) + "\" height=\"" +
         std::to_string(image.rows) + "\" src=\"data:image/png;base64," + base64(png.value()) + "\">";
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
  std::string svg =
      "<svg class=\"colourbar\" width=\"260\" height=\"42\" viewBox=\"0 0 260 42\"><defs><linearGradient "
      "id=\"" +
      gid + "\">";
  for (int k = 0; k <= 8; ++k)
    svg += "<stop offset=\"" + number("%.3f", k / 8.0) + "\" stop-color=\"" + viridis(k / 8.0) + "\"/>";
  svg += "</linearGradient></defs><text x=\"5\" y=\"11\" font-size=\"11\">" + escape_html(label) + "</text>";
  svg += "<rect x=\"5\" y=\"15\" width=\"250\" height=\"12\" fill=\"url(#" + gid + ")\"/>";
  svg += "<text x=\"5\" y=\"40\" font-size=\"11\">" + escape_html(scale_label(lo, lo, hi)) + "</text>";
  svg += "<text x=\"255\" y=\"40\" font-size=\"11\" text-anchor=\"end\">" + std::string(hi_clipped ? "&#8805; " : "") +
         escape_html(scale_label(hi, lo, hi)) + "</text>";
  return svg + "</svg>";
}

std::string false_colour(const cv::Mat& plane, const std::string& label, int min_width) {
  cv::Mat finite = plane == plane;  // not NaN
  std::vector<float> values;
  for (int y = 0; y < plane.rows; ++y)
    for (int x = 0; x < plane.cols; ++x)
      if (finite.at<uint8_t>(y, x)) values.push_back(plane.at<float>(y, x));
  double lo = 0, hi = 0, max = 0;
  if (!values.empty()) {
    std::sort(values.begin(), values.end());
    lo = values.front(), max = values.back();
    hi = values[std::min(values.size() - 1, static_cast<size_t>(0.99 * double(values.size())))];
  }
  cv::Mat scaled;
  plane.convertTo(scaled, CV_8U, hi > lo ? 255.0 / (hi - lo) : 0.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  cv::Mat colours;
  cv::applyColorMap(scaled, colours, cv::COLORMAP_VIRIDIS);
  colours.setTo(cv::Scalar(128, 128, 128), ~finite);
  const int factor = std::max(1, (min_width + plane.cols - 1) / plane.cols);
  cv::resize(colours, colours, {}, factor, factor, cv::INTER_NEAREST);
  return "<figure>" + img_tag(colours, label) + "<figcaption>" + colour_bar(lo, hi, label, max > hi) +
         "</figcaption></figure>";
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
  }
  return svg + "</svg>";
}

std::string section(const std::string& id, const std::string& title, const std::string& body) {
  return "<section id=\"" + id + "\">\n<h2>" + escape_html(title) + "</h2>\n" + body + "</section>\n";
}

}  // namespace vdrig::pipeline::html
