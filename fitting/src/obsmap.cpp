#include "vdrig/fitting/obsmap.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core/utility.hpp>

#include "vdrig/core/geometry.hpp"

namespace vdrig::fitting {

bool ObservationMapSpec::is_valid(std::string* why) const {
  if (texels_s < 1 || texels_t < 1) {
    if (why) *why = "observation map needs at least 1x1 texels";
    return false;
  }
  if (!(width_mm > 0) || !(height_mm > 0)) {
    if (why) *why = "surface size must be positive";
    return false;
  }
  return true;
}

ObservationMap::ObservationMap(const ObservationMapSpec& spec, int views) : spec_(spec), views_(views) {
  std::string why;
  VDRIG_CHECK(spec.is_valid(&why), why);
  VDRIG_CHECK(views >= 0, "view count must be >= 0");
  const size_t n = static_cast<size_t>(spec.texels_s) * spec.texels_t * views;
  radiance_.assign(3 * n, 0.0f);
  direction_.assign(3 * n, 0.0f);
  flags_.assign(n, kObsOutside);
}

void ObservationMap::set(int s, int t, int view, const Eigen::Vector3f& rgb, const Eigen::Vector3f& dir, uint8_t flag) {
  const size_t i = index(s, t, view);
  for (int c = 0; c < 3; ++c) {
    radiance_[3 * i + c] = rgb[c];
    direction_[3 * i + c] = dir[c];
  }
  flags_[i] = flag;
}

TexelObservations ObservationMap::texel(int s, int t, const std::vector<int>& held_out) const {
  TexelObservations out;
  const size_t base = index(s, t, 0);
  for (int v = 0; v < views_; ++v) {
    if (flags_[base + v] != kObsValid) continue;
    if (!held_out.empty() && std::binary_search(held_out.begin(), held_out.end(), v)) continue;
    const size_t i = base + v;
    out.direction.emplace_back(direction_[3 * i], direction_[3 * i + 1], direction_[3 * i + 2]);
    out.radiance.emplace_back(radiance_[3 * i], radiance_[3 * i + 1], radiance_[3 * i + 2]);
    out.view.push_back(v);
  }
  return out;
}

bool sample_bilinear(const cv::Mat& img, double x, double y, Eigen::Vector3f* rgb) {
  if (!(x >= 0.0) || !(y >= 0.0) || x > img.cols - 1 || y > img.rows - 1) return false;
  const int x0 = std::min(static_cast<int>(x), img.cols - 2 < 0 ? 0 : img.cols - 2);
  const int y0 = std::min(static_cast<int>(y), img.rows - 2 < 0 ? 0 : img.rows - 2);
  const int x1 = std::min(x0 + 1, img.cols - 1), y1 = std::min(y0 + 1, img.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const cv::Vec3f a = img.at<cv::Vec3f>(y0, x0), b = img.at<cv::Vec3f>(y0, x1);
  const cv::Vec3f c = img.at<cv::Vec3f>(y1, x0), d = img.at<cv::Vec3f>(y1, x1);
  const cv::Vec3f v = (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy;
  *rgb = Eigen::Vector3f(v[2], v[1], v[0]);
  return true;
}

uint8_t ObservationMap::observation(int s, int t, int view, Eigen::Vector3f* rgb, Eigen::Vector3f* dir) const {
  const size_t i = index(s, t, view);
  *rgb = Eigen::Vector3f(radiance_[3 * i], radiance_[3 * i + 1], radiance_[3 * i + 2]);
  *dir = Eigen::Vector3f(direction_[3 * i], direction_[3 * i + 1], direction_[3 * i + 2]);
  return flags_[i];
}

double pixel_footprint_mm(const CameraModel& camera, const ViewPose& pose, const Vec3d& p_mm) {
  const Vec3d pc = pose.to_camera(p_mm);
  if (!(pc.z() > 0.0)) return std::numeric_limits<double>::infinity();
  // d(pixel) / d(surface x, y) by central differences over a step small against any footprint (0.01 mm), large
  // against round-off at rig distances (metres).
  constexpr double kStepMm = 0.01;
  const Vec2d dx = (camera.project(pose.to_camera(p_mm + Vec3d(kStepMm, 0, 0))) -
                    camera.project(pose.to_camera(p_mm - Vec3d(kStepMm, 0, 0)))) /
                   (2 * kStepMm);
  const Vec2d dy = (camera.project(pose.to_camera(p_mm + Vec3d(0, kStepMm, 0))) -
                    camera.project(pose.to_camera(p_mm - Vec3d(0, kStepMm, 0)))) /
                   (2 * kStepMm);
  // Singular values of the 2x2 J = [dx dy]: s^2 = (q +- sqrt(q^2 - 4 det^2)) / 2, q = |J|_F^2. The smallest pixel
  // change per mm is the longest mm per pixel.
  const double q = dx.squaredNorm() + dy.squaredNorm();
  const double det = dx.x() * dy.y() - dx.y() * dy.x();
  const double s_min2 = 0.5 * (q - std::sqrt(std::max(0.0, q * q - 4.0 * det * det)));
  // det^2 / s_max^2 is the same value computed without cancellation when s_min << s_max (grazing).
  const double s_max2 = q - s_min2;
  const double s_min = s_max2 > 0.0 ? std::abs(det) / std::sqrt(s_max2) : 0.0;
  return s_min > 0.0 ? 1.0 / s_min : std::numeric_limits<double>::infinity();
}

uint8_t observe_texel(const ObservationMapSpec& spec, const ViewInput& in, int s, int t, Eigen::Vector3f* rgb,
                      Eigen::Vector3f* dir) {
  const Vec3d p = texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  *dir = (in.pose.camera_centre() - p).normalized().cast<float>();
  *rgb = Eigen::Vector3f::Zero();
  if (in.excluded) return kObsExcluded;
  if (dir->z() <= 0.0f) return kObsBackFacing;
  const Vec3d pc = in.pose.to_camera(p);
  if (pc.z() <= 0.0) return kObsOutside;
  const Vec2d px = in.camera.project(pc);
  if (!sample_bilinear(in.radiance_bgr, px.x(), px.y(), rgb)) {
    // sample_bilinear may have left nothing or garbage: an unusable observation carries zero radiance.
    *rgb = Eigen::Vector3f::Zero();
    return kObsOutside;
  }
  // A sample blending more of the surface than the texel (or, on a map finer than the camera resolves, than the
  // camera resolves square-on) is not an observation of this texel (kMaxFootprintTexels).
  const double texel_mm = std::min(spec.width_mm / spec.texels_s, spec.height_mm / spec.texels_t);
  const double square_on_mm = pc.norm() / std::sqrt(in.camera.fx * in.camera.fy);
  if (pixel_footprint_mm(in.camera, in.pose, p) >
      std::max(kMaxFootprintTexels * texel_mm, kMaxFootprintStretch * square_on_mm)) {
    *rgb = Eigen::Vector3f::Zero();
    return kObsCoarse;
  }
  if (!in.clip_mask.empty()) {
    const int xi = static_cast<int>(std::lround(px.x())), yi = static_cast<int>(std::lround(px.y()));
    if (in.clip_mask.at<uint8_t>(yi, xi) != 0) return kObsClipped;
  }
  return kObsValid;
}

void add_view(ObservationMap& map, int view, const ViewInput& in) {
  VDRIG_CHECK(in.radiance_bgr.type() == CV_32FC3, "view radiance must be CV_32FC3");
  VDRIG_CHECK(view >= 0 && view < map.views(), "view index out of range");
  const ObservationMapSpec& spec = map.spec();
  cv::parallel_for_(cv::Range(0, spec.texels_t), [&](const cv::Range& rows) {
    for (int t = rows.start; t < rows.end; ++t)
      for (int s = 0; s < spec.texels_s; ++s) {
        Eigen::Vector3f rgb, dir;
        const uint8_t flag = observe_texel(spec, in, s, t, &rgb, &dir);
        map.set(s, t, view, rgb, dir, flag);
      }
  });
}

}  // namespace vdrig::fitting
