#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/core/file_read.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::calib {
namespace {

cv::Mat camera_matrix(const CameraModel& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}
cv::Mat dist_coeffs(const CameraModel& c) { return (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3); }

/// Grey linear-ish float image of any supported input.
Result<cv::Mat> to_grey_float(const cv::Mat& image) {
  if (image.empty()) return make_error(ErrorCode::kInvalidArgument, "empty image");
  const int depth = image.depth();
  if (depth != CV_8U && depth != CV_16U && depth != CV_32F)
    return make_error(ErrorCode::kInvalidArgument, "image type must be 8U, 16U or 32F");
  cv::Mat f;
  image.convertTo(f, CV_32F);
  if (f.channels() == 3) {
    cv::cvtColor(f, f, cv::COLOR_BGR2GRAY);
  } else if (f.channels() != 1) {
    return make_error(ErrorCode::kInvalidArgument, "image must have 1 or 3 channels");
  }
  return f;
}

/// Boundary of a disc's image (distortion included); empty when any point is behind the camera.
std::vector<Vec2d> disc_outline(const CameraModel& camera, const ViewPose& pose, const Vec3d& centre, double radius,
                                int n) {
  std::vector<Vec2d> pts;
  pts.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * kPi * i / n;
    const Vec3d p_cam = pose.to_camera(centre + radius * Vec3d(std::cos(a), std::sin(a), 0.0));
    if (!(p_cam.z() > 1e-6)) return {};
    pts.push_back(camera.project(p_cam));
  }
  return pts;
}

/// Shoelace area and centroid of a closed polygon.
std::pair<double, Vec2d> polygon_area_centroid(const std::vector<Vec2d>& pts) {
  double a2 = 0.0;
  Vec2d c = Vec2d::Zero();
  for (size_t i = 0; i < pts.size(); ++i) {
    const Vec2d& p = pts[i];
    const Vec2d& q = pts[(i + 1) % pts.size()];
    const double cr = p.x() * q.y() - q.x() * p.y();
    a2 += cr;
    c += (p + q) * cr;
  }
  if (std::abs(a2) < 1e-12) return {0.0, pts.empty() ? Vec2d::Zero() : pts.front()};
  return {std::abs(a2) / 2.0, c / (3.0 * a2)};
}

