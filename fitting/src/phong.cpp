#include "vdrig/fitting/phong.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

namespace vdrig::fitting {

Vec3d PhongParams::evaluate(const Vec3d& v) const {
  Vec3d out = kd;
  for (const PhongLobe& lobe : lobes) {
    const double c = v.dot(lobe.direction);
    if (c > 0.0) out += lobe.ks * std::pow(c, lobe.shininess);
  }
  return out;
}

bool PhongFitOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (lobes < 1 || lobes > 4) return fail("Phong lobes must be 1..4");
  if (!(max_shininess > 1.0)) return fail("max_shininess must be > 1");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(relative_floor > 0)) return fail("relative_floor must be > 0");
  return true;
}

namespace {

/// Residuals of one texel's Phong-K model over all its observations: one Ceres residual block per texel (3 residuals
/// per observation), automatic derivatives. Parameter block layout:
///   [Kd R G B] then per lobe k [Ks R G B, azimuth_k, zenith_k], then log(m) once (shared) or per lobe.
template <int K, bool kShared>
struct PhongTexelCost {
  static constexpr int kParams = 3 + 5 * K + (kShared ? 1 : K);

  const TexelObservations* obs;
  std::vector<double> weight;  // per observation and channel (3 each): 1 for absolute, 1/(|o|+floor) for relative

  template <typename T>
  bool operator()(const T* p, T* residuals) const {
    T dir[K][3];
    T m[K];
    for (int k = 0; k < K; ++k) {
      const T az = p[3 + 5 * k + 3], zen = p[3 + 5 * k + 4];
      const T sz = sin(zen);
      dir[k][0] = sz * cos(az);
      dir[k][1] = sz * sin(az);
      dir[k][2] = cos(zen);
      m[k] = exp(p[3 + 5 * K + (kShared ? 0 : k)]);
    }
    for (size_t i = 0; i < obs->size(); ++i) {
      const Eigen::Vector3f& v = obs->direction[i];
      T pred[3] = {p[0], p[1], p[2]};
      for (int k = 0; k < K; ++k) {
        const T c = dir[k][0] * double(v[0]) + dir[k][1] * double(v[1]) + dir[k][2] * double(v[2]);
        if (c > T(0.0)) {
          const T s = exp(m[k] * log(c));
          for (int ch = 0; ch < 3; ++ch) pred[ch] += p[3 + 5 * k + ch] * s;
        }
      }
      for (int ch = 0; ch < 3; ++ch)
        residuals[3 * i + ch] = (pred[ch] - double(obs->radiance[i][ch])) * weight[3 * i + ch];
    }
    return true;
  }
};

double luminance(const Eigen::Vector3f& rgb) { return rgb[0] + rgb[1] + rgb[2]; }

/// Linear least squares of o_i = kd + ks s_i for one channel with kd, ks >= 0. Returns the squared error.
double fit_two_terms(const std::vector<double>& s, const std::vector<double>& o, double* kd, double* ks) {
  const double n = static_cast<double>(s.size());
  double ss = 0, so = 0, s1 = 0, o1 = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    ss += s[i] * s[i];
    so += s[i] * o[i];
    s1 += s[i];
    o1 += o[i];
  }
  const double det = n * ss - s1 * s1;
  double a = o1 / n, b = 0;
  if (std::abs(det) > 1e-12 * std::max(1.0, n * ss)) {
    a = (ss * o1 - s1 * so) / det;
    b = (n * so - s1 * o1) / det;
  }
  if (b < 0) {
    b = 0;
    a = o1 / n;
  }
  if (a < 0) {
    a = 0;
    b = ss > 0 ? std::max(0.0, so / ss) : 0.0;
  }
  double err = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const double r = a + b * s[i] - o[i];
    err += r * r;
  }
  *kd = a;
  *ks = b;
  return err;
}

/// Adds a lobe at the direction of the largest residual of `base` and picks Kd, Ks_new, m by a coarse search.
void initialise_lobe(const TexelObservations& obs, const PhongFitOptions& opt, PhongParams* params) {
  // Residual of the current model (without a new lobe) per observation, as luminance.
  size_t peak = 0;
  double best = -1e300;
  for (size_t i = 0; i < obs.size(); ++i) {
    const double r = luminance(obs.radiance[i]) - params->evaluate(obs.direction[i].cast<double>()).sum();
    if (r > best) {
      best = r;
      peak = i;
    }
  }
  Vec3d r0 = obs.direction[peak].cast<double>().normalized();
  if (r0.z() < 1e-3) r0 = Vec3d(r0.x(), r0.y(), 1e-3).normalized();
  std::vector<double> s(obs.size()), o(obs.size());
  double best_err = 1e300;
  PhongLobe best_lobe;
  Vec3d best_kd = params->kd;
  for (double m = 1.0; m <= opt.max_shininess; m *= 1.5) {
    for (size_t i = 0; i < obs.size(); ++i) {
      const double c = obs.direction[i].cast<double>().dot(r0);
      s[i] = c > 0 ? std::pow(c, m) : 0.0;
    }
    double err = 0;
    Vec3d kd, ks;
    for (int ch = 0; ch < 3; ++ch) {
      // Fit against what the existing lobes leave unexplained.
      for (size_t i = 0; i < obs.size(); ++i) {
        double others = 0;
        for (const auto& l : params->lobes) {
          const double c = obs.direction[i].cast<double>().dot(l.direction);
          if (c > 0) others += l.ks[ch] * std::pow(c, l.shininess);
        }
        o[i] = obs.radiance[i][ch] - others;
      }
      err += fit_two_terms(s, o, &kd[ch], &ks[ch]);
    }
    if (err < best_err) {
      best_err = err;
      best_lobe = {ks, r0, m};
      best_kd = kd;
    }
  }
  params->kd = best_kd;
  params->lobes.push_back(best_lobe);
}

