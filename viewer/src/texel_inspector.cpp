#include "vdrig/viewer/texel_inspector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"  // kCappedLobesChannel

namespace vdrig::viewer {
namespace {

std::string format_value(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string format_rgb(const Vec3d& v) {
  return format_value(v.x()) + " " + format_value(v.y()) + " " + format_value(v.z());
}

/// Diverging colour (BGR) for a residual in [-1, 1]: blue (model below the observation), white, red (above).
cv::Scalar residual_colour(double r) {
  r = std::clamp(r, -1.0, 1.0);
  const double a = std::abs(r);
  return r >= 0 ? cv::Scalar(255 * (1 - a), 255 * (1 - a), 255) : cv::Scalar(255, 255 * (1 - a), 255 * (1 - a));
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.45, cv::Scalar colour = {30, 30, 30}) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

}  // namespace

std::string capped_lobes_note(int capped_lobes) {
  return std::to_string(capped_lobes) + (capped_lobes == 1 ? " lobe" : " lobes") +
         " unsupported: m held at the sampling's bound, the width is a guess (the surface may be glossier)";
}

std::vector<int> held_out_views(const fitting::ParameterMap& map) {
  std::vector<int> views;
  const auto it = map.image().string_attributes.find("vdrig.held_out_views");
  if (it == map.image().string_attributes.end()) return views;
  std::stringstream in(it->second);
  std::string item;
  while (std::getline(in, item, ',')) {
    try {
      views.push_back(std::stoi(item));
    } catch (const std::exception&) {
      // A damaged attribute only loses the held-out marking, not the inspection.
    }
  }
  std::sort(views.begin(), views.end());
  return views;
}

TexelInspection inspect_texel(const fitting::ParameterMap& map, int s, int t, const fitting::TexelObservations& obs,
                              const std::vector<int>& held_out, const InspectOptions& options) {
  VDRIG_CHECK(s >= 0 && s < map.texels_s() && t >= 0 && t < map.texels_t(), "inspect_texel: texel outside the map");
  VDRIG_CHECK(options.curve_points >= 2, "inspect_texel: curve_points >= 2");
  TexelInspection r;
  r.s = s;
  r.t = t;
  r.model = map.model().name();
  const auto names = map.model().channels();
  const auto params = map.parameters(s, t);
  for (size_t i = 0; i < names.size(); ++i) r.parameters.emplace_back(names[i], params[i]);
  if (map.has("rms.R")) r.fit_rms = Vec3d(map.at("rms.R", s, t), map.at("rms.G", s, t), map.at("rms.B", s, t));
  if (map.has("n")) r.samples = static_cast<int>(map.at("n", s, t));
  if (map.has(fitting::kCappedLobesChannel))
    r.capped_lobes = static_cast<int>(map.at(fitting::kCappedLobesChannel, s, t));
  if (map.has("holdout.R"))
    r.holdout_rms = Vec3d(map.at("holdout.R", s, t), map.at("holdout.G", s, t), map.at("holdout.B", s, t));
  r.band_deg = options.band_deg;

  const Vec3d n = Vec3d::UnitZ();
  r.peak_direction = map.model().peak_direction(map.parameters(s, t));
  const Vec3d horizontal(r.peak_direction.x(), r.peak_direction.y(), 0.0);
  r.circle_u = horizontal.norm() > 1e-6 ? horizontal.normalized() : Vec3d::UnitX();
  for (int i = 0; i < options.curve_points; ++i) {
    const double a = -90.0 + 180.0 * i / (options.curve_points - 1);
    const Vec3d d = std::cos(deg_to_rad(a)) * n + std::sin(deg_to_rad(a)) * r.circle_u;
    r.curve_deg.push_back(a);
    r.curve.push_back(map.evaluate(s, t, d));
  }
  const Vec3d plane_normal = n.cross(r.circle_u);
  for (size_t i = 0; i < obs.size(); ++i) {
    InspectedObservation o;
    o.direction = obs.direction[i].cast<double>().normalized();
    o.observed = obs.radiance[i].cast<double>();
    o.model = map.evaluate(s, t, o.direction);
    o.view = obs.view[i];
    o.held_out = std::binary_search(held_out.begin(), held_out.end(), o.view);
    o.circle_deg = rad_to_deg(std::atan2(o.direction.dot(r.circle_u), o.direction.dot(n)));
    o.off_circle_deg = rad_to_deg(std::asin(std::clamp(std::abs(o.direction.dot(plane_normal)), 0.0, 1.0)));
    r.observations.push_back(o);
  }
  return r;
}

plot::Figure curve_figure(const TexelInspection& r) {
  constexpr plot::Rgb kChannel[3] = {{220, 40, 40}, {40, 160, 40}, {40, 60, 220}};  // R, G, B
  double y_max = 0;
  for (const auto& c : r.curve) y_max = std::max(y_max, c.maxCoeff());
  for (const auto& o : r.observations)
    if (o.off_circle_deg <= r.band_deg) y_max = std::max(y_max, o.observed.maxCoeff());
  plot::Figure f;
  f.title = "radiance along the great circle through n and the peak";
  f.x = plot::stepped_axis("angle from the normal, toward the peak (deg)", -90, 90, 30);
  f.y = plot::nice_axis("radiance (HDR units)", 0, y_max > 0 ? y_max : 1.0, 5);
  for (int c = 0; c < 3; ++c) {
    plot::Series model{c == 0 ? "model (R, G, B)" : "", kChannel[c], {}};
    for (size_t i = 0; i < r.curve.size(); ++i) model.points.emplace_back(r.curve_deg[i], r.curve[i][c]);
    f.series.push_back(model);
  }
  for (int c = 0; c < 3; ++c) {
    plot::Series seen{c == 0 ? "observed (within " + format_value(r.band_deg) + " deg)" : "", kChannel[c], {}};
    plot::Series held{c == 0 ? "held out" : "", kChannel[c], {}};
    seen.line = held.line = false;
    seen.marker = plot::Marker::kCircle;
    held.marker = plot::Marker::kCross;
    held.marker_px = 4;
    for (const auto& o : r.observations)
      if (o.off_circle_deg <= r.band_deg) (o.held_out ? held : seen).points.emplace_back(o.circle_deg, o.observed[c]);
    f.series.push_back(seen);
    if (!held.points.empty()) f.series.push_back(held);
  }
  return f;
}

cv::Mat plot_inspection(const TexelInspection& r, int width, int height) {
  VDRIG_CHECK(width >= 480 && height >= 270, "plot_inspection: the plot needs at least 480 x 270 pixels");
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(250, 250, 250));
  const int text_h = std::max(110, height / 4);
  const int plot_h = height - text_h;
  const int curve_w = width * 3 / 5;