/// Coverage-weighted centroid of one marker near `predicted`; `predicted_area` in px^2, `predicted_radius` in px.
Result<Vec2d> locate_marker(const cv::Mat& grey, const Vec2d& predicted, double predicted_area, double predicted_radius,
                            const MarkerDetectionOptions& opt) {
  const double half =
      opt.search_half_px > 0 ? opt.search_half_px : std::max(3.0 * predicted_radius, predicted_radius + 25.0);
  const cv::Rect full(0, 0, grey.cols, grey.rows);
  const cv::Rect win =
      cv::Rect(static_cast<int>(std::floor(predicted.x() - half)), static_cast<int>(std::floor(predicted.y() - half)),
               static_cast<int>(2 * half + 2), static_cast<int>(2 * half + 2)) &
      full;
  if (win.width < 8 || win.height < 8) return make_error(ErrorCode::kNotFound, "search window outside the image");
  const cv::Mat w = grey(win);
  // Background: a high percentile (the marker is a small part of the window); dark: the minimum.
  std::vector<float> values(w.begin<float>(), w.end<float>());
  std::nth_element(values.begin(), values.begin() + values.size() * 8 / 10, values.end());
  const double bright = values[values.size() * 8 / 10];
  double dark = 0;
  cv::minMaxLoc(w, &dark);
  if (!(bright > 0) || !(bright - dark >= opt.min_contrast * bright))
    return make_error(ErrorCode::kNotFound, "no dark blob (contrast too low)");
  const double threshold = 0.5 * (bright + dark);
  cv::Mat dark_mask = w < threshold;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(dark_mask, labels, stats, centroids, 8, CV_32S);
  int best = -1;
  double best_dist = 1e300;
  std::string rejected;
  for (int k = 1; k < n; ++k) {
    const int area = stats.at<int>(k, cv::CC_STAT_AREA);
    const int x = stats.at<int>(k, cv::CC_STAT_LEFT), y = stats.at<int>(k, cv::CC_STAT_TOP);
    const int bw = stats.at<int>(k, cv::CC_STAT_WIDTH), bh = stats.at<int>(k, cv::CC_STAT_HEIGHT);
    if (area < opt.min_area_ratio * predicted_area || area > opt.max_area_ratio * predicted_area) continue;
    // Touching the window's border: cut off (or the dark outside of the surface), not a whole disc.
    if (x == 0 || y == 0 || x + bw == win.width || y + bh == win.height) continue;
    // Ellipse fill: area against that of the ellipse with the blob's second moments (4 pi sqrt(det C)).
    const cv::Moments m = cv::moments(labels == k, true);
    const double cxx = m.mu20 / m.m00, cyy = m.mu02 / m.m00, cxy = m.mu11 / m.m00;
    const double det = cxx * cyy - cxy * cxy;
    const double fill = det > 0 ? area / (4.0 * kPi * std::sqrt(det)) : 0.0;
    if (fill < opt.min_ellipse_fill || fill > opt.max_ellipse_fill) {
      rejected = "a blob of the right size is not elliptic (fill " + std::to_string(fill) + ")";
      continue;
    }
    const Vec2d c(win.x + centroids.at<double>(k, 0), win.y + centroids.at<double>(k, 1));
    const double d = (c - predicted).norm();
    if (d < best_dist) best_dist = d, best = k;
  }
  if (best < 0)
    return make_error(ErrorCode::kNotFound,
                      rejected.empty() ? "no dark blob of the expected size (occluded or out of place?)" : rejected);

  // Coverage weights over the blob grown by 2 px (every partially covered pixel), background from a ring 3..6 px
  // out. Dark pixels of other blobs (the black outside of the surface) are kept out of both.
  const cv::Mat blob = labels == best;
  cv::Mat inner, outer;
  cv::dilate(blob, inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  cv::dilate(blob, outer, cv::getStructuringElement(cv::MORPH_ELLIPSE, {13, 13}));
  // Dark pixels of other blobs and their 1-px neighbours (partly dark: the edge of the surface is often 2-3 px
  // from a marker at grazing views) would bias both the background and the weights.
  cv::Mat foreign = dark_mask & ~blob;
  cv::dilate(foreign, foreign, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
  foreign &= ~blob;
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
  int ring = 0;
  for (int y = 0; y < w.rows; ++y)
    for (int x = 0; x < w.cols; ++x) {
      if (!outer.at<uint8_t>(y, x) || inner.at<uint8_t>(y, x) || dark_mask.at<uint8_t>(y, x) ||
          foreign.at<uint8_t>(y, x))
        continue;
      const Eigen::Vector3d a(1.0, x, y);
      AtA += a * a.transpose();
      Atb += a * w.at<float>(y, x);
      ++ring;
    }
  if (ring < 12) return make_error(ErrorCode::kNotFound, "too little background around the blob");
  const Eigen::Vector3d plane = AtA.ldlt().solve(Atb);
  cv::Mat core;
  cv::erode(blob, core, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
  const double dark_level = cv::countNonZero(core) > 0 ? cv::mean(w, core)[0] : dark;
  double sw = 0, sx = 0, sy = 0;
  for (int y = 0; y < w.rows; ++y)
    for (int x = 0; x < w.cols; ++x) {
      if (!inner.at<uint8_t>(y, x) || foreign.at<uint8_t>(y, x)) continue;
      const double bg = plane(0) + plane(1) * x + plane(2) * y;
      if (!(bg - dark_level > 0)) continue;
      const double cov = (bg - w.at<float>(y, x)) / (bg - dark_level);
      sw += cov;
      sx += cov * x;
      sy += cov * y;
    }
  if (!(sw > 0.25 * predicted_area * opt.min_area_ratio))
    return make_error(ErrorCode::kNotFound, "blob has no coverage after background removal");
  return Vec2d(win.x + sx / sw, win.y + sy / sw);
}

ViewPose pose_from_cv(const cv::Mat& rvec, const cv::Mat& tvec) {
  ViewPose p;
  p.R = rvec_to_rotation({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)});
  p.t = {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
  return p;
}

nlohmann::json vec_json(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

Result<Vec3d> vec_from_json(const nlohmann::json& j, const char* what) {
  if (!j.is_array() || j.size() != 3) return make_error(ErrorCode::kCorrupt, std::string(what) + " is not a 3-vector");
  return Vec3d(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
}

}  // namespace

MarkerLayout MarkerLayout::corners(double width_mm, double height_mm, double inset_mm, double radius_mm) {
  const double x = width_mm / 2 - inset_mm, y = height_mm / 2 - inset_mm;
  return {{{-x, -y, 0}, {x, -y, 0}, {x, y, 0}, {-x, y, 0}}, radius_mm};
}

bool MarkerLayout::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (centres_mm.size() < 4) return fail("need at least 4 markers, have " + std::to_string(centres_mm.size()));
  if (!(radius_mm > 0)) return fail("marker radius must be > 0");
  for (const auto& c : centres_mm)
    if (!c.allFinite() || std::abs(c.z()) > 1e-9) return fail("marker centres must be finite and in the plane z = 0");
  return true;
}

Vec2d projected_disc_centroid(const CameraModel& camera, const ViewPose& pose, const Vec3d& centre_mm,
                              double radius_mm) {
  const auto outline = disc_outline(camera, pose, centre_mm, radius_mm, 256);
  if (outline.empty()) return camera.project(pose.to_camera(centre_mm));
  return polygon_area_centroid(outline).second;
}

Result<std::vector<Vec2d>> detect_markers(const cv::Mat& image, const CameraModel& camera, const ViewPose& rough_pose,
                                          const MarkerLayout& layout, const MarkerDetectionOptions& options) {
  std::string why;
  if (!camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera: " + why);
  if (!layout.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "marker layout: " + why);
  auto grey = to_grey_float(image);
  if (!grey) return grey.error();
  if (grey->cols != camera.width || grey->rows != camera.height)
    return make_error(ErrorCode::kInvalidArgument, "image size differs from the camera model's");
  std::vector<Vec2d> found;
  std::string failures;
  for (size_t k = 0; k < layout.centres_mm.size(); ++k) {
    const auto outline = disc_outline(camera, rough_pose, layout.centres_mm[k], layout.radius_mm, 64);
    Result<Vec2d> r = make_error(ErrorCode::kNotFound, "behind the camera at the rough pose");
    if (!outline.empty()) {
      const auto [area, centre] = polygon_area_centroid(outline);
      double radius = 0;
      for (const auto& p : outline) radius = std::max(radius, (p - centre).norm());
      if (centre.x() < -radius || centre.y() < -radius || centre.x() > camera.width - 1 + radius ||
          centre.y() > camera.height - 1 + radius) {
        r = make_error(ErrorCode::kNotFound, "projects outside the image");
      } else if (area < 3.0) {
        r = make_error(ErrorCode::kNotFound, "too small in the image (" + std::to_string(area) + " px^2)");
      } else {
        r = locate_marker(grey.value(), centre, area, radius, options);
      }
    }
    if (r) {
      found.push_back(r.value());
    } else {
      failures +=
          (failures.empty() ? "" : "; ") + std::string("marker ") + std::to_string(k) + ": " + r.error().message;
    }
  }
  if (!failures.empty())
    return make_error(ErrorCode::kNotFound, "found " + std::to_string(found.size()) + " of " +
                                                std::to_string(layout.centres_mm.size()) + " markers (" + failures +
                                                ")");
  return found;
}

Result<ViewExtrinsics> solve_view_extrinsics(const std::vector<Vec2d>& markers_px, const CameraModel& camera,
                                             const MarkerLayout& layout, const ExtrinsicsOptions& options) {
  std::string why;
  if (!camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "camera: " + why);
  if (!layout.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "marker layout: " + why);
  if (markers_px.size() != layout.centres_mm.size())
    return make_error(ErrorCode::kInvalidArgument, "have " + std::to_string(markers_px.size()) + " marker points for " +
                                                       std::to_string(layout.centres_mm.size()) + " markers");
  std::vector<cv::Point3d> object;
  for (const auto& c : layout.centres_mm) object.emplace_back(c.x(), c.y(), c.z());
  std::vector<cv::Point2d> targets;
  for (const auto& p : markers_px) targets.emplace_back(p.x(), p.y());
  const cv::Mat K = camera_matrix(camera), D = dist_coeffs(camera);
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(object, targets, K, D, rvec, tvec, false, cv::SOLVEPNP_IPPE))
    return make_error(ErrorCode::kInternal, "solvePnP (IPPE) found no pose");
  // IPPE is exact for a homography, not the reprojection optimum: refine with Levenberg-Marquardt, then (optionally)
  // move the targets by the centroid bias of the current pose and refine again.
  const int iterations = options.correct_centroid_bias ? std::max(1, options.bias_iterations) : 0;
  for (int it = 0; it <= iterations; ++it) {
    if (it > 0) {
      const ViewPose pose = pose_from_cv(rvec, tvec);
      for (size_t k = 0; k < object.size(); ++k) {
        const Vec3d& c = layout.centres_mm[k];
        const Vec2d bias =
            projected_disc_centroid(camera, pose, c, layout.radius_mm) - camera.project(pose.to_camera(c));
        targets[k] = {markers_px[k].x() - bias.x(), markers_px[k].y() - bias.y()};
      }
    }
    cv::solvePnPRefineLM(object, targets, K, D, rvec, tvec,
                         cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  }
  ViewExtrinsics out;
  out.pose = pose_from_cv(rvec, tvec);
  out.markers_px = markers_px;
  if (!(out.pose.t.z() > 0) || !out.pose.R.allFinite() || out.pose.view_direction(Vec3d::Zero()).z() <= 0)
    return make_error(ErrorCode::kInternal, "solvePnP found no pose with the surface facing the camera");
  double sq = 0;
  for (size_t k = 0; k < object.size(); ++k) {
    const Vec2d model = options.correct_centroid_bias
                            ? projected_disc_centroid(camera, out.pose, layout.centres_mm[k], layout.radius_mm)
                            : camera.project(out.pose.to_camera(layout.centres_mm[k]));
    sq += (model - markers_px[k]).squaredNorm();
  }
  out.reprojection_error_px = std::sqrt(sq / object.size());
  out.excluded = !(out.reprojection_error_px <= options.max_error_px);
  return out;
}

Result<ViewExtrinsics> calibrate_view(const cv::Mat& image, const CameraModel& camera, const ViewPose& rough_pose,
                                      const MarkerLayout& layout, const MarkerDetectionOptions& detection,
                                      const ExtrinsicsOptions& options) {
  auto markers = detect_markers(image, camera, rough_pose, layout, detection);
  if (!markers) return markers.error();
  return solve_view_extrinsics(markers.value(), camera, layout, options);
}

Vec3d rotation_to_rvec(const Mat3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

Mat3d rvec_to_rotation(const Vec3d& rvec) {
  const double angle = rvec.norm();
  if (angle < 1e-15) return Mat3d::Identity();
  return Eigen::AngleAxisd(angle, rvec / angle).toRotationMatrix();
}

nlohmann::json to_json(const ViewsFile& f) {
  nlohmann::json j;
  j["format_version"] = kViewsFormatVersion;
  j["camera"] = f.camera_file;
  j["max_error_px"] = f.max_error_px;
  j["exclude_unposed"] = f.exclude_unposed;
  j["marker_radius_mm"] = f.layout.radius_mm;
  j["marker_centres_mm"] = nlohmann::json::array();
  for (const auto& c : f.layout.centres_mm) j["marker_centres_mm"].push_back(vec_json(c));
  j["views"] = nlohmann::json::array();
  for (const auto& v : f.views) {
    nlohmann::json jv;
    jv["index"] = v.index;
    jv["pan_deg"] = rad_to_deg(v.measured.pan_rad);
    jv["tilt_deg"] = rad_to_deg(v.measured.tilt_rad);
    jv["ok"] = v.extrinsics.has_value();
    if (v.extrinsics) {
      const auto& e = *v.extrinsics;
      jv["rvec"] = vec_json(rotation_to_rvec(e.pose.R));
      jv["tvec_mm"] = vec_json(e.pose.t);
      jv["reprojection_error_px"] = e.reprojection_error_px;
      jv["excluded"] = e.excluded;
      jv["markers_px"] = nlohmann::json::array();
      for (const auto& p : e.markers_px) jv["markers_px"].push_back({p.x(), p.y()});
    } else {
      jv["excluded"] = true;
      jv["error"] = v.error;
    }
    j["views"].push_back(jv);
  }
  j["kinematics"] = f.kinematics;
  return j;
}

Result<ViewsFile> views_from_json(const nlohmann::json& j) {
  try {
    const int version = j.at("format_version").get<int>();
    if (version != kViewsFormatVersion)
      return make_error(ErrorCode::kCorrupt, "views.json format_version " + std::to_string(version) +
                                                 " (this build reads " + std::to_string(kViewsFormatVersion) + ")");
    ViewsFile f;
    f.camera_file = j.value("camera", "camera.yml");
    f.max_error_px = j.value("max_error_px", 1.0);
    f.exclude_unposed = j.value("exclude_unposed", false);
    f.layout.radius_mm = j.at("marker_radius_mm").get<double>();
    for (const auto& c : j.at("marker_centres_mm")) {
      auto v = vec_from_json(c, "marker centre");
      if (!v) return v.error();
      f.layout.centres_mm.push_back(v.value());
    }
    for (const auto& jv : j.at("views")) {
      ViewRecord r;
      r.index = jv.at("index").get<int>();
      r.measured = {deg_to_rad(jv.value("pan_deg", 0.0)), deg_to_rad(jv.value("tilt_deg", 0.0))};
      if (jv.at("ok").get<bool>()) {
        ViewExtrinsics e;
        auto rv = vec_from_json(jv.at("rvec"), "rvec");
        auto tv = vec_from_json(jv.at("tvec_mm"), "tvec_mm");
        if (!rv) return rv.error();
        if (!tv) return tv.error();
        e.pose.R = rvec_to_rotation(rv.value());
        e.pose.t = tv.value();
        e.reprojection_error_px = jv.at("reprojection_error_px").get<double>();
        e.excluded = jv.at("excluded").get<bool>();
        for (const auto& p : jv.value("markers_px", nlohmann::json::array()))
          e.markers_px.emplace_back(p.at(0).get<double>(), p.at(1).get<double>());
        r.extrinsics = e;
      } else {
        r.error = jv.value("error", "");
      }
      f.views.push_back(std::move(r));
    }
    f.kinematics = j.value("kinematics", nlohmann::json());
    return f;
  } catch (const nlohmann::json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("views.json: ") + e.what());
  }
}

Status write_views_json(const std::filesystem::path& path, const ViewsFile& file) {
  return write_file_atomic(path, to_json(file).dump(1));
}

Result<ViewsFile> read_views_json(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) return make_error(ErrorCode::kNotFound, "no " + path.string());
  auto j = read_json_file(path);
  if (!j) return j.error();
  auto f = views_from_json(j.value());
  if (!f) return make_error(ErrorCode::kCorrupt, path.string() + ": " + f.error().message);
  return f;
}

}  // namespace vdrig::calib