template <int K, bool kShared>
PhongFit solve(const TexelObservations& obs, const PhongFitOptions& opt, const PhongParams& init) {
  using Cost = PhongTexelCost<K, kShared>;
  std::vector<double> p(Cost::kParams);
  for (int c = 0; c < 3; ++c) p[c] = std::max(0.0, init.kd[c]);
  for (int k = 0; k < K; ++k) {
    const PhongLobe& l = init.lobes[k];
    for (int c = 0; c < 3; ++c) p[3 + 5 * k + c] = std::max(0.0, l.ks[c]);
    const SphericalDir sd = spherical_from_direction(l.direction);
    p[3 + 5 * k + 3] = sd.azimuth_rad;
    p[3 + 5 * k + 4] = std::min(sd.zenith_rad, kPi / 2);
    if (kShared && k > 0) continue;
    p[3 + 5 * K + (kShared ? 0 : k)] = std::log(std::clamp(l.shininess, 1.0, opt.max_shininess));
  }
  auto* functor = new Cost{&obs, std::vector<double>(3 * obs.size(), 1.0)};
  if (opt.residual == ResidualMode::kRelative)
    for (size_t i = 0; i < obs.size(); ++i)
      for (int c = 0; c < 3; ++c)
        functor->weight[3 * i + c] = 1.0 / (std::abs(obs.radiance[i][c]) + opt.relative_floor);
  ceres::Problem problem;
  auto* cost =
      new ceres::AutoDiffCostFunction<Cost, ceres::DYNAMIC, Cost::kParams>(functor, static_cast<int>(3 * obs.size()));
  problem.AddResidualBlock(cost, nullptr, p.data());
  for (int c = 0; c < 3; ++c) problem.SetParameterLowerBound(p.data(), c, 0.0);
  for (int k = 0; k < K; ++k) {
    for (int c = 0; c < 3; ++c) problem.SetParameterLowerBound(p.data(), 3 + 5 * k + c, 0.0);
    problem.SetParameterLowerBound(p.data(), 3 + 5 * k + 4, 0.0);
    problem.SetParameterUpperBound(p.data(), 3 + 5 * k + 4, kPi / 2);
  }
  for (int j = 3 + 5 * K; j < Cost::kParams; ++j) {
    problem.SetParameterLowerBound(p.data(), j, 0.0);
    problem.SetParameterUpperBound(p.data(), j, std::log(opt.max_shininess));
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = opt.max_iterations;
  so.num_threads = 1;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  PhongFit fit;
  for (int c = 0; c < 3; ++c) fit.params.kd[c] = p[c];
  for (int k = 0; k < K; ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) l.ks[c] = p[3 + 5 * k + c];
    l.direction = direction_from_spherical(p[3 + 5 * k + 3], p[3 + 5 * k + 4]);
    l.shininess = std::exp(p[3 + 5 * K + (kShared ? 0 : k)]);
    fit.params.lobes.push_back(l);
  }
  fit.cost = summary.final_cost;
  fit.converged = summary.termination_type == ceres::CONVERGENCE;
  fit.quality = measure_quality(fit.params, obs);
  return fit;
}

template <int K>
PhongFit solve_k(const TexelObservations& obs, const PhongFitOptions& opt, const PhongParams& init) {
  return opt.shared_shininess ? solve<K, true>(obs, opt, init) : solve<K, false>(obs, opt, init);
}

}  // namespace

PhongFit fit_phong(const TexelObservations& obs, const PhongFitOptions& opt) {
  std::string why;
  VDRIG_CHECK(opt.is_valid(&why), why);
  const size_t params = 3 + 5 * opt.lobes + (opt.shared_shininess ? 1 : opt.lobes);
  if (obs.size() * 3 < params + 3) {
    PhongFit fit;
    for (size_t i = 0; i < obs.size(); ++i) fit.params.kd += obs.radiance[i].cast<double>() / obs.size();
    fit.quality = measure_quality(fit.params, obs);
    return fit;
  }
  PhongParams init;
  PhongFit fit;
  for (int k = 1; k <= opt.lobes; ++k) {
    // Lobe k starts at the residual peak of the (k-1)-lobe fit.
    initialise_lobe(obs, opt, &init);
    if (opt.shared_shininess)
      for (auto& l : init.lobes) l.shininess = init.lobes.front().shininess;
    switch (k) {
      case 1:
        fit = solve_k<1>(obs, opt, init);
        break;
      case 2:
        fit = solve_k<2>(obs, opt, init);
        break;
      case 3:
        fit = solve_k<3>(obs, opt, init);
        break;
      default:
        fit = solve_k<4>(obs, opt, init);
        break;
    }
    init = fit.params;
  }
  return fit;
}

}  // namespace vdrig::fitting
