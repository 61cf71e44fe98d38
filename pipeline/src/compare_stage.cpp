#include "vdrig/pipeline/compare_stage.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/core/utility.hpp>
#include <sstream>

#include "surface_rays.hpp"
#include "vdrig/calib/hdr.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/pipeline/eval_stage.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/viewer/surface_renderer.hpp"

namespace vdrig::pipeline {
namespace fs = std::filesystem;
namespace {

constexpr uint8_t kDiffuse = 128, kHighlight = 255;
constexpr const char* kHeldOutAttribute = "vdrig.held_out_views";

/// Per texel, the RGB sum of the radiance that is not specular: the model's diffuse part where it has one (Phong's
/// Kd), else the lowest radiance over kFloorDirections hemisphere directions (CV_64FC1, T x S).
cv::Mat diffuse_floor(const fitting::ParameterMap& map) {
  const int S = map.texels_s(), T = map.texels_t();
  cv::Mat floor(T, S, CV_64FC1);
  const fitting::ReflectanceModel& model = map.model();
  const bool exact = model.has_diffuse_part();
  const std::vector<Vec3d> directions = hemisphere_directions(kFloorDirections);
  cv::parallel_for_(cv::Range(0, T), [&](const cv::Range& rows) {
    for (int t = rows.start; t < rows.end; ++t)
      for (int s = 0; s < S; ++s) {
        double lowest = 0.0;
        if (exact) {
          lowest = model.diffuse_part(map.parameters(s, t)).sum();
        } else {
          lowest = std::numeric_limits<double>::infinity();
          for (const Vec3d& v : directions) lowest = std::min(lowest, map.evaluate(s, t, v).sum());
        }
        floor.at<double>(t, s) = lowest;
      }
  });
  return floor;
}

std::string view_stem(int view) {
  char stem[32];
  std::snprintf(stem, sizeof stem, "view_%04d", view);
  return stem;
}

nlohmann::json stats_json(const DifferenceStats& d) {
  return {{"samples", d.samples}, {"mean", d.mean}, {"stddev", d.stddev}};
}
DifferenceStats stats_of(const nlohmann::json& j) {
  return {j.at("samples").get<long long>(), j.at("mean").get<double>(), j.at("stddev").get<double>()};
}

}  // namespace

std::vector<int> spread_holdout_views(int views, int count) {
  std::vector<int> out;
  for (int k = 1; k <= count; ++k) out.push_back(views * k / (count + 1));
  return out;
}

std::vector<int> spread_holdout_views(int views, int count, const std::vector<bool>& unusable) {
  std::vector<int> out;
  std::vector<bool> taken(static_cast<size_t>(std::max(views, 0)), false);
  const auto usable = [&](int v) {
    return v >= 1 && v < views && !taken[v] && !(static_cast<size_t>(v) < unusable.size() && unusable[v]);
  };
  for (int wanted : spread_holdout_views(views, count)) {
    for (int d = 0; d < views; ++d) {
      const int pick = usable(wanted + d) ? wanted + d : usable(wanted - d) ? wanted - d : -1;
      if (pick < 0) continue;
      taken[pick] = true;
      out.push_back(pick);
      break;
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

Result<std::vector<int>> common_held_out_views(const std::vector<fs::path>& maps) {
  std::vector<int> first;
  for (size_t i = 0; i < maps.size(); ++i) {
    auto map = fitting::ParameterMap::read(maps[i]);
    if (!map) return make_error(map.error().code, maps[i].string() + ": " + map.error().message);
    auto held = held_out_views(map.value());
    if (!held)
      return make_error(ErrorCode::kInvalidArgument,
                        maps[i].string() + " was fitted without --holdout: its fit saw every view, so --holdout has " +
                            "no view to compare it at (fit it with --holdout N, or name views with --views)");
    if (i == 0) {
      first = held.value();
    } else if (held.value() != first) {
      return make_error(ErrorCode::kInvalidArgument,
                        maps[i].string() + " held out other views than " + maps[0].string() +
                            ": --holdout needs maps fitted with the same --holdout (or name views with --views)");
    }
  }
  if (maps.empty()) return make_error(ErrorCode::kInvalidArgument, "compare needs at least one map");
  return first;
}

Result<std::vector<int>> held_out_views(const fitting::ParameterMap& map) {
  const auto& attributes = map.image().string_attributes;
  const auto it = attributes.find(kHeldOutAttribute);
  if (it == attributes.end() || it->second.empty())
    return make_error(ErrorCode::kNotFound, "the map records no held-out views (fitted without --holdout)");
  std::vector<int> views;
  std::istringstream in(it->second);
  std::string item;
  while (std::getline(in, item, ',')) {
    try {
      views.push_back(std::stoi(item));
    } catch (const std::exception&) {
      return make_error(ErrorCode::kCorrupt, std::string(kHeldOutAttribute) + " is not a list of views: " + it->second);
    }
  }
  return views;
}

DifferenceStats difference_stats(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  VDRIG_CHECK(a.type() == CV_8UC3 && b.type() == CV_8UC3 && a.size() == b.size() && mask.type() == CV_8UC1 &&
                  mask.size() == a.size(),
              "difference_stats needs two 8-bit BGR images and a mask of one size");
  double sum = 0.0, sum2 = 0.0;
  long long n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const auto& pa = a.at<cv::Vec3b>(y, x);
      const auto& pb = b.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double d = std::abs(int(pa[c]) - int(pb[c]));
        sum += d, sum2 += d * d, ++n;
      }
    }
  DifferenceStats out;
  out.samples = n;
  if (n == 0) return out;
  out.mean = sum / double(n);
  out.stddev = std::sqrt(std::max(0.0, sum2 / double(n) - out.mean * out.mean));
  return out;
}

cv::Mat highlight_regions(const fitting::ParameterMap& map, const CameraModel& camera, const ViewPose& pose,
                          const cv::Mat& hdr_mask, double highlight_fraction) {
  const cv::Mat floor = diffuse_floor(map);
  const int S = map.texels_s(), T = map.texels_t();
  const double W = map.width_mm(), H = map.height_mm();
  const Vec3d centre = pose.camera_centre();
  cv::Mat regions(camera.height, camera.width, CV_8UC1, cv::Scalar(0));
  for_each_surface_hit(camera, pose, [&](int x, int y, const Vec3d& p) {
    if (!hdr_mask.empty() && hdr_mask.at<uint8_t>(y, x) != 0) return;
    const double u = (p.x() + W / 2) / W, w = (p.y() + H / 2) / H;
    if (u < 0 || u >= 1 || w < 0 || w >= 1) return;
    const int s = std::min(S - 1, int(u * S)), t = std::min(T - 1, int(w * T));
    const double total = map.evaluate(s, t, (centre - p).normalized()).sum();
    const double specular = total - floor.at<double>(t, s);
    regions.at<uint8_t>(y, x) = total > 0 && specular > highlight_fraction * total ? kHighlight : kDiffuse;
  });
  return regions;
}

Result<CompareReport> compare_maps(const capture::Session& session, const std::vector<fs::path>& map_files,
                                   const std::vector<int>& views, const CompareOptions& options) {
  if (map_files.empty()) return make_error(ErrorCode::kInvalidArgument, "compare needs at least one map");
  if (views.empty()) return make_error(ErrorCode::kInvalidArgument, "compare needs at least one view");
  if (!(options.gamma > 0) || !std::isfinite(options.gamma))
    return make_error(ErrorCode::kInvalidArgument, "gamma must be positive");
  if (!(options.highlight_fraction > 0 && options.highlight_fraction < 1))
    return make_error(ErrorCode::kInvalidArgument, "the highlight fraction must be in (0, 1)");
  const int n_views = static_cast<int>(session.manifest().views.size());
  for (int v : views)
    if (v < 0 || v >= n_views || !session.view_complete(v))
      return make_error(ErrorCode::kInvalidArgument, "view " + std::to_string(v) + " is not a complete view of " +
                                                         session.dir().string() + " (views 0.." +
                                                         std::to_string(n_views - 1) + ")");
  std::vector<fitting::ParameterMap> maps;
  for (const fs::path& file : map_files) {
    auto map = fitting::ParameterMap::read(file);
    if (!map) return make_error(map.error().code, file.string() + ": " + map.error().message);
    if (std::abs(map->width_mm() - session.manifest().surface_width_mm) > 1e-6 ||
        std::abs(map->height_mm() - session.manifest().surface_height_mm) > 1e-6)
      return make_error(ErrorCode::kInvalidArgument, file.string() + " covers another surface size than the session");
    maps.push_back(std::move(map.value()));
  }
  size_t reference = 0;
  for (size_t i = maps.size(); i-- > 0;)
    if (maps[i].model().has_diffuse_part()) reference = i;  // the first whose diffuse part is exact

  auto geometry = session_geometry(session);
  if (!geometry) return geometry.error();
  const CameraModel& camera = geometry->camera;

  // Photos and regions once per view; renders per map.
  struct ViewData {
    cv::Mat photo, regions;
  };
  std::vector<ViewData> view_data;
  for (int v : views) {
    const fs::path file = session.layout().hdr_file(v);
    auto hdr = calib::read_hdr_exr(file);
    if (!hdr)
      return make_error(hdr.error().code, "view " + std::to_string(v) + ": " + hdr.error().message +
                                              " (merge the brackets first: vdrig hdr SESSION)");
    if (hdr->radiance.cols != camera.width || hdr->radiance.rows != camera.height)
      return make_error(ErrorCode::kCorrupt, file.string() + " is not of the camera's size");
    cv::Mat radiance = hdr->radiance;
    cv::patchNaNs(radiance, 0.0);
    view_data.push_back(
        {viewer::tone_map(radiance, options.gamma),
         highlight_regions(maps[reference], camera, geometry->poses.at(v), hdr->mask, options.highlight_fraction)});
  }

  auto ctx = viewer::GlContext::create(camera.width, camera.height, false);
  if (!ctx) return ctx.error();
  CompareReport report;
  report.gamma = options.gamma;
  report.highlight_fraction = options.highlight_fraction;
  report.region_map = map_files[reference].stem().string();
  report.command = options.command;
  const fs::path out_dir = fs::absolute(options.out_dir.empty() ? session.layout().compare_dir() : options.out_dir);
  for (size_t m = 0; m < maps.size(); ++m) {
    auto renderer = viewer::SurfaceRenderer::create(maps[m]);
    if (!renderer) return renderer.error();
    const fs::path map_dir = out_dir / map_files[m].stem();
    std::error_code ec;
    fs::create_directories(map_dir, ec);
    if (ec) return make_error(ErrorCode::kIo, "cannot create " + map_dir.string() + ": " + ec.message());
    for (size_t i = 0; i < views.size(); ++i) {
      const int v = views[i];
      auto radiance = renderer.value()->render_radiance(camera, geometry->poses.at(v), {});
      if (!radiance) return radiance.error();
      const cv::Mat render = viewer::tone_map(radiance.value(), options.gamma);
      const ViewData& data = view_data[i];
      ViewComparison row;
      row.map_name = map_files[m].stem().string();
      row.model = maps[m].model().name();
      row.view = v;
      row.all = difference_stats(render, data.photo, data.regions);
      row.diffuse = difference_stats(render, data.photo, data.regions == kDiffuse);
      row.highlight = difference_stats(render, data.photo, data.regions == kHighlight);
      cv::Mat diff;
      cv::absdiff(render, data.photo, diff);
      diff.convertTo(diff, CV_8U, 8.0);  // amplified 8x (saturating) so small differences are visible
      const std::string stem = view_stem(v);
      row.render_png = map_dir / (stem + "_render.png");
      row.photo_png = map_dir / (stem + "_photo.png");
      row.diff_png = map_dir / (stem + "_diff_x8.png");
      row.regions_png = map_dir / (stem + "_regions.png");
      VDRIG_TRY(write_png(row.render_png, render));
      VDRIG_TRY(write_png(row.photo_png, data.photo));
      VDRIG_TRY(write_png(row.diff_png, diff));
      VDRIG_TRY(write_png(row.regions_png, data.regions));
      report.rows.push_back(row);
    }
  }
  report.json_file = out_dir / "compare.json";
  VDRIG_TRY(write_file_atomic(report.json_file, report.to_json().dump(2) + "\n"));
  return report;
}

nlohmann::json CompareReport::to_json() const {
  nlohmann::json rows_json = nlohmann::json::array();
  for (const ViewComparison& r : rows)
    rows_json.push_back({{"map", r.map_name},
                         {"model", r.model},
                         {"view", r.view},
                         {"all", stats_json(r.all)},
                         {"diffuse", stats_json(r.diffuse)},
                         {"highlight", stats_json(r.highlight)},
                         {"render_png", r.render_png.string()},
                         {"photo_png", r.photo_png.string()},
                         {"diff_png", r.diff_png.string()},
                         {"regions_png", r.regions_png.string()}});
  return {{"gamma", gamma},     {"highlight_fraction", highlight_fraction},  {"region_map", region_map},
          {"command", command}, {"units", "8-bit codes after tone mapping"}, {"rows", rows_json}};
}

Result<CompareReport> CompareReport::from_json(const nlohmann::json& j) {
  try {
    CompareReport out;
    out.gamma = j.at("gamma").get<double>();
    out.highlight_fraction = j.at("highlight_fraction").get<double>();
    out.region_map = j.at("region_map").get<std::string>();
    out.command = j.value("command", "");
    for (const auto& r : j.at("rows")) {
      ViewComparison row;
      row.map_name = r.at("map").get<std::string>();
      row.model = r.at("model").get<std::string>();
      row.view = r.at("view").get<int>();
      row.all = stats_of(r.at("all"));
      row.diffuse = stats_of(r.at("diffuse"));
      row.highlight = stats_of(r.at("highlight"));
      row.render_png = r.at("render_png").get<std::string>();
      row.photo_png = r.at("photo_png").get<std::string>();
      row.diff_png = r.at("diff_png").get<std::string>();
      row.regions_png = r.at("regions_png").get<std::string>();
      out.rows.push_back(row);
    }
    return out;
  } catch (const nlohmann::json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("not a compare.json: ") + e.what());
  }
}

std::string CompareReport::table() const {
  char line[256];
  std::string out = "mean / std.dev. of |render - photo|, 8-bit codes (tone mapping gamma " +
                    std::to_string(gamma).substr(0, 4) + "; highlight: specular > " +
                    std::to_string(int(std::lround(highlight_fraction * 100))) + " % of " + region_map + ")\n";
  std::snprintf(line, sizeof line, "%-16s %5s  %15s  %15s  %15s\n", "map", "view", "diffuse", "highlight", "all");
  out += line;
  auto cell = [](const DifferenceStats& d) {
    char buf[40];
    if (d.samples == 0)
      std::snprintf(buf, sizeof buf, "%15s", "-");
    else
      std::snprintf(buf, sizeof buf, "%7.2f / %5.2f", d.mean, d.stddev);
    return std::string(buf);
  };
  for (const ViewComparison& r : rows) {
    std::snprintf(line, sizeof line, "%-16.16s %5d  ", r.map_name.c_str(), r.view);
    out += line + cell(r.diffuse) + "  " + cell(r.highlight) + "  " + cell(r.all) + "\n";
  }
  return out;
}

}  // namespace vdrig::pipeline
