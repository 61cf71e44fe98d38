#include "vdrig/probe/fusion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "vdrig/core/log.hpp"

namespace vdrig::probe {
namespace {

std::string vec_text(const Vec3d& v) {
  return std::to_string(v.x()) + "," + std::to_string(v.y()) + "," + std::to_string(v.z());
}

// Largest stored depth among the four pixels around direction `dir_probe` (probe frame); same pixel-centre
// convention as radiance_at (centres at integers, azimuth wraps, zenith clamps). The largest, not the bilinear
// blend, so that a depth edge (or the ridge at a room corner) does not make a visible point look occluded.
double max_depth_around(const cv::Mat& depth, const Vec3d& dir_probe) {
  const int W = depth.cols, H = depth.rows;
  const SphericalDir s = spherical_from_direction(dir_probe);
  const double x = s.azimuth_rad / (2.0 * kPi) * W - 0.5;
  const double y = std::clamp(s.zenith_rad / kPi * H - 0.5, 0.0, static_cast<double>(H - 1));
  int x0 = static_cast<int>(std::floor(x)) % W;
  if (x0 < 0) x0 += W;
  const int x1 = (x0 + 1) % W;
  const int y0 = static_cast<int>(std::floor(y)), y1 = std::min(y0 + 1, H - 1);
  return std::max({depth.at<float>(y0, x0), depth.at<float>(y0, x1), depth.at<float>(y1, x0), depth.at<float>(y1, x1)});
}

template <typename Proxy>
cv::Mat proxy_depth_impl(const Probe& probe, const Proxy& proxy) {
  const int W = probe.width(), H = probe.height();
  cv::Mat depth(H, W, CV_32FC1, cv::Scalar::all(0));
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const ProxyHit h =
          intersect_from_inside(proxy, probe.position_mm, probe.rotation * latlong_direction(i, j, W, H));
      if (h.hit) depth.at<float>(j, i) = static_cast<float>(h.distance_mm);
    }
  return depth;
}

Error invalid(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, "probe fusion: " + m); }

}  // namespace

bool ProxyBox::is_valid(std::string* why) const {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(min_mm[k]) || !std::isfinite(max_mm[k]) || !(min_mm[k] < max_mm[k])) {
      if (why)
        *why =
            "proxy box needs finite min < max on every axis, got min " + vec_text(min_mm) + " max " + vec_text(max_mm);
      return false;
    }
  return true;
}

bool ProxyBox::contains(const Vec3d& p, double margin_mm) const {
  for (int k = 0; k < 3; ++k)
    if (!(p[k] > min_mm[k] + margin_mm && p[k] < max_mm[k] - margin_mm)) return false;
  return true;
}

ProxyHit intersect_from_inside(const ProxyBox& box, const Vec3d& origin, const Vec3d& dir) {
  ProxyHit h;
  const double n = dir.norm();
  if (!(n > 0) || !box.contains(origin)) return h;
  const Vec3d d = dir / n;
  double best = std::numeric_limits<double>::infinity();
  int axis = -1;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0) continue;
    const double t = ((d[k] > 0 ? box.max_mm[k] : box.min_mm[k]) - origin[k]) / d[k];
    if (t < best) {
      best = t;
      axis = k;
    }
  }
  if (axis < 0) return h;
  h.hit = true;
  h.distance_mm = best;
  h.point_mm = origin + best * d;
  h.normal = Vec3d::Zero();
  h.normal[axis] = d[axis] > 0 ? -1.0 : 1.0;
  return h;
}

ProxyHit intersect_from_inside(const ProxySphere& sphere, const Vec3d& origin, const Vec3d& dir) {
  ProxyHit h;
  const double n = dir.norm();
  const Vec3d oc = origin - sphere.centre_mm;
  const double c = oc.squaredNorm() - sphere.radius_mm * sphere.radius_mm;
  if (!(n > 0) || !(c < 0)) return h;  // c < 0: strictly inside
  const Vec3d d = dir / n;
  const double b = d.dot(oc);
  const double t = -b + std::sqrt(b * b - c);  // the positive root; b^2 - c > 0 since c < 0
  h.hit = true;
  h.distance_mm = t;
  h.point_mm = origin + t * d;
  h.normal = (sphere.centre_mm - h.point_mm) / sphere.radius_mm;
  return h;
}

