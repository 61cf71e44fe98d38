#include "vdrig/pipeline/report.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "html.hpp"
#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/capture/session.hpp"
#include "vdrig/core/camera.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/pipeline/compare_stage.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/viewer/surface_renderer.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;
namespace plot = viewer::plot;
namespace {

using html::colour_bar;
using html::false_colour;
using html::img_tag;
using html::missing;
using html::polar_plot;
using html::PolarPoint;
using html::section;
using html::viridis;

// ---- Sections ----

/// What the report shows of one view's merged HDR image.
struct ViewHdr {
  double clipped_fraction = -1.0;  // -1 not merged, -2 unreadable
  cv::Mat thumbnail;               // tone mapped, 8-bit BGR; empty when not merged
};

struct ReportData {
  const capture::Session* session = nullptr;
  const ReportOptions* options = nullptr;
  std::vector<fs::path> map_files;      // SESSION/maps/*.exr, sorted
  std::vector<ViewHdr> hdr;             // per planned view, in manifest order
  std::map<int, std::string> held_out;  // view -> the maps that held it out of their fit ("phong:1.exr, hsh:6.exr")
  std::map<int, std::string> excluded;  // view -> why the calibration (calib/views.json) left it out
};

/// Every merged view read once, in parallel (the slowest part of the report): the share of its pixels clipped in
/// every exposure, and a thumbnail through the display tone mapping of vdrig compare and the viewer (gamma 1).
std::vector<ViewHdr> read_view_hdrs(const capture::Session& s, int thumbnail_width_px) {
  const auto& planned = s.manifest().views;
  std::vector<ViewHdr> out(planned.size());
  cv::parallel_for_(cv::Range(0, static_cast<int>(planned.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      const int v = planned[i].index;
      if (!s.view_complete(v) || !fs::exists(s.layout().hdr_file(v))) continue;
      auto hdr = calib::read_hdr_exr(s.layout().hdr_file(v));
      if (!hdr || hdr->mask.empty() || hdr->radiance.empty()) {
        out[i].clipped_fraction = -2.0;
        continue;
      }
      out[i].clipped_fraction = cv::countNonZero(hdr->mask & calib::kHdrSaturated) / double(hdr->mask.total());
      if (thumbnail_width_px > 0 && hdr->radiance.type() == CV_32FC3) {
        cv::Mat small;
        const double scale = double(thumbnail_width_px) / hdr->radiance.cols;
        cv::resize(hdr->radiance, small, {}, scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_NEAREST);
        out[i].thumbnail = viewer::tone_map(small, 1.0);
      }
    }
  });
  return out;
}

/// The views each map held out of its fit (vdrig.held_out_views), as view -> "map, map".
std::map<int, std::string> held_out_by_maps(const std::vector<fs::path>& map_files) {
  std::map<int, std::string> held;
  for (const fs::path& file : map_files) {
    auto image = read_exr(file, fitting::ParameterMap::kMaxReadBytes);
    if (!image) continue;
    const auto it = image->string_attributes.find("vdrig.held_out_views");
    if (it == image->string_attributes.end()) continue;
    const std::string& list = it->second;
    for (size_t at = 0; at < list.size();) {
      char* end = nullptr;
      const long view = std::strtol(list.c_str() + at, &end, 10);
      if (end == list.c_str() + at) break;  // not a number: the rest is not read
      std::string& maps = held[static_cast<int>(view)];
      maps += (maps.empty() ? "" : ", ") + file.filename().string();
      at = static_cast<size_t>(end - list.c_str());
      while (at < list.size() && (list[at] == ',' || list[at] == ' ')) ++at;
    }
  }
  return held;
}

/// The views calib/views.json leaves out of the fit (no pose, or a reprojection error above its threshold) and why;
/// none when there is no readable calibration.
std::map<int, std::string> excluded_by_calibration(const capture::SessionLayout& layout) {
  std::map<int, std::string> excluded;
  if (!fs::exists(layout.views_file())) return excluded;
  auto views = calib::read_views_json(layout.views_file());
  if (!views) return excluded;
  for (const calib::ViewRecord& v : views->views)
    if (!v.usable())
      excluded[v.index] = v.extrinsics ? "marker reprojection error " +
                                             html::significant(v.extrinsics->reprojection_error_px, 3) + " px > " +
                                             html::significant(views->max_error_px, 3) + " px"
                                       : "no pose: " + v.error;
  return excluded;
}

/// Views in the order they were captured (by the sequence number of their first journaled frame).
std::vector<int> capture_order(const capture::Session& session) {
  std::map<uint64_t, int> first;
  std::set<int> seen;
  for (const capture::FrameRecord& f : session.frames())
    if (session.view_complete(f.view) && seen.insert(f.view).second) first[f.sequence] = f.view;
  std::vector<int> order;
  for (const auto& [sequence, view] : first) order.push_back(view);
  return order;
}

std::string coverage_section(const ReportData& d) {
  const capture::Manifest& m = d.session->manifest();
  const std::vector<int> order = capture_order(*d.session);
  std::vector<int> rank(m.views.size(), -1);
  for (size_t i = 0; i < order.size(); ++i)
    if (order[i] >= 0 && order[i] < int(rank.size())) rank[order[i]] = int(i);
  std::vector<PolarPoint> points;
  std::vector<Vec3d> route;
  for (const capture::PlannedView& v : m.views) {
    route.push_back(v.direction);
    const int k = v.index >= 0 && v.index < int(rank.size()) ? rank[v.index] : -1;
    const double zenith_deg = std::acos(std::clamp(v.direction.z(), -1.0, 1.0)) * 180 / kPi;
    const double azimuth_deg = std::atan2(v.direction.y(), v.direction.x()) * 180 / kPi;
    std::string title = "view " + std::to_string(v.index) + ": azimuth " + html::number("%.1f", azimuth_deg) +
                        " deg, zenith " + html::number("%.1f", zenith_deg) + " deg, ";
    title += k >= 0 ? "captured " + std::to_string(k + 1) + "th" : "not captured";
    const auto held = d.held_out.find(v.index);
    const auto excluded = d.excluded.find(v.index);
    if (held != d.held_out.end()) title += "; held out of " + held->second;
    if (excluded != d.excluded.end()) title += "; excluded: " + excluded->second;
    points.push_back({v.direction, k >= 0 ? viridis(order.size() > 1 ? double(k) / (order.size() - 1) : 0.0) : "none",
                      4.0, title, held != d.held_out.end(), excluded != d.excluded.end()});
  }
  std::string body = "<p>Scheme <code>" + escape_html(m.scheme) + "</code>: " + std::to_string(order.size()) + " of " +
                     std::to_string(m.views.size()) +
                     " planned views captured. Seen from above: the centre is the surface normal, the rim 90&#176; "
                     "from it; the orange line is the planned route, filled points the captured views coloured by "
                     "capture order, hollow points views not captured.</p>\n";
  body += "<figure>" + polar_plot(points, route) + "<figcaption>" +
          colour_bar(1, std::max<double>(1, order.size()), "capture order") + "<br>" + html::polar_legend() + "<br>" +
          std::to_string(d.held_out.size()) + " views held out of a fit (ringed), " +
          std::to_string(d.excluded.size()) + " excluded by the calibration (crossed out)</figcaption></figure>\n";
  if (order.size() < m.views.size())
    body += missing(std::to_string(m.views.size() - order.size()) +
                    " planned views are not captured (resume with vdrig capture or vdrigd)");
  return section("coverage", "Coverage of the hemisphere", body);
}

/// The merged views as small tone-mapped thumbnails (JPEG: photographs), each labelled with its view number; views held
/// out of a fit framed in red, views the calibration excluded dimmed with a dashed frame.
std::string thumbnail_grid(const ReportData& d) {
  const auto& planned = d.session->manifest().views;
  std::string grid;
  int shown = 0;
  for (size_t i = 0; i < planned.size() && i < d.hdr.size(); ++i) {
    if (d.hdr[i].thumbnail.empty()) continue;
    const int v = planned[i].index;
    const auto held = d.held_out.find(v);
    const auto excluded = d.excluded.find(v);
    std::string cls = "thumb", title = "view " + std::to_string(v), label = std::to_string(v);
    if (held != d.held_out.end()) {
      cls += " held-out";
      title += ", held out of " + held->second;
      label += " held out";
    }
    if (excluded != d.excluded.end()) {
      cls += " excluded";
      title += ", excluded: " + excluded->second;
      label += " excluded";
    }
    grid += "<figure class=\"" + cls + "\" title=\"" + escape_html(title) + "\">" +
            img_tag(d.hdr[i].thumbnail, "view " + std::to_string(v), 0, 80) + "<figcaption>" + escape_html(label) +
            "</figcaption></figure>";
    ++shown;
  }
  if (shown == 0) return "";
  return "<p>The " + std::to_string(shown) +
         " merged views, tone mapped as vdrig compare shows them (y = 1 &#8722; exp(&#8722;x), sRGB), in view order. "
         "<span class=\"key held-out\">held out</span> of a fit (" +
         std::to_string(d.held_out.size()) + "), <span class=\"key excluded\">excluded</span> by the calibration (" +
         std::to_string(d.excluded.size()) + ").</p>\n<div class=\"thumbs\">" + grid + "</div>\n";
}

std::string views_section(const ReportData& d) {
  const capture::Session& s = *d.session;
  int64_t t0 = 0;
  for (const auto& f : s.frames())
    if (t0 == 0 || (f.timestamp_ns > 0 && f.timestamp_ns < t0)) t0 = f.timestamp_ns;
  std::string rows;
  int merged = 0, clipped_views = 0;
  const auto& planned = s.manifest().views;
  std::vector<double> clipped_fraction(planned.size(), -1.0);
  for (size_t i = 0; i < planned.size() && i < d.hdr.size(); ++i) clipped_fraction[i] = d.hdr[i].clipped_fraction;
  for (size_t i = 0; i < planned.size(); ++i) {
    const capture::PlannedView& v = planned[i];
    const auto frames = s.frames_of_view(v.index);
    std::string exposures;
    int n_saturated = 0;
    int64_t first = 0, last = 0;
    for (const auto& f : frames) {
      exposures += (exposures.empty() ? "" : ", ") + html::number("%.4g", f.exposure_s * 1000.0);
      n_saturated += f.saturated;
      first = first == 0 ? f.timestamp_ns : std::min(first, f.timestamp_ns);
      last = std::max(last, f.timestamp_ns);
    }
    std::string clipped = "&#8211;";
    if (clipped_fraction[i] >= 0) {
      ++merged;
      clipped_views += clipped_fraction[i] > 0;
      clipped = html::number("%.3f", 100.0 * clipped_fraction[i]);
    } else if (clipped_fraction[i] == -2.0) {
      clipped = "unreadable";
    }
    rows += "<tr" + std::string(s.view_complete(v.index) ? "" : " class=\"incomplete\"") + "><td>" +
            std::to_string(v.index) + "</td><td>" +
            html::number("%.1f", std::atan2(v.direction.y(), v.direction.x()) * 180 / kPi) + "</td><td>" +
            html::number("%.1f", std::acos(std::clamp(v.direction.z(), -1.0, 1.0)) * 180 / kPi) + "</td><td>" +
            (exposures.empty() ? "not captured" : exposures) + "</td><td>" +
            (frames.empty() ? "" : std::to_string(n_saturated) + " of " + std::to_string(frames.size())) + "</td><td>" +
            clipped + "</td><td>" + (frames.empty() ? "" : html::number("%.2f", (first - t0) * 1e-9)) + "</td><td>" +
            (frames.empty() ? "" : html::number("%.3f", (last - first) * 1e-9)) + "</td></tr>\n";
  }
  std::string body = "<p>Bracket <code>" + escape_html(s.manifest().bracket) +
                     "</code>. <em>Saturated frames</em>: frames of the bracket with a pixel at the maximum code; "
                     "<em>clipped</em>: share of the merged HDR pixels saturated in every exposure (their radiance is "
                     "a lower bound). Times from the journal, relative to the first frame.</p>\n";
  if (merged == 0)
    body += missing("merged HDR views (run vdrig hdr " + escape_html(s.dir().string()) + "): no clipped fractions");
  else
    body += "<p>" + std::to_string(clipped_views) + " of " + std::to_string(merged) +
            " merged views have clipped pixels.</p>\n";
  body += thumbnail_grid(d);
  body +=
      "<div class=\"scroll\"><table><thead><tr><th>view</th><th>azimuth &#176;</th><th>zenith &#176;</th>"
      "<th>exposures ms</th><th>saturated frames</th><th>clipped %</th><th>start s</th><th>duration s</th>"
      "</tr></thead><tbody>\n" +
      rows + "</tbody></table></div>\n";
  return section("views", "Views: brackets, saturation, capture time", body);
}

/// Per-view marker reprojection error as bars: the y scale fitted to the errors of the views the calibration kept
/// (a threshold of 1 px would flatten errors of 0.02 px), its ticks at round values; a bar above the scale (an
/// excluded view) clipped with a triangle on top; a view without a pose a cross under the axis. View numbers label
/// the x axis, as many as fit.
std::string reprojection_chart(const calib::ViewsFile& views) {
  const int n = static_cast<int>(views.views.size());
  double kept_max = 0, all_max = 0;
  int usable = 0, posed = 0;
  for (const auto& v : views.views)
    if (v.extrinsics) {
      ++posed;
      all_max = std::max(all_max, v.extrinsics->reprojection_error_px);
      if (v.usable()) ++usable, kept_max = std::max(kept_max, v.extrinsics->reprojection_error_px);
    }
  double top = usable > 0 ? kept_max : all_max;
  if (!(top > 0)) top = views.max_error_px > 0 ? views.max_error_px : 1.0;
  html::Ticks ticks = html::nice_ticks(0, top, 5);
  const double y_max = std::ceil(top / ticks.step - 1e-9) * ticks.step;
  if (ticks.values.empty() || ticks.values.back() < y_max - 1e-9 * y_max) ticks.values.push_back(y_max);

  constexpr double left = 58, right = 12, top_px = 14, plot_h = 150, bottom = 44;
  const double width = std::clamp(left + right + 24.0 * n, 420.0, 1180.0);  // at most 1180: the page is 1280 wide
  const double height = top_px + plot_h + bottom;
  const double bar = (width - left - right) / std::max(1, n);
  const auto y_of = [&](double e) { return top_px + plot_h * (1 - std::min(e, y_max) / y_max); };
  const auto f1 = [](double x) { return html::number("%.1f", x); };
  std::string svg = "<svg class=\"bars\" width=\"" + html::number("%.0f", width) + "\" height=\"" +
                    html::number("%.0f", height) + "\" viewBox=\"0 0 " + html::number("%.0f", width) + " " +
                    html::number("%.0f", height) + "\">";
  // Y axis: grid lines and labels at the ticks, the axis title turned along it.
  for (double t : ticks.values)
    svg += "<line x1=\"" + f1(left) + "\" x2=\"" + f1(width - right) + "\" y1=\"" + f1(y_of(t)) + "\" y2=\"" +
           f1(y_of(t)) + "\" stroke=\"#e4e4e4\"/><text class=\"tick y\" x=\"" + f1(left - 4) + "\" y=\"" +
           f1(y_of(t) + 3.5) + "\" font-size=\"10\" text-anchor=\"end\">" + html::tick_label(t, ticks.step) + "</text>";
  svg += "<text x=\"12\" y=\"" + f1(top_px + plot_h / 2) +
         "\" font-size=\"11\" text-anchor=\"middle\" transform=\"rotate(-90 12 " + f1(top_px + plot_h / 2) +
         ")\">reprojection error, px</text>";
  // X axis labels: every k-th view number, k the smallest of 1, 2, 5, 10, ... leaving 22 px per label.
  int every = 1;
  for (int k : {1, 2, 5, 10, 20, 50, 100, 200, 500, 1000}) {
    every = k;
    if (k * bar >= 22) break;
  }
  for (int i = 0; i < n; ++i) {
    const auto& v = views.views[i];
    const double x = left + i * bar;
    const std::string title = "view " + std::to_string(v.index) + ": ";
    if (v.extrinsics) {
      const double e = v.extrinsics->reprojection_error_px;
      svg += "<rect class=\"" + std::string(v.extrinsics->excluded ? "bar excluded" : "bar") + "\" x=\"" + f1(x) +
             "\" y=\"" + f1(y_of(e)) + "\" width=\"" + html::number("%.2f", std::max(1.0, bar - 1)) + "\" height=\"" +
             f1(top_px + plot_h - y_of(e)) + "\" fill=\"" + (v.extrinsics->excluded ? "#d04040" : "#4070c0") +
             "\"><title>" + title + html::significant(e, 3) + " px" + (v.extrinsics->excluded ? " (excluded)" : "") +
             "</title></rect>";
      if (e > y_max)  // above the scale: a triangle on the clipped bar
        svg += "<path class=\"clipped\" d=\"M" + f1(x + bar / 2 - 4) + " " + f1(top_px + 6) + "L" + f1(x + bar / 2) +
               " " + f1(top_px - 2) + "L" + f1(x + bar / 2 + 4) + " " + f1(top_px + 6) +
               "Z\" fill=\"#d04040\"><title>" + title + html::significant(e, 3) + " px, above the scale</title></path>";
    } else {
      const double cx = x + bar / 2, cy = top_px + plot_h + 5;
      svg += "<path class=\"no-pose\" d=\"M" + f1(cx - 3) + " " + f1(cy - 3) + "L" + f1(cx + 3) + " " + f1(cy + 3) +
             "M" + f1(cx - 3) + " " + f1(cy + 3) + "L" + f1(cx + 3) + " " + f1(cy - 3) +
             "\" stroke=\"#d04040\" stroke-width=\"1.5\"><title>" + title + escape_html(v.error) + "</title></path>";
    }
    if (v.index % every == 0)
      svg += "<text class=\"tick x\" x=\"" + f1(x + bar / 2) + "\" y=\"" + f1(top_px + plot_h + 20) +
             "\" font-size=\"10\" text-anchor=\"middle\">" + std::to_string(v.index) + "</text>";
  }
  svg += "<line x1=\"" + f1(left) + "\" x2=\"" + f1(width - right) + "\" y1=\"" + f1(top_px + plot_h) + "\" y2=\"" +
         f1(top_px + plot_h) + "\" stroke=\"#333\"/><line x1=\"" + f1(left) + "\" x2=\"" + f1(left) + "\" y1=\"" +
         f1(top_px) + "\" y2=\"" + f1(top_px + plot_h) + "\" stroke=\"#333\"/>";
  svg += "<text x=\"" + f1(left + (width - left - right) / 2) + "\" y=\"" + f1(height - 6) +
         "\" font-size=\"11\" text-anchor=\"middle\">view</text>";
  const bool threshold_shown = views.max_error_px <= y_max;
  if (threshold_shown)
    svg += "<line class=\"threshold\" x1=\"" + f1(left) + "\" x2=\"" + f1(width - right) + "\" y1=\"" +
           f1(y_of(views.max_error_px)) + "\" y2=\"" + f1(y_of(views.max_error_px)) +
           "\" stroke=\"#d04040\" stroke-dasharray=\"4 3\"/>";
  svg += "</svg>";
  std::string text = "<p>Marker reprojection error per view (RMS over the corner markers, px), " +
                     std::to_string(usable) + " of " + std::to_string(n) + " views usable, " +
                     std::to_string(n - posed) + " without a pose (red crosses under the axis). Blue: kept; red: " +
                     "excluded, its error above the threshold of " + html::significant(views.max_error_px, 3) + " px";
  text += threshold_shown ? " (dashed line)"
                          : ", far above this scale (kept views at most " + html::significant(kept_max, 3) + " px)";
  if (all_max > y_max) text += "; bars above the scale end in a triangle";
  return text + ".</p>\n<figure class=\"wide\">" + svg + "</figure>\n";
}

std::string calibration_section(const ReportData& d) {
  const capture::SessionLayout layout = d.session->layout();
  std::string body;
  if (!fs::exists(layout.camera_file())) {
    body += missing("calib/camera.yml (intrinsics: vdrig calib intrinsics, then vdrig calib extrinsics " +
                    escape_html(d.session->dir().string()) + "); the stages after HDR need it");
  } else if (auto camera = CameraModel::load_yaml(layout.camera_file()); !camera) {
    body += missing("a readable calib/camera.yml: " + escape_html(camera.error().message));
  } else {
    double rms = -1;
    try {
      cv::FileStorage fs(layout.camera_file().string(), cv::FileStorage::READ);
      if (!fs["avg_reprojection_error"].empty()) fs["avg_reprojection_error"] >> rms;
    } catch (const cv::Exception&) {
    }
    const CameraModel& c = camera.value();
    body +=
        "<table><tr><th>image</th><th>fx</th><th>fy</th><th>cx</th><th>cy</th><th>k1</th><th>k2</th><th>p1</th>"
        "<th>p2</th><th>k3</th><th>RMS reprojection px</th></tr><tr><td>" +
        std::to_string(c.width) + "x" + std::to_string(c.height) + "</td>";
    for (double x : {c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2, c.k3})
      body += "<td>" + html::number("%.5g", x) + "</td>";
    body += "<td>" + (rms >= 0 ? html::number("%.4f", rms) : std::string("not recorded")) + "</td></tr></table>\n";
  }
  if (!fs::exists(layout.views_file())) {
    body += missing("calib/views.json (per-view marker poses and the kinematic fit: vdrig calib extrinsics " +
                    escape_html(d.session->dir().string()) + ")");
    return section("calibration", "Calibration", body);
  }
  auto views = calib::read_views_json(layout.views_file());
  if (!views) {
    body += missing("a readable calib/views.json: " + escape_html(views.error().message));
    return section("calibration", "Calibration", body);
  }
  body += reprojection_chart(views.value());
  if (views->kinematics.is_null()) {
    body += missing("the kinematic fit (fewer than two usable views)");
  } else {
    body += "<p>Kinematic fit of the rig (± standard deviation):</p><table>";
    const nlohmann::json& sigma = views->kinematics.contains("sigma") ? views->kinematics["sigma"] : nlohmann::json();
    for (const auto& [key, value] : views->kinematics.items())
      if (!value.is_array() && !value.is_object()) {
        // Numbers to the precision their standard deviation gives them, not as JSON prints doubles
        // ("2.2193484540451628e-05 ± 0.00051" is "0.00002 ± 0.00051").
        std::string cell = value.is_number() ? html::significant(value.get<double>(), 4) : value.dump();
        if (value.is_number() && sigma.is_object() && sigma.contains(key) && sigma[key].is_number())
          cell = html::with_uncertainty(value.get<double>(), sigma[key].get<double>());
        body += "<tr><th>" + escape_html(key) + "</th><td>" + escape_html(cell) + "</td></tr>";
      }
    body += "</table>\n";
  }
  return section("calibration", "Calibration", body);
}

/// Channels r, g, b of a map image as one BGR image (CV_32FC3), or an empty Mat when one is absent.
cv::Mat bgr_of(const ExrImage& image, const std::string& r, const std::string& g, const std::string& b) {
  std::vector<cv::Mat> planes;
  for (const std::string& name : {b, g, r}) {
    const int i = image.find(name);
    if (i < 0) return {};
    planes.push_back(image.channels[i]);
  }
  cv::Mat out;
  cv::merge(planes, out);
  return out;
}

// Map values are in the units of the HDR images the observations came from (linear, relative radiance).
constexpr const char* kRadiance = "radiance (HDR units)";

/// The mean of channels before + R/G/B + after (e.g. "sh." "R" ".01"), or an empty Mat when one is absent.
cv::Mat rgb_mean_of(const ExrImage& image, const std::string& before, const std::string& after) {
  cv::Mat sum;
  for (const char* c : {"R", "G", "B"}) {
    const int i = image.find(before + c + after);
    if (i < 0) return {};
    sum = sum.empty() ? image.channels[i].clone() : cv::Mat(sum + image.channels[i]);
  }
  return sum / 3.0;
}

/// Images of a map's parameters, by the channel names of the models (fitting/*_model.cpp): Phong's kd, and ks and m of
/// every lobe; SH/HSH's coefficient 0 as colour and coefficients 1 to 3 (mean of R, G, B) in false colour; PTM's
/// constant term as colour and its two linear terms. Channels of a model not known here are not shown.
std::string parameter_images(const ExrImage& image, int width) {
  std::string out;
  const auto colour = [&](const cv::Mat& bgr, const std::string& label, const std::string& what) {
    if (!bgr.empty()) out += html::colour_image(bgr, label, width, what, kRadiance);
  };
  const auto plane = [&](const cv::Mat& values, const std::string& label, const std::string& what,
                         const std::string& units) {
    if (!values.empty()) out += false_colour(values, label, width, what, units);
  };
  const auto channel = [&](const std::string& name) {
    const int i = image.find(name);
    return i < 0 ? cv::Mat() : image.channels[i];
  };
  colour(bgr_of(image, "kd.R", "kd.G", "kd.B"), "kd", "diffuse colour (R, G, B)");
  for (int k = 0; k < 16; ++k) {
    const std::string n = std::to_string(k);
    colour(bgr_of(image, "ks" + n + ".R", "ks" + n + ".G", "ks" + n + ".B"), "ks" + n,
           "specular colour of lobe " + n + " (R, G, B)");
    plane(channel("m" + n), "m" + n, "shininess of lobe " + n + " (Phong exponent)", "unitless");
  }
  plane(channel("m"), "m", "shininess shared by the lobes (Phong exponent)", "unitless");
  for (const std::string prefix : {"sh.", "hsh."}) {
    const std::string name = prefix == "sh." ? "SH" : "HSH";
    colour(bgr_of(image, prefix + "R.00", prefix + "G.00", prefix + "B.00"), name + " coefficient 0",
           "the constant term (R, G, B)");
    for (int i = 1; i <= 3; ++i)
      plane(rgb_mean_of(image, prefix, ".0" + std::to_string(i)), name + " coefficient " + std::to_string(i),
            "first band, mean of R, G, B", kRadiance);
  }
  // PTM terms (ptm_basis): 0 lu^2, 1 lv^2, 2 lu lv, 3 lu, 4 lv, 5 the constant (the radiance toward the normal).
  colour(bgr_of(image, "ptm.R.5", "ptm.G.5", "ptm.B.5"), "PTM term 5",
         "the constant term (R, G, B): the radiance toward the normal");
  if (const cv::Mat luminance = channel("ptm.L.5"), chroma = bgr_of(image, "chroma.R", "chroma.G", "chroma.B");
      !luminance.empty() && !chroma.empty()) {
    std::vector<cv::Mat> planes;
    cv::split(chroma, planes);
    for (cv::Mat& p : planes) p = p.mul(luminance);
    cv::Mat c;
    cv::merge(planes, c);
    colour(c, "PTM term 5 x chroma", "the luminance's constant term times the chroma: the radiance toward the normal");
  }
  for (const auto& [term, axis] : {std::pair{"3", "lu"}, std::pair{"4", "lv"}}) {
    cv::Mat c = rgb_mean_of(image, "ptm.", std::string(".") + term);
    const bool lrgb = c.empty();
    if (lrgb) c = channel(std::string("ptm.L.") + term);
    plane(
        c, std::string("PTM term ") + term,
        std::string("linear in ") + axis + " (the tilt of the radiance)" + (lrgb ? ", luminance" : ", mean of R, G, B"),
        kRadiance);
  }
  return out;
}

std::string maps_section(const ReportData& d) {
  std::string body;
  if (d.map_files.empty())
    return section("maps", "Fitted maps",
                   missing("fitted maps in maps/ (vdrig fit " + escape_html(d.session->dir().string()) +
                           " --model phong:1 --holdout 3)"));
  for (const fs::path& file : d.map_files) {
    body += "<article class=\"map\"><h3>" + escape_html(file.filename().string()) + "</h3>\n";
    auto image = read_exr(file, fitting::ParameterMap::kMaxReadBytes);
    if (!image) {
      body += missing("a readable map: " + escape_html(image.error().message)) + "</article>\n";
      continue;
    }
    const auto& attrs = image->string_attributes;
    // Escaped text, or a dash (markup, not escaped again: it once showed as a literal "&#8211;").
    const auto attr = [&](const std::string& k) {
      return attrs.count(k) && !attrs.at(k).empty() ? escape_html(attrs.at(k)) : std::string("&#8211;");
    };
    body += "<p>Model <code>" + attr("vdrig.model_spec") + "</code>, " + std::to_string(image->width) + "x" +
            std::to_string(image->height) + " texels; held-out views: " + attr("vdrig.held_out_views") +
            ".</p>\n<h4>Parameters</h4><div class=\"row\">";
    const std::string parameters = parameter_images(*image, d.options->map_image_px);
    body += (parameters.empty() ? "<p>(no images for this model's parameters)</p>" : parameters) +
            "</div>\n<h4>Fit quality</h4><div class=\"row\">";
    const cv::Mat rms = rgb_mean_of(*image, "rms.", "");
    if (!rms.empty())
      body += false_colour(rms, "fit residual RMS", d.options->map_image_px,
                           "root mean square of model &#8722; observation over the fitted views, mean of R, G, B",
                           kRadiance);
    const cv::Mat holdout = rgb_mean_of(*image, "holdout.", "");
    if (!holdout.empty())
      body += false_colour(holdout, "held-out RMS", d.options->map_image_px,
                           "root mean square of model &#8722; observation over the held-out views, mean of R, G, B",
                           kRadiance);
    if (const int lobes = image->find("lobes"); lobes >= 0)
      body += false_colour(image->channels[lobes], "lobes", d.options->map_image_px, "lobes the fit chose (phong:auto)",
                           "lobes");
    // Where the map guesses: lobes whose width the sampling bounds (docs/models.md, "Between the samples").
    int capped_texels = 0;
    if (const int capped = image->find(fitting::kCappedLobesChannel); capped >= 0) {
      capped_texels = cv::countNonZero(image->channels[capped] > 0.0f);
      if (capped_texels > 0)
        body += false_colour(image->channels[capped], "m_capped", d.options->map_image_px,
                             "lobes whose shininess is held at the sampling's bound", "lobes");
    }
    body += "</div>\n";
    if (capped_texels > 0)
      body += "<p>" + std::to_string(capped_texels) + " of " + std::to_string(image->width * image->height) +
              " texels have a lobe narrower than the views can resolve: its shininess is held at the sampling's "
              "bound, so the surface may be glossier there than the map shows (docs/models.md).</p>\n";
    if (rms.empty()) body += missing("the fit residual channels rms.R/G/B");
    if (holdout.empty()) body += missing("held-out error: fitted without --holdout");
    body += "</article>\n";
  }
  return section("maps", "Fitted maps", body);
}

/// The maps' error against the simulator's truth, the figures `vdrig eval MAP --scene SCENE --session S` prints: only
/// for a session the simulator captured from a scene it knows (simulated_scene_of), and only through eval_stage
/// (evaluate_map), the one part of the pipeline that reads the truth; no other section uses it. A real rig's
/// session has no truth, and the section says so.
std::string eval_section(const ReportData& d) {
  const std::string title = "Error against the simulator's truth";
  const capture::Session& s = *d.session;
  const std::optional<sim::Scene> scene = simulated_scene_of(s.manifest().rig_config);
  if (!scene)
    return section("eval", title,
                   "<p>No truth to compare with: the session was not captured by the simulator from a scene it knows "
                   "(a real rig's session is judged by its held-out error and <code>vdrig compare</code>).</p>\n");
  if (d.options->eval_directions <= 0)
    return section("eval", title, "<p>Not evaluated (the report was asked for no dense directions).</p>\n");
  if (d.map_files.empty()) return section("eval", title, missing("a fitted map (see Fitted maps)"));
  const std::string dir = s.dir().string();
  std::string body = "<p>The session was captured by the simulator from scene <code>" + escape_html(scene->name) +
                     "</code>, so its truth is known: each map is evaluated as <code>vdrig eval MAP --scene " +
                     escape_html(scene->name) + " --session " + escape_html(dir) +
                     "</code> evaluates it (the same code and figures). Per material (texels on one material only): "
                     "the relative RMS error of the map's radiance against the truth, in %, over " +
                     std::to_string(d.options->eval_directions) +
                     " directions spread over the hemisphere and over the session's views; the Phong parameters' "
                     "relative errors where the truth and the model have them.</p>\n";
  const auto pct = [](double x) { return std::isfinite(x) ? html::number("%.2f", 100.0 * x) : std::string("&#8211;"); };
  for (const fs::path& file : d.map_files) {
    body += "<article class=\"eval\"><h3>" + escape_html(file.filename().string()) + "</h3>\n";
    auto map = fitting::ParameterMap::read(file);
    EvalOptions options;
    options.dense_directions = d.options->eval_directions;
    options.session_dir = s.dir();
    auto report = map ? evaluate_map(map.value(), scene.value(), options) : Result<EvalReport>(map.error());
    if (!report) {
      body += missing("an evaluation of this map: " + escape_html(report.error().message)) + "</article>\n";
      continue;
    }
    bool phong = false;
    for (const MaterialEval& m : report->materials) phong = phong || m.has_phong;
    const bool session = report->session_views > 0;
    body +=
        "<div class=\"scroll\"><table class=\"eval\"><thead><tr><th>material</th><th>texels</th><th>mean %</th>"
        "<th>p95 %</th><th>p99 %</th><th>max %</th>" +
        std::string(session ? "<th>at the views: mean %</th><th>p95 %</th>" : "") +
        (phong ? "<th>Kd err %</th><th>Ks err %</th><th>m err %</th>" : "") +
        "<th>after the scale: mean %</th></tr></thead><tbody>\n";
    for (const MaterialEval& m : report->materials) {
      body += "<tr><td>" + escape_html(m.name) + "</td><td>" + std::to_string(m.texels) + "</td>";
      for (double x : {m.dense.mean, m.dense.p95, m.dense.p99, m.dense.max}) body += "<td>" + pct(x) + "</td>";
      if (session) body += "<td>" + pct(m.session.mean) + "</td><td>" + pct(m.session.p95) + "</td>";
      if (phong)
        for (double x : {m.phong.kd_rel, m.phong.ks_rel, m.phong.shininess_rel})
          body += "<td>" + (m.has_phong ? pct(x) : std::string("&#8211;")) + "</td>";
      body += "<td>" + pct(m.dense_scaled.mean) + "</td></tr>\n";
    }
    body += "</tbody></table></div>\n";
    {
      char scale[160];
      std::snprintf(scale, sizeof scale, "%.4f %.4f %.4f", report->scale[0], report->scale[1], report->scale[2]);
      body += "<p>Scale map / truth (R G B): " + std::string(scale) +
              ", units a response curve recovered from the images cannot know; the last column divides the map by "
              "it (eval_stage.hpp).</p>\n";
    }
    if (report->materials.empty()) body += missing("texels entirely on one material (the map is too coarse)");
    for (const std::string& warning : report->warnings) body += "<p class=\"missing\">" + escape_html(warning) + "</p>";
    if (const int rel = report->error_map.find("rel_rms"); rel >= 0) {
      cv::Mat percent = report->error_map.channels[rel] * 100.0;
      body += "<div class=\"row\">" +
              false_colour(percent, "relative RMS error", d.options->map_image_px,
                           "per texel, over the dense directions (edges of materials included)", "%") +
              "</div>\n";
    }
    body += "</article>\n";
  }
  return section("eval", title, body);
}

Result<std::string> compare_section(const ReportData& d) {
  const fs::path file =
      d.options->compare_json.empty() ? d.session->layout().compare_dir() / "compare.json" : d.options->compare_json;
  if (!fs::exists(file)) {
    if (!d.options->compare_json.empty()) return make_error(ErrorCode::kNotFound, file.string() + " does not exist");
    return section("compare", "Renders against photographs",
                   missing("a comparison (vdrig compare " + escape_html(d.session->dir().string()) +
                           " --maps phong:1 --views held-out writes " + escape_html(file.string()) + ")"));
  }
  auto json = read_json_file(file);
  if (!json) return json.error();
  auto report = CompareReport::from_json(json.value());
  if (!report) return make_error(report.error().code, file.string() + ": " + report.error().message);
  std::string body =
      "<p>Mean / standard deviation of |render &#8722; photo| in 8-bit codes after the same tone "
      "mapping (gamma " +
      html::number("%.3g", report->gamma) + "); highlight pixels: specular term above " +
      html::number("%.0f", 100 * report->highlight_fraction) + " % of the total in map <code>" +
      escape_html(report->region_map) + "</code>. Difference images amplified 8x.</p>\n";
  body +=
      "<div class=\"wide\"><table><thead><tr><th>map</th><th>view</th><th>diffuse</th><th>highlight</th><th>all</th>"
      "<th>render</th>"
      "<th>photo</th><th>difference x8</th><th>regions</th></tr></thead><tbody>\n";
  auto cell = [](const DifferenceStats& s) {
    return s.samples == 0 ? std::string("&#8211;")
                          : html::number("%.2f", s.mean) + " / " + html::number("%.2f", s.stddev);
  };
  std::string absent;
  for (const ViewComparison& r : report->rows) {
    body += "<tr><td>" + escape_html(r.map_name) + "</td><td>" + std::to_string(r.view) + "</td><td>" +
            cell(r.diffuse) + "</td><td>" + cell(r.highlight) + "</td><td>" + cell(r.all) + "</td>";
    for (const auto& [png, alt] : {std::pair{r.render_png, "render"}, std::pair{r.photo_png, "photo"},
                                   std::pair{r.diff_png, "difference"}, std::pair{r.regions_png, "regions"}}) {
      auto image = read_png(png);
      if (!image || image->depth() != CV_8U) {
        body += "<td>&#8211;</td>";
        absent += " " + png.filename().string();
        continue;
      }
      cv::Mat thumb;
      const double scale = double(d.options->thumbnail_width_px) / image->cols;
      cv::resize(image.value(), thumb, {}, scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_NEAREST);
      body += "<td>" + img_tag(thumb, std::string(alt) + " of view " + std::to_string(r.view)) + "</td>";
    }
    body += "</tr>\n";
  }
  body += "</tbody></table></div>\n";
  if (!absent.empty()) body += missing("compare images (run vdrig compare again):" + escape_html(absent));
  if (!report->command.empty()) body += "<p>Made by <code>" + escape_html(report->command) + "</code>.</p>\n";
  return section("compare", "Renders against photographs", body);
}

struct TexelPick {
  int s = 0, t = 0;
  std::string why;
};

/// A texel's parameters as a table, one row per quantity with its colour channels or axes side by side ("kd (R, G, B)
/// 0.31 0.22 0.12", "r0 (x, y, z)"), rather than a line of "kd.R 0.31, kd.G 0.22, ..." pairs.
std::string parameter_table(const std::vector<std::string>& names, const std::vector<double>& values) {
  std::vector<std::pair<std::string, std::string>> rows;  // quantity, cells
  std::map<std::string, size_t> row_of;
  std::map<std::string, std::string> components;
  for (size_t i = 0; i < names.size() && i < values.size(); ++i) {
    // The component is the part of the name that is one of R, G, B, x, y, z ("hsh.R.07": quantity "hsh.07", R).
    std::string key, component;
    size_t start = 0;
    for (size_t end = 0; end != std::string::npos; start = end + 1) {
      end = names[i].find('.', start);
      const std::string part = names[i].substr(start, end == std::string::npos ? end : end - start);
      if (component.empty() && part.size() == 1 && std::string("RGBxyz").find(part) != std::string::npos)
        component = part;
      else
        key += (key.empty() ? "" : ".") + part;
    }
    const auto [it, added] = row_of.try_emplace(key, rows.size());
    if (added) rows.push_back({key, ""});
    rows[it->second].second += "<td>" + html::significant(values[i], 4) + "</td>";
    if (!component.empty()) components[key] += (components[key].empty() ? "" : ", ") + component;
  }
  std::string table = "<table class=\"params\">";
  for (const auto& [key, cells] : rows)
    table += "<tr><th>" + escape_html(key + (components[key].empty() ? "" : " (" + components[key] + ")")) + "</th>" +
             cells + "</tr>";
  return table + "</table>";
}

std::string texel_plot(const fitting::ParameterMap& map, const fitting::ObsMapReader& obs, const TexelPick& pick,
                       const std::vector<int>& held_out) {
  auto tile = obs.read_tile_of_texel(pick.s, pick.t);
  if (!tile)
    return missing("texel " + std::to_string(pick.s) + "," + std::to_string(pick.t) + ": " +
                   escape_html(tile.error().message));
  const fitting::TexelObservations o = tile->texel(pick.s, pick.t);
  std::vector<double> residual(o.size());
  double worst = 1e-12;
  for (size_t i = 0; i < o.size(); ++i) {
    const Vec3d v = o.direction[i].cast<double>();
    residual[i] = (map.evaluate(pick.s, pick.t, v) - o.radiance[i].cast<double>()).norm();
    worst = std::max(worst, residual[i]);
  }
  std::vector<PolarPoint> points;
  for (size_t i = 0; i < o.size(); ++i) {
    const bool held = std::binary_search(held_out.begin(), held_out.end(), o.view[i]);
    const Vec3d rgb = o.radiance[i].cast<double>();
    points.push_back({o.direction[i].cast<double>(), viridis(residual[i] / worst), held ? 6.0 : 3.5,
                      "view " + std::to_string(o.view[i]) + (held ? " (held out)" : "") + ": observed " +
                          html::number("%.4g", rgb.x()) + " " + html::number("%.4g", rgb.y()) + " " +
                          html::number("%.4g", rgb.z()) + ", |residual| " + html::number("%.4g", residual[i])});
  }
  const std::string params = parameter_table(map.model().channels(), map.parameters(pick.s, pick.t));
  // The inspector's curve plot (`vdrig inspect`, the viewer's overlay), from the same description (viewer/plot.hpp).
  plot::Figure curve = viewer::curve_figure(viewer::inspect_texel(map, pick.s, pick.t, o, held_out));
  curve.width_px = 420;
  curve.height_px = 260;
  return "<figure class=\"texel\">" + polar_plot(points, {}, 260) + plot::to_svg(curve) + "<figcaption>Texel " +
         std::to_string(pick.s) + "," + std::to_string(pick.t) + " (" + escape_html(pick.why) + "), " +
         std::to_string(o.size()) + " observations; large points: held-out views.<br>" +
         colour_bar(0, worst, "|model - observed| (RGB norm)") + params + "</figcaption></figure>\n";
}

std::string texels_section(const ReportData& d) {
  if (d.map_files.empty())
    return section("texels", "Texels on the hemisphere", missing("a fitted map (see Fitted maps)"));
  // The most recently fitted map that reads (not the first by name: a user's latest fit is the one in question), with
  // its observation map at the same resolution.
  std::vector<std::pair<fs::file_time_type, fs::path>> by_age;
  for (const fs::path& file : d.map_files) {
    std::error_code ec;
    const auto written = fs::last_write_time(file, ec);
    by_age.push_back({ec ? fs::file_time_type::min() : written, file});
  }
  std::stable_sort(by_age.begin(), by_age.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string body;
  for (const auto& [written, file] : by_age) {
    auto map = fitting::ParameterMap::read(file);
    if (!map) continue;
    const fs::path obs_file = d.session->layout().obsmap_file(map->texels_s(), map->texels_t());
    auto obs = fitting::ObsMapReader::open(obs_file);
    if (!obs) {
      return section("texels", "Texels on the hemisphere",
                     missing("the observation map " + escape_html(obs_file.string()) + " (vdrig obsmap build " +
                             escape_html(d.session->dir().string()) + " --res " + std::to_string(map->texels_s()) +
                             "x" + std::to_string(map->texels_t()) + ")"));
    }
    std::vector<int> held;
    if (auto h = held_out_views(map.value())) held = h.value();
    std::sort(held.begin(), held.end());
    std::vector<TexelPick> picks;
    if (map->has("rms.R") && map->has("rms.G") && map->has("rms.B")) {
      std::vector<std::pair<float, int>> by_rms;
      for (int t = 0; t < map->texels_t(); ++t)
        for (int s = 0; s < map->texels_s(); ++s)
          by_rms.push_back(
              {map->at("rms.R", s, t) + map->at("rms.G", s, t) + map->at("rms.B", s, t), t * map->texels_s() + s});
      std::sort(by_rms.begin(), by_rms.end());
      const int S = map->texels_s();
      picks.push_back({by_rms.back().second % S, by_rms.back().second / S, "the worst fit residual"});
      const auto& median = by_rms[by_rms.size() / 2];
      picks.push_back({median.second % S, median.second / S, "the median fit residual"});
    }
    for (const auto& [s, t] : d.options->texels) {
      if (s < 0 || t < 0 || s >= map->texels_s() || t >= map->texels_t())
        body += missing("texel " + std::to_string(s) + "," + std::to_string(t) + ": outside the " +
                        std::to_string(map->texels_s()) + "x" + std::to_string(map->texels_t()) + " map");
      else
        picks.push_back({s, t, "chosen"});
    }
    body = "<p>Map <code>" + escape_html(file.filename().string()) + "</code>" +
           (d.map_files.size() > 1 ? " (the most recently fitted)" : "") +
           ": each point an observation of the texel from the direction it was seen (as the coverage plot), "
           "coloured by the model's residual there.</p>\n<div class=\"row\">" +
           [&] {
             std::string plots;
             for (const TexelPick& p : picks) plots += texel_plot(map.value(), obs.value(), p, held);
             return plots;
           }() +
           "</div>\n" + body;
    return section("texels", "Texels on the hemisphere", body);
  }
  return section("texels", "Texels on the hemisphere", missing("a readable fitted map"));
}

std::string utc(fs::file_time_type t) {
  const auto sys = std::chrono::file_clock::to_sys(t);
  const std::time_t tt = std::chrono::system_clock::to_time_t(sys);
  std::tm tm{};
  gmtime_r(&tt, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

std::string provenance_section(const ReportData& d, double build_s) {
  const capture::Session& s = *d.session;
  const capture::Manifest& m = s.manifest();
  const capture::SessionLayout layout = s.layout();
  std::string body = "<table>";
  const auto row = [&](const std::string& k, const std::string& v) {
    body += "<tr><th>" + escape_html(k) + "</th><td>" + v + "</td></tr>";
  };
  row("session", "<code>" + escape_html(fs::absolute(s.dir()).string()) + "</code>");
  row("captured by", escape_html(m.software_version) + ", " + escape_html(m.created_utc));
  row("report by", escape_html(capture::software_version()));
  row("rig", "<code>" + escape_html(m.rig_config.value("backend", m.rig_config.dump().substr(0, 200))) + "</code>");
  row("scheme, bracket", "<code>" + escape_html(m.scheme) + "</code>, <code>" + escape_html(m.bracket) + "</code>");
  if (!m.extra.empty()) row("manifest extra", "<code>" + escape_html(m.extra.dump()) + "</code>");
  body +=
      "</table>\n<h3>Stage timings</h3><table><tr><th>stage</th><th>from</th><th>to / written</th>"
      "<th>duration, s</th></tr>";
  int64_t first = 0, last = 0;
  for (const auto& f : s.frames()) {
    first = first == 0 ? f.timestamp_ns : std::min(first, f.timestamp_ns);
    last = std::max(last, f.timestamp_ns);
  }
  body += "<tr><td>capture (journal timestamps)</td><td></td><td></td><td>" +
          (s.frames().empty() ? std::string("no frames") : html::number("%.1f", (last - first) * 1e-9)) + "</td></tr>";
  // HDR merge and observation maps record no timings of their own: their outputs' modification times say when they
  // ended, and for several files a lower bound of the stage's length (the first file's own work is not in it). A
  // single file (an observation map) bounds nothing: its time is shown, its duration is not recorded. Fits record
  // their wall time in the map (vdrig.fit_seconds); the span of the maps' write times was no fit's duration.
  auto span_of = [&](const std::string& stage, const fs::path& dir, const std::string& ext) {
    std::error_code ec;
    std::optional<fs::file_time_type> lo, hi;
    int files = 0;
    if (fs::is_directory(dir, ec))
      for (const auto& e : fs::directory_iterator(dir, ec))
        if (e.is_regular_file() && e.path().extension() == ext) {
          const auto t = e.last_write_time(ec);
          if (ec) continue;
          ++files;
          lo = lo ? std::min(*lo, t) : t;
          hi = hi ? std::max(*hi, t) : t;
        }
    if (!lo) {
      body += "<tr><td>" + escape_html(stage) + "</td><td colspan=\"3\" class=\"missing\">not run</td></tr>";
      return;
    }
    const std::string duration =
        files < 2 ? std::string("not recorded")
                  : "&#8805; " + html::significant(std::chrono::duration<double>(*hi - *lo).count(), 3) +
                        " (first to last file written)";
    body += "<tr><td>" + escape_html(stage) + "</td><td>" + utc(*lo) + "</td><td>" + utc(*hi) + "</td><td>" + duration +
            "</td></tr>";
  };
  span_of("HDR merge (hdr/*.exr written)", layout.hdr_dir(), ".exr");
  span_of("observation maps (obsmap/*.vdobs written)", layout.obsmap_dir(), ".vdobs");
  for (const fs::path& file : d.map_files) {
    auto image = read_exr(file, fitting::ParameterMap::kMaxReadBytes);
    std::error_code ec;
    const auto written = fs::last_write_time(file, ec);
    std::string seconds = "not recorded (an older map)";
    if (image)
      if (const auto it = image->number_attributes.find(fitting::kFitSecondsAttribute);
          it != image->number_attributes.end())
        seconds = html::significant(it->second, 3);
    body += "<tr><td>fit " + escape_html(file.filename().string()) + "</td><td></td><td>" +
            (ec ? std::string() : utc(written)) + "</td><td>" + seconds + "</td></tr>";
  }
  if (d.map_files.empty())
    body += "<tr><td>fits (maps/*.exr)</td><td colspan=\"3\" class=\"missing\">not run</td></tr>";
  span_of("comparison (compare.json written)", layout.compare_dir(), ".json");
  body += "<tr><td>this report</td><td></td><td></td><td>" + html::number("%.2f", build_s) + "</td></tr></table>\n";
  body += "<h3>Commands</h3><ul><li>capture: scheme <code>" + escape_html(m.scheme) + "</code> (" +
          escape_html(m.extra.value("created_by", std::string("vdrig capture or vdrigd"))) + ")</li>";
  for (const fs::path& file : d.map_files) {
    auto image = read_exr(file, fitting::ParameterMap::kMaxReadBytes);
    const auto attribute = [&](const std::string& key) {
      return image && image->string_attributes.count(key) ? image->string_attributes.at(key) : std::string();
    };
    body += "<li>" + escape_html(file.filename().string()) + ": ";
    if (!attribute("vdrig.command").empty()) {
      body += "<code>" + escape_html(attribute("vdrig.command")) + "</code></li>";
      continue;
    }
    const std::string spec =
        attribute("vdrig.model_spec").empty() ? file.stem().string() : attribute("vdrig.model_spec");
    const std::string held = attribute("vdrig.held_out_views");
    body += "not recorded; the map holds model <code>" + escape_html(spec) + "</code>" +
            (held.empty() ? "" : ", held-out views " + escape_html(held)) + "</li>";
  }
  body += "</ul>\n";
  return section("provenance", "Provenance: versions, timings, commands", body);
}

constexpr const char* kStyle = R"(
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1400px; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; } h3 { margin-bottom: 0.3em; }
table { border-collapse: collapse; font-size: 0.85em; max-width: 100%; }
td, th { border: 1px solid #ddd; padding: 2px 6px; } th { white-space: nowrap; }
td code { overflow-wrap: anywhere; } /* long JSON and paths wrap instead of running off the page */
th { background: #f3f3f3; text-align: left; } tr.incomplete { color: #a00; }
.scroll { max-height: 360px; max-width: 100%; overflow: auto; display: inline-block; }
.wide { max-width: 100%; overflow-x: auto; } /* tables of thumbnails scroll inside the page at any width */
.missing { color: #a05000; background: #fff4e0; padding: 4px 8px; }
.row { display: flex; flex-wrap: wrap; gap: 1em; } figure { margin: 0.5em 0; } figcaption { font-size: 0.8em; }
.texel { max-width: 700px; } .params td { text-align: right; } .mapimage { max-width: 262px; }
.thumbs { display: flex; flex-wrap: wrap; gap: 4px; margin-bottom: 1em; }
.thumb { margin: 0; padding: 1px; border: 2px solid transparent; text-align: center; }
.thumb img { display: block; image-rendering: auto; } .thumb figcaption { font-size: 0.7em; }
.thumb.held-out, .key.held-out { border: 2px solid #d62728; }
.thumb.excluded, .key.excluded { border: 2px dashed #111; } .thumb.excluded img { opacity: 0.45; }
.key { padding: 0 3px; } img { image-rendering: pixelated; }
nav a { margin-right: 1em; }
)";

}  // namespace

Result<std::string> build_report_html(const fs::path& session_dir, const ReportOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  auto session = capture::Session::open(session_dir);
  if (!session)
    return make_error(session.error().code,
                      "cannot read session " + session_dir.string() + ": " + session.error().message);
  ReportData data;
  data.session = &session.value();
  data.options = &options;
  std::error_code ec;
  if (fs::is_directory(session->layout().maps_dir(), ec))
    for (const auto& e : fs::directory_iterator(session->layout().maps_dir(), ec))
      if (e.is_regular_file() && e.path().extension() == ".exr") data.map_files.push_back(e.path());
  std::sort(data.map_files.begin(), data.map_files.end());
  data.hdr = read_view_hdrs(session.value(), options.view_thumbnail_px);
  data.held_out = held_out_by_maps(data.map_files);
  data.excluded = excluded_by_calibration(session->layout());

  auto compare = compare_section(data);
  if (!compare) return compare.error();
  std::string sections = coverage_section(data) + views_section(data) + calibration_section(data) + maps_section(data) +
                         eval_section(data) + compare.value() + texels_section(data);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  sections += provenance_section(data, build_s);
  const std::string title = "vdrig session report: " + fs::absolute(session_dir).filename().string();
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + escape_html(title) +
         "</title>\n<style>" + kStyle + "</style>\n</head>\n<body>\n<h1>" + escape_html(title) +
         "</h1>\n<nav><a href=\"#coverage\">coverage</a><a href=\"#views\">views</a><a "
         "href=\"#calibration\">calibration</a><a href=\"#maps\">maps</a><a href=\"#eval\">truth</a><a "
         "href=\"#compare\">compare</a><a "
         "href=\"#texels\">texels</a><a href=\"#provenance\">provenance</a></nav>\n" +
         sections + "</body>\n</html>\n";
}

Status write_report(const fs::path& session_dir, const fs::path& out, const ReportOptions& options) {
  auto html = build_report_html(session_dir, options);
  if (!html) return html.error();
  return write_file_atomic(out, html.value());
}

}  // namespace vdrig::pipeline
