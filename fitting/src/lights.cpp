#include "vdrig/fitting/lights.hpp"

#include "vdrig/fitting/light_uncertainty.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <random>

#include "vdrig/core/log.hpp"

namespace vdrig::fitting {

Vec3d mirror_direction_at(const EstimatedLight& light, const Vec3d& p_mm) {
  const Vec3d to_light = light.at_infinity ? light.direction : (light.position_mm - p_mm).normalized();
  return mirror_direction(to_light, Vec3d::UnitZ());
}

bool LightEstimationOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (max_lights < 1) return fail("max_lights must be >= 1");
  if (!(inlier_angle_rad > 0.0 && inlier_angle_rad < kPi / 2)) return fail("inlier_angle_rad must be in (0, pi/2)");
  if (min_inliers < 2) return fail("min_inliers must be >= 2");
  if (!(exclusion_angle_rad >= inlier_angle_rad && exclusion_angle_rad < kPi / 2))
    return fail("exclusion_angle_rad must be in [inlier_angle_rad, pi/2)");
  if (ransac_iterations < 1) return fail("ransac_iterations must be >= 1");
  if (!(max_distance_mm > 0.0) || !std::isfinite(max_distance_mm)) return fail("max_distance_mm must be > 0");
  if (!(min_elevation_rad >= 0.0 && min_elevation_rad < kPi / 2)) return fail("min_elevation_rad must be in [0, pi/2)");
  return true;
}