cv::Mat proxy_depth(const Probe& probe, const ProxyBox& box) { return proxy_depth_impl(probe, box); }
cv::Mat proxy_depth(const Probe& probe, const ProxySphere& sphere) { return proxy_depth_impl(probe, sphere); }

bool FusionOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (height < 0 || height > kMaxHeight)
    return fail("fusion height must be in [0, " + std::to_string(kMaxHeight) + "] rows (0: the probes'), got " +
                std::to_string(height));
  if (!(angular_exponent >= 0) || !std::isfinite(angular_exponent))
    return fail("angular exponent must be finite and >= 0, got " + std::to_string(angular_exponent));
  if (!(resolution_exponent >= 0) || !std::isfinite(resolution_exponent))
    return fail("resolution exponent must be finite and >= 0, got " + std::to_string(resolution_exponent));
  if (!(min_cosine >= -1.0 && min_cosine < 1.0))
    return fail("min cosine must lie in [-1, 1), got " + std::to_string(min_cosine));
  if (!(min_distance_mm > 0) || !std::isfinite(min_distance_mm))
    return fail("min distance must be > 0 mm, got " + std::to_string(min_distance_mm));
  if (!(occlusion_tolerance >= 0) || !std::isfinite(occlusion_tolerance))
    return fail("occlusion tolerance must be >= 0, got " + std::to_string(occlusion_tolerance));
  return true;
}

namespace {

// One source's contribution to the direction `dir` leaving new_position_mm, whose ray meets the proxy at h (hit):
// the source's radiance at the wall point and its fusion weight there (0: the source does not see the point). The
// one place the weights are computed; reproject(), fused_radiance() and the GPU fusion (probe_gl) follow it.
struct SourceSample {
  double weight = 0;
  Rgb radiance = Rgb::Zero();
};

SourceSample source_sample(const Probe& source, const Mat3d& to_source, const ProxyHit& h, const Vec3d& dir,
                           const FusionOptions& options) {
  SourceSample out;
  const Vec3d to_src = source.position_mm - h.point_mm;
  const double d_src = to_src.norm();
  if (!(d_src >= options.min_distance_mm)) return out;
  const Vec3d w_src = to_src / d_src;  // from the wall point toward the source
  const double cos_src = w_src.dot(h.normal);
  if (!(cos_src > 0)) return out;  // the source is behind this wall
  const Vec3d dir_src = to_source * (-w_src);
  if (source.has_depth() && d_src > max_depth_around(source.depth_mm, dir_src) * (1.0 + options.occlusion_tolerance))
    return out;              // something nearer hides the point from the source (thesis eq. 5.4)
  const Vec3d w_new = -dir;  // from the wall point toward the new position
  const double agreement = w_new.dot(w_src);
  if (agreement < options.min_cosine) return out;
  double weight_here = 1.0;
  if (options.angular_exponent > 0) weight_here *= std::pow(0.5 * (1.0 + agreement), options.angular_exponent);
  if (options.resolution_exponent > 0) {
    const double cos_new = std::max(w_new.dot(h.normal), 1e-9);
    const double rho = (h.distance_mm * h.distance_mm * cos_src) / (d_src * d_src * cos_new);
    weight_here *= std::pow(std::min(1.0, rho), options.resolution_exponent);
  }
  if (!(weight_here > 0)) return out;
  out.weight = weight_here;
  out.radiance = radiance_at(source, dir_src);
  return out;
}

}  // namespace