  // --- Curve plot: radiance along the great circle, with the observations near it (plot.hpp) ---
  plot::draw(curve_figure(r), img, cv::Rect(0, 0, curve_w, plot_h));

  // --- Hemisphere: observations at (d.x, d.y), coloured by residual ---
  const int radius = std::min(width - curve_w - 40, plot_h - 70) / 2;
  const cv::Point centre(curve_w + (width - curve_w) / 2, 30 + radius + 10);
  cv::circle(img, centre, radius, cv::Scalar(120, 120, 120), 1, cv::LINE_AA);
  auto hemi_px = [&](const Vec3d& d) {
    return centre +
           cv::Point(static_cast<int>(std::lround(d.x() * radius)), static_cast<int>(std::lround(-d.y() * radius)));
  };
  cv::line(img, hemi_px(-r.circle_u), hemi_px(r.circle_u), cv::Scalar(170, 170, 170), 1, cv::LINE_AA);
  double scale = 0;
  for (const auto& o : r.observations) scale = std::max(scale, std::abs(o.residual()));
  if (scale <= 0) scale = 1;
  for (const auto& o : r.observations) {
    const cv::Point p = hemi_px(o.direction);
    cv::circle(img, p, 5, residual_colour(o.residual() / scale), cv::FILLED, cv::LINE_AA);
    cv::circle(img, p, 5, o.held_out ? cv::Scalar(0, 0, 0) : cv::Scalar(150, 150, 150), o.held_out ? 2 : 1,
               cv::LINE_AA);
  }
  cv::drawMarker(img, hemi_px(r.peak_direction), cv::Scalar(0, 140, 255), cv::MARKER_STAR, 12, 1);
  text(img, "observations (top view, +y up), model - observed:", cv::Point(curve_w + 10, 20), 0.42);
  text(img, "blue -" + format_value(scale) + "  white 0  red +" + format_value(scale) + "  * peak",
       cv::Point(curve_w + 10, centre.y + radius + 22), 0.4);