namespace {

struct Ray {
  Vec3d o, d;  // origin, unit direction toward the light
  double w;
};

/// The rays a light can explain: positive finite weight, finite origin, a direction of non-zero length (made unit)
/// rising at least min_elevation_rad above the surface plane.
std::vector<Ray> usable_rays(const std::vector<LobeRay>& rays_in, const LightEstimationOptions& opt) {
  std::vector<Ray> rays;
  const double min_z = std::sin(opt.min_elevation_rad);
  for (const LobeRay& r : rays_in) {
    const double n = r.toward_light.norm();
    if (!(r.weight > 0.0) || !std::isfinite(r.weight) || !r.origin_mm.allFinite() || !std::isfinite(n) || !(n > 0.0))
      continue;
    if (!(r.toward_light.z() / n >= min_z)) continue;
    rays.push_back({r.origin_mm, r.toward_light / n, r.weight});
  }
  return rays;
}

/// A light hypothesis: a point, or a direction (at infinity).
struct Model {
  bool infinite = false;
  Vec3d point = Vec3d::Zero();
  Vec3d dir = Vec3d::UnitZ();
};

/// Unit direction from the ray's origin toward the model, or zero when undefined (the origin is the point).
Vec3d toward(const Model& m, const Ray& r) {
  if (m.infinite) return m.dir;
  const Vec3d v = m.point - r.o;
  const double n = v.norm();
  return n > 0.0 ? Vec3d(v / n) : Vec3d::Zero();
}

std::vector<int> inliers_of(const Model& m, const std::vector<Ray>& rays, const std::vector<int>& pool,
                            double cos_threshold) {
  std::vector<int> out;
  for (int i : pool)
    if (rays[i].d.dot(toward(m, rays[i])) >= cos_threshold) out.push_back(i);
  return out;
}

double weight_of(const std::vector<Ray>& rays, const std::vector<int>& set) {
  double w = 0.0;
  for (int i : set) w += rays[i].w;
  return w;
}

Vec3d mean_direction(const std::vector<Ray>& rays, const std::vector<int>& set) {
  Vec3d s = Vec3d::Zero();
  for (int i : set) s += rays[i].w * rays[i].d;
  return s.normalized();
}

Vec3d centroid(const std::vector<Ray>& rays, const std::vector<int>& set) {
  Vec3d s = Vec3d::Zero();
  for (int i : set) s += rays[i].w * rays[i].o;
  return s / weight_of(rays, set);
}

/// 0.5 sum w |component of unit(P - o) across d|^2 (~ 0.5 sum w angle^2 for small angles), with its Gauss-Newton
/// normal equations when h/g are given. Rays whose origin is P contribute nothing.
double angular_cost(const std::vector<Ray>& rays, const std::vector<int>& set, const Vec3d& p, Mat3d* h, Vec3d* g) {
  if (h) {
    h->setZero();
    g->setZero();
  }
  double cost = 0.0;
  for (int i : set) {
    const Ray& r = rays[i];
    const Vec3d v = p - r.o;
    const double rho = v.norm();
    if (!(rho > 0.0)) continue;
    const Vec3d u = v / rho;
    // Residual: the part of u perpendicular to d, as 3 components (rank 2); its Jacobian (I - d d^T)(I - u u^T) / rho.
    const Mat3d across = Mat3d::Identity() - r.d * r.d.transpose();
    const Vec3d res = across * u;
    cost += 0.5 * r.w * res.squaredNorm();
    if (!h) continue;
    const Mat3d j = across * (Mat3d::Identity() - u * u.transpose()) / rho;
    *h += r.w * j.transpose() * j;
    *g += r.w * j.transpose() * res;
  }
  return cost;
}

/// The same cost for a direction (a light at infinity).
double angular_cost_direction(const std::vector<Ray>& rays, const std::vector<int>& set, const Vec3d& dir) {
  double cost = 0.0;
  for (int i : set) cost += 0.5 * rays[i].w * (dir - dir.dot(rays[i].d) * rays[i].d).squaredNorm();
  return cost;
}

/// Refines a model on `set`: the weighted linear least-squares point closest to the lines, then Levenberg-Marquardt
/// on the angular errors (the linear fit weighs far rays by their distance). At infinity when the lines do not meet
/// in front of the rays within max_distance_mm (or do not meet at all to working precision), or when the point
/// explains the rays no better than a direction does.
Model refine(const std::vector<Ray>& rays, const std::vector<int>& set, const LightEstimationOptions& opt) {
  Model at_infinity;
  at_infinity.infinite = true;
  at_infinity.dir = mean_direction(rays, set);
  Mat3d a = Mat3d::Zero();
  Vec3d b = Vec3d::Zero();
  for (int i : set) {
    const Mat3d across = Mat3d::Identity() - rays[i].d * rays[i].d.transpose();
    a += rays[i].w * across;
    b += rays[i].w * across * rays[i].o;
  }
  const Eigen::SelfAdjointEigenSolver<Mat3d> eig(a);
  if (!(eig.eigenvalues()[0] > 1e-14 * eig.eigenvalues()[2])) return at_infinity;  // parallel to working precision
  const Vec3d c = centroid(rays, set);
  // Beyond max_distance_mm, or where the rays point away from (the light would be behind the surface).
  auto too_far = [&](const Vec3d& p) {
    return !p.allFinite() || (p - c).norm() > opt.max_distance_mm || (p - c).dot(at_infinity.dir) <= 0.0;
  };
  Vec3d p = eig.eigenvectors() * (eig.eigenvectors().transpose() * b).cwiseQuotient(eig.eigenvalues());
  if (too_far(p)) return at_infinity;
  Mat3d h;
  Vec3d g;
  double cost = angular_cost(rays, set, p, &h, &g);
  double lambda = 1e-6;
  for (int it = 0; it < 20; ++it) {
    Mat3d damped = h;
    damped.diagonal() += lambda * h.diagonal().cwiseMax(1e-30);
    const Vec3d step = damped.ldlt().solve(-g);
    if (!step.allFinite()) break;
    const Vec3d p_new = p + step;
    const double new_cost = angular_cost(rays, set, p_new, nullptr, nullptr);
    if (new_cost < cost && !too_far(p_new)) {
      const bool done = step.norm() <= 1e-9 * (p.norm() + 1.0) || cost - new_cost <= 1e-14 * cost;
      p = p_new;
      cost = angular_cost(rays, set, p, &h, &g);
      lambda = std::max(lambda / 10.0, 1e-12);
      if (done) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e8) break;
    }
  }
  // Model selection: a point has one parameter more than a direction (its distance), which always lowers the cost a
  // little; keep it only when it lowers it by more than that parameter is worth (BIC over the 2 residuals per ray).
  // A far light seen through noise otherwise comes out as a point anywhere along the line of sight.
  const double cost_dir = angular_cost_direction(rays, set, at_infinity.dir);
  const double residuals = 2.0 * static_cast<double>(set.size());
  if (!(cost > 0.0) || residuals * std::log(cost_dir / cost) > std::log(residuals)) {
    Model m;
    m.point = p;
    m.dir = (p - c).normalized();
    return m;
  }
  return at_infinity;
}

}  // namespace