Status validate_fusion_inputs(const std::vector<Probe>& probes, const ProxyBox& box, const FusionOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) return invalid(why);
  if (!box.is_valid(&why)) return invalid(why);
  if (probes.empty()) return invalid("no probes to fuse");
  for (size_t k = 0; k < probes.size(); ++k) {
    const Probe& p = probes[k];
    if (p.radiance.empty() || p.radiance.type() != CV_32FC3 || p.width() != 2 * p.height())
      return invalid("probe " + std::to_string(k) + " is not a 2:1 CV_32FC3 lat-long map");
    if (p.width() != probes[0].width())
      return invalid("probes differ in size: probe 0 is " + std::to_string(probes[0].width()) + " x " +
                     std::to_string(probes[0].height()) + ", probe " + std::to_string(k) + " is " +
                     std::to_string(p.width()) + " x " + std::to_string(p.height()));
    if (p.has_depth() && (p.depth_mm.type() != CV_32FC1 || p.depth_mm.size() != p.radiance.size()))
      return invalid("probe " + std::to_string(k) + " has a depth map that is not CV_32FC1 of the map's size");
    if (!box.contains(p.position_mm))
      return invalid("probe " + std::to_string(k) + " at " + vec_text(p.position_mm) + " mm is not inside the room");
  }
  return Status::ok();
}

namespace {

Status validate_position(const Vec3d& position_mm, const ProxyBox& box) {
  if (!box.contains(position_mm)) return invalid("position " + vec_text(position_mm) + " mm is not inside the room");
  return Status::ok();
}

}  // namespace

size_t nearest_probe(const std::vector<Probe>& probes, const Vec3d& position_mm) {
  size_t nearest = 0;
  for (size_t k = 1; k < probes.size(); ++k)
    if ((probes[k].position_mm - position_mm).norm() < (probes[nearest].position_mm - position_mm).norm()) nearest = k;
  return nearest;
}

Probe reproject(const Probe& source, const Vec3d& new_position_mm, const ProxyBox& box, int height, cv::Mat* weight,
                const FusionOptions& options) {
  std::string why;
  VDRIG_CHECK(box.is_valid(&why), why);
  VDRIG_CHECK(options.is_valid(&why), why);
  VDRIG_CHECK(height >= 1, "reprojection needs at least one row");
  Probe out = make_probe(height);
  out.position_mm = new_position_mm;
  const int W = out.width(), H = out.height();
  out.depth_mm = cv::Mat(H, W, CV_32FC1, cv::Scalar::all(0));
  cv::Mat w(H, W, CV_32FC1, cv::Scalar::all(0));
  const Mat3d to_source = source.rotation.transpose();  // world -> source probe frame
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const Vec3d dir = latlong_direction(i, j, W, H);
      const ProxyHit h = intersect_from_inside(box, new_position_mm, dir);
      if (!h.hit) continue;
      out.depth_mm.at<float>(j, i) = static_cast<float>(h.distance_mm);
      const SourceSample s = source_sample(source, to_source, h, dir, options);
      if (s.weight <= 0) continue;
      out.set_pixel(i, j, s.radiance);
      w.at<float>(j, i) = static_cast<float>(s.weight);
    }
  if (weight) *weight = w;
  return out;
}

Rgb fused_radiance(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box, const Vec3d& dir,
                   const FusionOptions& options, double* weight_sum) {
  VDRIG_CHECK(!probes.empty(), "fused_radiance needs probes");
  const Vec3d d = dir.normalized();
  const ProxyHit h = intersect_from_inside(box, position_mm, d);
  double wsum = 0;
  Rgb sum = Rgb::Zero();
  if (h.hit)
    for (const Probe& p : probes) {
      const SourceSample s = source_sample(p, p.rotation.transpose(), h, d, options);
      if (s.weight <= 0) continue;
      sum += s.weight * s.radiance;
      wsum += s.weight;
    }
  if (weight_sum) *weight_sum = wsum;
  if (wsum > 0) return sum / wsum;
  const Probe& nearest = probes[nearest_probe(probes, position_mm)];
  return radiance_at(nearest, nearest.rotation.transpose() * d);
}