  // --- Text: texel, model, quality, parameters ---
  int y = plot_h + 16;
  text(img,
       "texel " + std::to_string(r.s) + "," + std::to_string(r.t) + "   " + r.model + "   n " +
           std::to_string(r.samples) + " fitted of " + std::to_string(r.observations.size()) + " observations",
       cv::Point(10, y), 0.45, cv::Scalar(0, 0, 0));
  y += 18;
  text(img,
       "RMS R G B: fit " + format_rgb(r.fit_rms) + "   held out " +
           (r.holdout_rms ? format_rgb(*r.holdout_rms) : std::string("- (no views held out)")),
       cv::Point(10, y), 0.45, cv::Scalar(0, 0, 0));
  if (r.capped_lobes && *r.capped_lobes > 0) {
    y += 18;
    text(img, capped_lobes_note(*r.capped_lobes), cv::Point(10, y), 0.45, cv::Scalar(0, 0, 200));
  }
  std::string line;
  // Parameters in lines of at most chars_per_line characters; as many lines as fit, the last one saying how many
  // parameters did not.
  const int chars_per_line = std::max(20, width / 8);
  std::vector<std::string> lines;
  std::vector<size_t> shown_after;  // parameters shown up to and including each line
  for (size_t i = 0; i < r.parameters.size(); ++i) {
    const std::string item = r.parameters[i].first + " " + format_value(r.parameters[i].second) + "   ";
    if (lines.empty() || static_cast<int>(lines.back().size() + item.size()) > chars_per_line) {
      lines.emplace_back();
      shown_after.push_back(0);
    }
    lines.back() += item;
    shown_after.back() = i + 1;
  }
  const size_t fit = static_cast<size_t>(std::max(0, (height - 8 - y) / 18));
  for (size_t k = 0; k < std::min(fit, lines.size()); ++k) {
    std::string l = lines[k];
    if (k + 1 == fit && k + 1 < lines.size())
      l += "... (" + std::to_string(r.parameters.size() - shown_after[k]) + " more)";
    y += 18;
    text(img, l, cv::Point(10, y), 0.4);
  }
  return img;
}

std::optional<std::pair<int, int>> pick_texel(const CameraModel& camera, const ViewPose& pose,
                                              const fitting::ParameterMap& map, const Vec2d& pixel) {
  const Vec3d ray = pose.R.transpose() * camera.pixel_ray(pixel);
  const Vec3d c = pose.camera_centre();
  if (std::abs(ray.z()) < 1e-12) return std::nullopt;
  const double along = -c.z() / ray.z();
  if (along <= 0) return std::nullopt;
  const Vec3d p = c + along * ray;
  const double u = (p.x() + 0.5 * map.width_mm()) / map.width_mm();
  const double v = (p.y() + 0.5 * map.height_mm()) / map.height_mm();
  if (u < 0 || u >= 1 || v < 0 || v >= 1) return std::nullopt;
  return std::make_pair(std::min(map.texels_s() - 1, static_cast<int>(u * map.texels_s())),
                        std::min(map.texels_t() - 1, static_cast<int>(v * map.texels_t())));
}

}  // namespace vdrig::viewer