Result<std::vector<EstimatedLight>> estimate_point_lights(const std::vector<LobeRay>& rays_in,
                                                          const LightEstimationOptions& opt) {
  std::string why;
  if (!opt.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, why);
  const std::vector<Ray> rays = usable_rays(rays_in, opt);
  std::vector<EstimatedLight> lights;
  const size_t min_inliers = static_cast<size_t>(opt.min_inliers);
  if (rays.size() < std::max<size_t>(2, min_inliers)) return lights;

  const double cos_threshold = std::cos(opt.inlier_angle_rad);
  const double cos_exclusion = std::cos(std::max(opt.exclusion_angle_rad, opt.inlier_angle_rad));
  const double cos_parallel = std::cos(2.0 * opt.inlier_angle_rad);
  std::mt19937 rng(opt.seed);
  std::vector<int> pool(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) pool[i] = static_cast<int>(i);

  while (static_cast<int>(lights.size()) < opt.max_lights && pool.size() >= std::max<size_t>(2, min_inliers)) {
    std::uniform_int_distribution<size_t> pick(0, pool.size() - 1);
    Model best;
    std::vector<int> best_inliers;
    double best_weight = 0.0;
    for (int it = 0; it < opt.ransac_iterations; ++it) {
      const size_t a = pick(rng);
      size_t b = pick(rng);
      if (a == b) b = (b + 1) % pool.size();
      const Ray& r1 = rays[pool[a]];
      const Ray& r2 = rays[pool[b]];
      Model m;
      const double cos12 = r1.d.dot(r2.d);
      if (cos12 >= cos_parallel) {
        // Nearly parallel: the pair only says "far away, this way".
        m.infinite = true;
        m.dir = (r1.d + r2.d).normalized();
      } else {
        // Closest points o1 + t1 d1, o2 + t2 d2 of the two lines (unit directions).
        const Vec3d w0 = r1.o - r2.o;
        const double d1w = r1.d.dot(w0), d2w = r2.d.dot(w0), denom = 1.0 - cos12 * cos12;
        const double t1 = (cos12 * d2w - d1w) / denom, t2 = (d2w - cos12 * d1w) / denom;
        if (!(t1 > 0.0 && t2 > 0.0)) continue;  // the lines meet behind a texel: no light there
        m.point = 0.5 * (r1.o + t1 * r1.d + r2.o + t2 * r2.d);
      }
      std::vector<int> in = inliers_of(m, rays, pool, cos_threshold);
      const double w = weight_of(rays, in);
      if (w > best_weight || (w == best_weight && in.size() > best_inliers.size())) {
        best_weight = w;
        best = m;
        best_inliers = std::move(in);
      }
    }
    if (best_inliers.size() < min_inliers) break;

    // Refine on the inliers and re-collect them (a few rounds: the refined light can gather rays the hypothesis
    // missed, or lose some).
    std::vector<int> inliers = best_inliers;
    Model model = best;
    for (int round = 0; round < 4; ++round) {
      const Model refined = refine(rays, inliers, opt);
      std::vector<int> again = inliers_of(refined, rays, pool, cos_threshold);
      if (again.size() < min_inliers) break;
      model = refined;
      const bool same = again == inliers;
      inliers = std::move(again);
      if (same) break;
    }
    // The model must explain its final inliers (refine on exactly them once more if the last round changed them).
    model = refine(rays, inliers, opt);
    inliers = inliers_of(model, rays, pool, cos_threshold);
    if (inliers.size() < min_inliers) break;

    EstimatedLight light;
    light.at_infinity = model.infinite;
    light.position_mm = model.infinite ? Vec3d::Zero() : model.point;
    light.direction = model.dir;
    light.inliers = static_cast<int>(inliers.size());
    double sq = 0.0;
    for (int i : inliers) {
      const double ang = angle_between(rays[i].d, toward(model, rays[i]));
      sq += rays[i].w * ang * ang;
    }
    light.rms_angle_rad = std::sqrt(sq / weight_of(rays, inliers));
    lights.push_back(light);
    log::get("fitting")->debug("light {}: {} inliers, rms {:.3f} deg, {}", lights.size(), light.inliers,
                               rad_to_deg(light.rms_angle_rad), light.at_infinity ? "at infinity" : "point");

    // The light's inliers and its tail (rays within the exclusion angle) leave the pool.
    const std::vector<int> claimed = inliers_of(model, rays, pool, cos_exclusion);
    std::vector<int> rest;
    std::set_difference(pool.begin(), pool.end(), claimed.begin(), claimed.end(), std::back_inserter(rest));
    pool = std::move(rest);
  }
  std::stable_sort(lights.begin(), lights.end(),
                   [](const EstimatedLight& a, const EstimatedLight& b) { return a.inliers > b.inliers; });
  return lights;
}

Result<Mat3d> light_position_covariance(const std::vector<LobeRay>& rays_in, const EstimatedLight& light,
                                        const LightEstimationOptions& opt) {
  if (light.at_infinity) return make_error(ErrorCode::kInvalidArgument, "a light at infinity has no position");
  const std::vector<Ray> rays = usable_rays(rays_in, opt);
  std::vector<int> pool(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) pool[i] = static_cast<int>(i);
  Model m;
  m.point = light.position_mm;
  const std::vector<int> inliers = inliers_of(m, rays, pool, std::cos(opt.inlier_angle_rad));
  if (inliers.size() < 2) return make_error(ErrorCode::kInvalidArgument, "fewer than 2 rays explained by the light");
  Mat3d h;
  Vec3d g;
  const double cost = angular_cost(rays, inliers, light.position_mm, &h, &g);
  // Weighted residual variance per component: 2 cost = sum w |r|^2 over 2 components a ray, 3 parameters fitted.
  const double dof = std::max(1.0, 2.0 * static_cast<double>(inliers.size()) - 3.0);
  const double sigma2 = 2.0 * cost / dof;
  const Eigen::SelfAdjointEigenSolver<Mat3d> eig(h);
  if (!(eig.eigenvalues()[0] > 0.0)) return make_error(ErrorCode::kInvalidArgument, "the rays do not fix the position");
  return Mat3d(sigma2 * eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() *
               eig.eigenvectors().transpose());
}

}  // namespace vdrig::fitting