Result<CubeMap> fuse_cube(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box, int size,
                          const FusionOptions& options, int* uncovered_texels) {
  VDRIG_TRY(validate_fusion_inputs(probes, box, options));
  VDRIG_TRY(validate_position(position_mm, box));
  if (size < 1) return invalid("cube size must be >= 1, got " + std::to_string(size));
  CubeMap cube = make_cube_map(size);
  int uncovered = 0;
  for (int f = 0; f < kCubeFaceCount; ++f)
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < size; ++i) {
        double wsum = 0;
        const Rgb c = fused_radiance(probes, position_mm, box,
                                     cube_direction(static_cast<CubeFace>(f), i + 0.5, j + 0.5, size), options, &wsum);
        if (!(wsum > 0)) ++uncovered;
        cube.set_texel(static_cast<CubeFace>(f), i, j, c);
      }
  if (uncovered_texels) *uncovered_texels = uncovered;
  return cube;
}

Result<Probe> fuse(const std::vector<Probe>& probes, const Vec3d& position_mm, const ProxyBox& box,
                   const FusionOptions& options, FusionStats* stats) {
  VDRIG_TRY(validate_fusion_inputs(probes, box, options));
  VDRIG_TRY(validate_position(position_mm, box));

  const int H = options.height > 0 ? options.height : probes[0].height(), W = 2 * H;
  cv::Mat sum(H, W, CV_64FC3, cv::Scalar::all(0)), wsum(H, W, CV_64FC1, cv::Scalar::all(0));
  std::vector<double> share(probes.size(), 0.0);
  Probe fused;
  for (size_t k = 0; k < probes.size(); ++k) {
    cv::Mat w;
    Probe r = reproject(probes[k], position_mm, box, H, &w, options);
    for (int j = 0; j < H; ++j) {
      const double sa = latlong_pixel_solid_angle(j, W, H);
      for (int i = 0; i < W; ++i) {
        const double wk = w.at<float>(j, i);
        if (wk <= 0) continue;
        const cv::Vec3f c = r.radiance.at<cv::Vec3f>(j, i);
        sum.at<cv::Vec3d>(j, i) += cv::Vec3d(c[0], c[1], c[2]) * wk;
        wsum.at<double>(j, i) += wk;
        share[k] += wk * sa;
      }
    }
    if (k == 0) fused = std::move(r);  // keeps the position and the proxy depth seen from position_mm
  }

  // Fallback for points no probe sees: the nearest probe along the same direction (distant-scene assumption).
  const size_t nearest = nearest_probe(probes, position_mm);
  const Mat3d to_nearest = probes[nearest].rotation.transpose();
  FusionStats s;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const double ws = wsum.at<double>(j, i);
      cv::Vec3f& out = fused.radiance.at<cv::Vec3f>(j, i);
      if (ws > 0) {
        const cv::Vec3d c = sum.at<cv::Vec3d>(j, i) / ws;
        out = cv::Vec3f(static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
      } else {
        const Rgb c = radiance_at(probes[nearest], to_nearest * latlong_direction(i, j, W, H));
        out = to_bgr(c);
        ++s.uncovered_pixels;
        s.uncovered_sr += latlong_pixel_solid_angle(j, W, H);
      }
    }
  double total = 0;
  for (double v : share) total += v;
  for (double& v : share) v = total > 0 ? v / total : 0.0;
  s.weight_share = std::move(share);
  if (s.uncovered_pixels > 0)
    vdrig::log::get("probe")->warn(
        "probe fusion at {} mm: {} pixels ({:.3f} sr) seen by no probe, filled from probe {}", vec_text(position_mm),
        s.uncovered_pixels, s.uncovered_sr, nearest);
  if (stats) *stats = std::move(s);
  return fused;
}

}  // namespace vdrig::probe
