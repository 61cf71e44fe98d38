#include "vdrig/fitting/phong.hpp"

#include "bounded_lm.hpp"
#include "vdrig/fitting/lobe_fit.hpp"
#include "vdrig/fitting/voronoi.hpp"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>

#include <fmt/format.h>

namespace vdrig::fitting {

Vec3d PhongParams::evaluate(const Vec3d& v) const {
  Vec3d out = kd;
  for (const PhongLobe& lobe : lobes) {
    const double c = v.dot(lobe.direction);
    if (c > 0.0) out += lobe.ks * std::pow(c, lobe.shininess);
  }
  return out;
}

std::string PhongFitOptions::fingerprint() const {
  // {} formats doubles as the shortest text that reads back to the same value: equal text, equal options.
  std::string s =
      fmt::format("lobes:{},solver:{},shared_m:{},max_m:{},iterations:{},residual:{},floor:{},fixed:", lobes,
                  static_cast<int>(solver), shared_shininess, max_shininess, max_iterations, static_cast<int>(residual),
                  relative_floor);
  for (const Vec3d& d : fixed_directions) s += fmt::format("{},{},{}/", d.x(), d.y(), d.z());
  return s + fmt::format(",support:{},significant:{},solid_angle:{}", lobe_support, significant_lobes_only,
                         solid_angle_weights);
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
  if (lobe_support < 0 || lobe_support > 64)
    return fail("lobe_support must be 0..64 observations, not " + std::to_string(lobe_support));
  if (!fixed_directions.empty()) {
    if (static_cast<int>(fixed_directions.size()) != lobes)
      return fail("fixed_directions must hold one direction per lobe (" + std::to_string(lobes) + "), not " +
                  std::to_string(fixed_directions.size()));
    for (size_t k = 0; k < fixed_directions.size(); ++k) {
      const Vec3d& d = fixed_directions[k];
      if (!d.allFinite() || std::abs(d.norm() - 1.0) > 1e-6)
        return fail("fixed_directions[" + std::to_string(k) + "] must be a unit vector (|d| - 1 within 1e-6)");
      if (d.z() < 0.0) return fail("fixed_directions[" + std::to_string(k) + "] is below the horizon (z < 0)");
    }
  }
  return true;
}

namespace {

/// The weights of the residuals as minimised, per observation and channel (3 each): 1 for absolute, 1 / (|o| +
/// floor) for relative, times sqrt(the observation's solid angle / its mean) with solid_angle_weights, so that the
/// sum of squares approximates the integral of the squared error over the hemisphere whatever the views' density.
/// The solid angle is the observation's spherical Voronoi cell (voronoi.hpp), capped at kMaxSolidAngleWeight times
/// the mean so that one lone view at the horizon does not carry the fit.
constexpr double kMaxSolidAngleWeight = 8.0;
std::vector<double> residual_weights(const TexelObservations& obs, const PhongFitOptions& opt) {
  std::vector<double> weight(3 * obs.size(), 1.0);
  if (opt.residual == ResidualMode::kRelative)
    for (size_t i = 0; i < obs.size(); ++i)
      for (int c = 0; c < 3; ++c) weight[3 * i + c] = 1.0 / (std::abs(obs.radiance[i][c]) + opt.relative_floor);
  if (opt.solid_angle_weights && obs.size() > 1) {
    std::vector<Vec3d> dirs(obs.size());
    for (size_t i = 0; i < obs.size(); ++i) dirs[i] = obs.direction[i].cast<double>();
    std::vector<double> area = hemisphere_voronoi_areas(dirs);
    double total = 0;
    for (double a : area) total += a;
    if (total > 0)
      for (size_t i = 0; i < obs.size(); ++i) {
        const double w = std::min(area[i] * static_cast<double>(obs.size()) / total, kMaxSolidAngleWeight);
        for (int c = 0; c < 3; ++c) weight[3 * i + c] *= std::sqrt(w);
      }
  }
  return weight;
}

/// Residuals of one texel's Phong-K model over all its observations (3 per observation) with analytic derivatives,
/// accumulated straight into the normal equations J^T J, J^T r (the Jacobian itself, 3N x P, is never stored).
/// Parameter layout:
///   [Kd R G B] then per lobe k [Ks R G B, azimuth_k, zenith_k], then log(m) once (shared) or per lobe.
/// Model per channel c: I_c = Kd_c + sum_k Ks_kc s_k, s_k = c_k^m_k, c_k = max(0, v . d_k), m_k = exp(L_k), so
///   dI/dKs_kc = s_k,  dI/d(az_k, zen_k) = Ks_kc m_k c_k^(m_k - 1) v . d(d_k)/d(az_k, zen_k),
///   dI/dL_k = Ks_kc s_k m_k ln c_k.
template <int K, bool kShared>
class PhongTexelCost {
 public:
  static constexpr int kParams = 3 + 5 * K + (kShared ? 1 : K);
  using Vec = Eigen::Matrix<double, kParams, 1>;
  using Mat = Eigen::Matrix<double, kParams, kParams>;

  PhongTexelCost(const TexelObservations* obs, std::vector<double> weight) : obs_(obs), weight_(std::move(weight)) {}

  /// 0.5 sum r^2 at p; with jtj/jtr also the normal equations (both overwritten).
  double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const {
    double dir[K][3], d_az[K][3], d_zen[K][3], m[K];
    for (int k = 0; k < K; ++k) {
      const double az = p[3 + 5 * k + 3], zen = p[3 + 5 * k + 4];
      const double sa = std::sin(az), ca = std::cos(az), sz = std::sin(zen), cz = std::cos(zen);
      dir[k][0] = sz * ca;
      dir[k][1] = sz * sa;
      dir[k][2] = cz;
      d_az[k][0] = -sz * sa;
      d_az[k][1] = sz * ca;
      d_az[k][2] = 0.0;
      d_zen[k][0] = cz * ca;
      d_zen[k][1] = cz * sa;
      d_zen[k][2] = -sz;
      m[k] = std::exp(p[3 + 5 * K + (kShared ? 0 : k)]);
    }
    if (jtj) {
      jtj->setZero();
      jtr->setZero();
    }
    double cost = 0.0;
    for (size_t i = 0; i < obs_->size(); ++i) {
      const Eigen::Vector3f& vf = obs_->direction[i];
      const double v[3] = {vf[0], vf[1], vf[2]};
      double pred[3] = {p[0], p[1], p[2]};
      double s[K], ds_daz[K], ds_dzen[K], ds_dl[K];
      for (int k = 0; k < K; ++k) {
        const double c = dir[k][0] * v[0] + dir[k][1] * v[1] + dir[k][2] * v[2];
        s[k] = ds_daz[k] = ds_dzen[k] = ds_dl[k] = 0.0;
        if (c > 0.0) {
          const double log_c = std::log(c);
          s[k] = std::exp(m[k] * log_c);
          if (jtj) {
            const double ds_dc = m[k] * s[k] / c;
            ds_daz[k] = ds_dc * (d_az[k][0] * v[0] + d_az[k][1] * v[1]);
            ds_dzen[k] = ds_dc * (d_zen[k][0] * v[0] + d_zen[k][1] * v[1] + d_zen[k][2] * v[2]);
            ds_dl[k] = s[k] * m[k] * log_c;
          }
        }
        for (int ch = 0; ch < 3; ++ch) pred[ch] += p[3 + 5 * k + ch] * s[k];
      }
      for (int ch = 0; ch < 3; ++ch) {
        const double w = weight_[3 * i + ch];
        const double r = (pred[ch] - obs_->radiance[i][ch]) * w;
        cost += 0.5 * r * r;
        if (!jtj) continue;
        // The row is sparse (Kd_c, and per lobe Ks_kc, azimuth, zenith, log m): accumulate only its non-zeros.
        constexpr int kNonZero = 1 + 3 * K + (kShared ? 1 : K);
        int idx[kNonZero];
        double val[kNonZero];
        int n = 0;
        idx[n] = ch;
        val[n++] = w;
        double dl_shared = 0.0;
        for (int k = 0; k < K; ++k) {
          const double ks = p[3 + 5 * k + ch];
          idx[n] = 3 + 5 * k + ch;
          val[n++] = w * s[k];
          idx[n] = 3 + 5 * k + 3;
          val[n++] = w * ks * ds_daz[k];
          idx[n] = 3 + 5 * k + 4;
          val[n++] = w * ks * ds_dzen[k];
          if (kShared) {
            dl_shared += w * ks * ds_dl[k];
          } else {
            idx[n] = 3 + 5 * K + k;
            val[n++] = w * ks * ds_dl[k];
          }
        }
        if (kShared) {
          idx[n] = 3 + 5 * K;
          val[n++] = dl_shared;
        }
        for (int a = 0; a < kNonZero; ++a) {
          (*jtr)[idx[a]] += r * val[a];
          for (int b = 0; b < kNonZero; ++b) (*jtj)(idx[a], idx[b]) += val[a] * val[b];
        }
      }
    }
    return cost;
  }

 private:
  const TexelObservations* obs_;
  std::vector<double> weight_;  // per observation and channel (3 each): 1 for absolute, 1/(|o|+floor) for relative
};

/// Adds a lobe at the direction of the largest residual of `params` and picks Kd, Ks_new, m by a coarse search
/// (lobe_fit.hpp). The per-observation quantities that do not depend on the candidate m (cosines, their logs, what
/// the existing lobes leave unexplained) are computed once; each candidate then costs one exp per lit observation.
void initialise_lobe(const TexelObservations& obs, const PhongFitOptions& opt, PhongParams* params) {
  const size_t n = obs.size();
  const LobeTarget target = lobe_target(obs, params->kd, [&](const Vec3d& d) {
    Vec3d others = Vec3d::Zero();
    for (const auto& l : params->lobes) {
      const double c = d.dot(l.direction);
      if (c > 0) others += l.ks * std::pow(c, l.shininess);
    }
    return others;
  });
  Vec3d r0 = lobe_start_direction(obs.direction[target.peak].cast<double>());
  if (!opt.fixed_directions.empty()) r0 = opt.fixed_directions[params->lobes.size()].normalized();
  std::vector<double> log_c(n);
  for (size_t i = 0; i < n; ++i) {
    const double c = obs.direction[i].cast<double>().dot(r0);
    log_c[i] = c > 0 ? std::log(c) : -std::numeric_limits<double>::infinity();
  }
  const LobeStart start =
      search_lobe_width(target, geometric_steps(1.0, opt.max_shininess, 1.5), [&](double m, std::vector<double>& s) {
        for (size_t i = 0; i < n; ++i) s[i] = std::exp(m * log_c[i]);  // exp(-inf) = 0 for unlit observations
      });
  if (std::isnan(start.width)) {  // no candidate fitted (non-finite observations): an empty lobe
    params->lobes.push_back(PhongLobe{});
    return;
  }
  params->kd = start.base;
  params->lobes.push_back({start.scale, r0, start.width});
}

/// The same residuals as PhongTexelCost, as a Ceres functor with automatic derivatives: one residual block per texel
/// (3 residuals per observation), one parameter block laid out as PhongTexelCost's. The reference solver (see
/// PhongSolver); bench_phong_fit runs both side by side.
template <int K, bool kShared>
struct PhongAutoDiffResiduals {
  static constexpr int kParams = 3 + 5 * K + (kShared ? 1 : K);
  const TexelObservations* obs;
  const std::vector<double>* weight;

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
        residuals[3 * i + ch] = (pred[ch] - double(obs->radiance[i][ch])) * (*weight)[3 * i + ch];
    }
    return true;
  }
};

template <int K, bool kShared, typename Vec>
bool minimise_with_ceres(const TexelObservations& obs, const std::vector<double>& weight, Vec& p, const Vec& lo,
                         const Vec& hi, const std::vector<int>& fixed, int max_iterations, double* final_cost) {
  using Functor = PhongAutoDiffResiduals<K, kShared>;
  constexpr int n = Functor::kParams;
  ceres::Problem problem;
  auto* cost = new ceres::AutoDiffCostFunction<Functor, ceres::DYNAMIC, n>(new Functor{&obs, &weight},
                                                                           static_cast<int>(3 * obs.size()));
  problem.AddResidualBlock(cost, nullptr, p.data());
  // Constant coordinates (fixed lobe directions) are left out of the tangent space; Ceres owns the manifold.
  if (!fixed.empty()) problem.SetManifold(p.data(), new ceres::SubsetManifold(n, fixed));
  for (int j = 0; j < n; ++j) {
    if (std::find(fixed.begin(), fixed.end(), j) != fixed.end()) continue;
    if (std::isfinite(lo[j])) problem.SetParameterLowerBound(p.data(), j, lo[j]);
    if (std::isfinite(hi[j])) problem.SetParameterUpperBound(p.data(), j, hi[j]);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  so.num_threads = 1;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  *final_cost = summary.final_cost;
  return summary.termination_type == ceres::CONVERGENCE;
}

/// One solve of K lobes from `init`; lobe k's shininess is at most min(max_shininess, m_cap[k]) (the smallest of the
/// K caps when m is shared).
template <int K, bool kShared>
PhongFit solve(const TexelObservations& obs, const PhongFitOptions& opt, const PhongParams& init,
               const std::array<double, 4>& m_cap) {
  using Cost = PhongTexelCost<K, kShared>;
  typename Cost::Vec p, lo, hi;
  lo.setZero();  // Kd, Ks >= 0, zenith >= 0, log(m) >= 0
  hi.setConstant(std::numeric_limits<double>::infinity());
  for (int c = 0; c < 3; ++c) p[c] = std::max(0.0, init.kd[c]);
  for (int k = 0; k < K; ++k) {
    const PhongLobe& l = init.lobes[k];
    for (int c = 0; c < 3; ++c) p[3 + 5 * k + c] = std::max(0.0, l.ks[c]);
    const SphericalDir sd = spherical_from_direction(l.direction);
    p[3 + 5 * k + 3] = sd.azimuth_rad;
    lo[3 + 5 * k + 3] = -std::numeric_limits<double>::infinity();  // azimuth is free
    p[3 + 5 * k + 4] = std::min(sd.zenith_rad, kPi / 2);
    hi[3 + 5 * k + 4] = kPi / 2;
    if (kShared && k > 0) continue;
    p[3 + 5 * K + (kShared ? 0 : k)] = std::log(std::clamp(l.shininess, 1.0, opt.max_shininess));
  }
  double shared_cap = opt.max_shininess;
  for (int k = 0; k < K; ++k) shared_cap = std::min(shared_cap, m_cap[static_cast<size_t>(k)]);
  for (int k = 0; k < (kShared ? 1 : K); ++k) {
    const double cap = kShared ? shared_cap : std::min(opt.max_shininess, m_cap[static_cast<size_t>(k)]);
    hi[3 + 5 * K + k] = std::log(std::max(1.0, cap));
  }
  // Fixed directions: (azimuth, zenith) of lobe k are constants (opt.fixed_directions holds at least K of them).
  Eigen::Matrix<bool, Cost::kParams, 1> fixed = Eigen::Matrix<bool, Cost::kParams, 1>::Constant(false);
  std::vector<int> fixed_indices;
  const bool fixed_dirs = !opt.fixed_directions.empty();
  if (fixed_dirs) {
    for (int k = 0; k < K; ++k) {
      const SphericalDir sd = spherical_from_direction(opt.fixed_directions[k]);
      p[3 + 5 * k + 3] = sd.azimuth_rad;
      p[3 + 5 * k + 4] = std::min(sd.zenith_rad, kPi / 2);
      for (int j : {3 + 5 * k + 3, 3 + 5 * k + 4}) {
        fixed[j] = true;
        fixed_indices.push_back(j);
      }
    }
  }
  std::vector<double> weight = residual_weights(obs, opt);
  PhongFit fit;
  if (opt.solver == PhongSolver::kCeres) {
    p = p.cwiseMax(lo).cwiseMin(hi);
    fit.converged =
        minimise_with_ceres<K, kShared>(obs, weight, p, lo, hi, fixed_indices, opt.max_iterations, &fit.cost);
  } else {
    const Cost cost(&obs, std::move(weight));
    fit.converged = minimise_bounded(cost, p, lo, hi, fixed, opt.max_iterations, &fit.cost);
  }

  for (int c = 0; c < 3; ++c) fit.params.kd[c] = p[c];
  for (int k = 0; k < K; ++k) {
    PhongLobe l;
    for (int c = 0; c < 3; ++c) l.ks[c] = p[3 + 5 * k + c];
    l.direction = fixed_dirs ? opt.fixed_directions[k].normalized()
                             : direction_from_spherical(p[3 + 5 * k + 3], p[3 + 5 * k + 4]);
    l.shininess = std::exp(p[3 + 5 * K + (kShared ? 0 : k)]);
    fit.params.lobes.push_back(l);
  }
  fit.quality = measure_quality(fit.params, obs);
  return fit;
}

template <int K>
PhongFit solve_k(const TexelObservations& obs, const PhongFitOptions& opt, const PhongParams& init,
                 const std::array<double, 4>& m_cap) {
  return opt.shared_shininess ? solve<K, true>(obs, opt, init, m_cap) : solve<K, false>(obs, opt, init, m_cap);
}

/// A lobe far below the diffuse level is the fit's way of saying "no highlight" (its direction and width are noise).
bool carries_energy(const PhongParams& params, const PhongLobe& lobe) {
  return lobe.ks.maxCoeff() > 1e-3 * std::max(params.kd.maxCoeff(), 1e-12);
}

/// The RMS of one residual of `params` over `obs` (per channel and observation, unweighted, over the degrees of
/// freedom left by a fit with `parameters` free parameters), floored at 1e-6 of the observations' RMS (float32
/// round-off): the noise a lobe is detected (LobeCountBic) or seen (phong_lobe_width_measured) against.
double fit_noise_rms(const TexelObservations& obs, const PhongParams& params, int parameters) {
  const int n = static_cast<int>(3 * obs.size());
  double sq = 0.0, observed = 0.0;
  for (size_t i = 0; i < obs.size(); ++i) {
    sq += (params.evaluate(obs.direction[i].cast<double>()) - obs.radiance[i].cast<double>()).squaredNorm();
    observed += obs.radiance[i].cast<double>().squaredNorm();
  }
  return std::max(std::sqrt(sq / std::max(1, n - parameters)), 1e-6 * std::sqrt(observed / std::max(1, n)));
}

/// Solves K lobes, then caps the shininess of every lobe that the observations do not support (fewer than
/// opt.lobe_support of them inside its support cone: phong_support_cap at the lobe's fitted direction) and solves
/// again from there, until every lobe is supported. A capped lobe may move, which changes its cap: the caps only ever
/// tighten, and after kRounds rounds the lobes are held where they are for a last solve under their caps, so every
/// returned lobe is supported.
template <int K>
PhongFit solve_supported(const TexelObservations& obs, const PhongFitOptions& opt, const PhongParams& init) {
  constexpr int kRounds = 4;
  std::array<double, 4> cap;
  cap.fill(std::numeric_limits<double>::infinity());
  PhongFit fit = solve_k<K>(obs, opt, init, cap);
  if (opt.lobe_support <= 0) return fit;
  if (!opt.fixed_directions.empty()) {
    // A lobe held at a known direction (the lights' mirror directions, estimated over the whole map) is not placed by
    // this texel's observations, and where they see it on its flanks they measure its width: it is not capped. But
    // where fewer than lobe_support observations see it above the noise, its width is not measured -- Ks and m
    // trade along Ks c^m = what one view saw -- and the solve runs to a peak nothing saw (m in the thousands, Ks in
    // the hundreds, docs/models.md): such a lobe is capped as a free lobe is (both rules of phong_support_cap).
    // Where lobe_support observations do see it, they measure its width only if they see it at different heights on
    // its flank (m = ln(I1 / I2) / ln(c1 / c2)): views at about the same cosine, or a residual so small that a far
    // flank counts as seen, leave Ks and m trading again, and the solve ran to m 1866, Ks 9e8 from two views at cos
    // 0.9881 and 0.9880 that saw 0.21 and 0.16 of it (lights2 adaptive:60 seed 2). Such a lobe is capped too
    // (phong_lobe_width_measured).
    const double noise_rms =
        fit_noise_rms(obs, fit.params, phong_parameter_count(K, opt.shared_shininess, /*fixed_directions=*/true));
    bool unsupported = false;
    for (int k = 0; k < K; ++k) {
      const PhongLobe& lobe = fit.params.lobes[static_cast<size_t>(k)];
      if (!carries_energy(fit.params, lobe)) continue;
      double& c = cap[static_cast<size_t>(k)];
      if (phong_lobe_width_measured(obs, lobe, noise_rms, opt.lobe_support)) continue;
      c = phong_support_cap(obs, lobe.direction, opt.lobe_support);
      if (lobe.shininess > c * (1.0 + 1e-6)) unsupported = true;
    }
    if (unsupported) fit = solve_k<K>(obs, opt, fit.params, cap);
    for (int k = 0; k < K; ++k) {
      const PhongLobe& lobe = fit.params.lobes[static_cast<size_t>(k)];
      if (carries_energy(fit.params, lobe) && lobe.shininess >= cap[static_cast<size_t>(k)] * (1.0 - 1e-6))
        ++fit.capped_lobes;
    }
    return fit;
  }
  for (int round = 0; round <= kRounds; ++round) {
    bool unsupported = false;
    for (int k = 0; k < K; ++k) {
      const PhongLobe& lobe = fit.params.lobes[static_cast<size_t>(k)];
      if (!carries_energy(fit.params, lobe)) continue;
      double& c = cap[static_cast<size_t>(k)];
      c = std::min(c, phong_support_cap(obs, lobe.direction, opt.lobe_support));
      if (lobe.shininess > c * (1.0 + 1e-6)) unsupported = true;
    }
    if (!unsupported) break;
    if (round == kRounds) {
      // Still drifting: hold the lobes where they are and solve Kd, Ks and m under the caps there.
      PhongFitOptions held = opt;
      held.fixed_directions.clear();
      for (const PhongLobe& lobe : fit.params.lobes) held.fixed_directions.push_back(lobe.direction.normalized());
      fit = solve_k<K>(obs, held, fit.params, cap);
      break;
    }
    fit = solve_k<K>(obs, opt, fit.params, cap);
  }
  for (int k = 0; k < K; ++k) {
    const PhongLobe& lobe = fit.params.lobes[static_cast<size_t>(k)];
    if (carries_energy(fit.params, lobe) && lobe.shininess >= cap[static_cast<size_t>(k)] * (1.0 - 1e-6))
      ++fit.capped_lobes;
  }
  return fit;
}

}  // namespace

namespace {

/// Fits 1, 2, ... lobes, each starting from the previous fit plus a lobe at its residual peak; after each fit
/// `keep_going(k, fit)` decides whether to add another lobe (up to max_lobes). Returns the last accepted fit.
PhongFit fit_progressive(const TexelObservations& obs, const PhongFitOptions& opt, int max_lobes,
                         const std::function<bool(int, const PhongFit&)>& keep_going) {
  PhongParams init;
  PhongFit fit;
  for (int k = 1; k <= max_lobes; ++k) {
    // Lobe k starts at the residual peak of the (k-1)-lobe fit.
    initialise_lobe(obs, opt, &init);
    if (opt.shared_shininess)
      for (auto& l : init.lobes) l.shininess = init.lobes.front().shininess;
    switch (k) {
      case 1:
        fit = solve_supported<1>(obs, opt, init);
        break;
      case 2:
        fit = solve_supported<2>(obs, opt, init);
        break;
      case 3:
        fit = solve_supported<3>(obs, opt, init);
        break;
      default:
        fit = solve_supported<4>(obs, opt, init);
        break;
    }
    if (!keep_going(k, fit)) break;
    init = fit.params;
  }
  return fit;
}

PhongFit mean_only_fit(const TexelObservations& obs) {
  PhongFit fit;
  for (size_t i = 0; i < obs.size(); ++i) fit.params.kd += obs.radiance[i].cast<double>() / obs.size();
  fit.quality = measure_quality(fit.params, obs);
  return fit;
}

/// The fit with no lobe: Kd by (weighted) linear least squares, its cost as the lobed fits' (converged).
PhongFit no_lobe_fit(const TexelObservations& obs, const PhongFitOptions& opt) {
  PhongFit fit;
  const std::vector<double> weight = residual_weights(obs, opt);
  for (int c = 0; c < 3; ++c) {
    double wo = 0, ww = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      const double w2 = std::pow(weight[3 * i + c], 2);
      wo += w2 * obs.radiance[i][c];
      ww += w2;
    }
    fit.params.kd[c] = ww > 0 ? std::max(0.0, wo / ww) : 0.0;
  }
  for (size_t i = 0; i < obs.size(); ++i)
    for (int c = 0; c < 3; ++c)
      fit.cost += 0.5 * std::pow((fit.params.kd[c] - obs.radiance[i][c]) * weight[3 * i + c], 2);
  fit.converged = true;
  fit.quality = measure_quality(fit.params, obs);
  return fit;
}

/// phong_bic of a k-lobe fit of `obs`, as fitted with `opt` (RSS = 2 cost, n = 3 x observations).
class LobeCountBic {
 public:
  LobeCountBic(const TexelObservations& obs, const PhongFitOptions& opt)
      : obs_(obs),
        check_detection_(opt.significant_lobes_only && opt.fixed_directions.empty()),
        n_(static_cast<int>(3 * obs.size())),
        shared_(opt.shared_shininess),
        fixed_(!opt.fixed_directions.empty()) {
    double sq = 0;
    for (size_t i = 0; i < obs.size(); ++i) sq += obs.radiance[i].cast<double>().squaredNorm();
    rms_observed_ = std::sqrt(sq / std::max(1, n_));
  }
  /// The BIC of a k-lobe fit, or +inf when one of its lobes is not detected above the fit's noise
  /// (phong_lobe_snr < kLobeDetectionSnr): such a lobe may lower the BIC by fitting a few noisy samples.
  double operator()(int lobes, const PhongFit& fit) const {
    const int parameters = phong_parameter_count(lobes, shared_, fixed_);
    if (lobes > 0 && check_detection_) {
      const double noise_rms = fit_noise_rms(obs_, fit.params, parameters);
      for (size_t k = 0; k < fit.params.lobes.size(); ++k)
        if (phong_lobe_snr(obs_, fit.params.lobes[k], noise_rms) < kLobeDetectionSnr)
          return std::numeric_limits<double>::infinity();
    }
    return phong_bic(2.0 * fit.cost, n_, parameters, rms_observed_);
  }

 private:
  const TexelObservations& obs_;
  bool check_detection_ = true;
  int n_;
  bool shared_, fixed_;
  double rms_observed_ = 0.0;
};

}  // namespace

int phong_parameter_count(int lobes, bool shared_shininess, bool fixed_directions) {
  if (lobes <= 0) return 3;
  return 3 + (fixed_directions ? 3 : 5) * lobes + (shared_shininess ? 1 : lobes);
}

double phong_support_cap(const TexelObservations& obs, const Vec3d& direction, int support) {
  if (support <= 0) return std::numeric_limits<double>::infinity();
  if (obs.size() < static_cast<size_t>(support)) return 1.0;
  std::vector<double> cosines(obs.size());
  for (size_t i = 0; i < obs.size(); ++i) cosines[i] = obs.direction[i].cast<double>().normalized().dot(direction);
  std::sort(cosines.begin(), cosines.end(), std::greater<>());
  // The largest m for which the observation with cosine c lies at `level` of the lobe's peak: c^m = level.
  auto cap = [](double c, double level) {
    if (!(c > 0.0)) return 1.0;
    if (c >= 1.0 - 1e-15) return std::numeric_limits<double>::infinity();
    return std::max(1.0, std::log(level) / std::log(c));
  };
  return std::min(cap(cosines[static_cast<size_t>(support - 1)], kLobeSupportLevel),
                  cap(cosines.front(), kLobePeakLevel));
}

bool phong_lobe_width_measured(const TexelObservations& obs, const PhongLobe& lobe, double noise_rms, int support) {
  int seen = 0;
  double brightest = 0.0, faintest = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < obs.size(); ++i) {
    const double c = lobe.direction.dot(obs.direction[i].cast<double>().normalized());
    const double seen_of_it = c > 0.0 ? lobe.ks.maxCoeff() * std::pow(c, lobe.shininess) : 0.0;
    if (!(seen_of_it >= kLobeSeenSnr * noise_rms)) continue;
    ++seen;
    brightest = std::max(brightest, seen_of_it);
    faintest = std::min(faintest, seen_of_it);
  }
  return seen >= support && brightest >= faintest / kLobePeakLevel;
}

namespace {

/// kRefitCheckDirections on a Fibonacci spiral, uniform in solid angle over the upper hemisphere (z > 0).
const std::vector<Vec3d>& refit_check_directions() {
  static const std::vector<Vec3d> directions = [] {
    std::vector<Vec3d> d;
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < kRefitCheckDirections; ++i) {
      const double z = 1.0 - (i + 0.5) / kRefitCheckDirections;
      const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
      d.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
    }
    return d;
  }();
  return directions;
}

}  // namespace

bool phong_refit_within_free_fit(const PhongParams& refit, const PhongParams& free, const TexelObservations& obs) {
  double level = 0.0;
  for (const Eigen::Vector3f& r : obs.radiance) level += r.cast<double>().sum();
  const double slack = kRefitCheckFloor * level / static_cast<double>(std::max<size_t>(1, 3 * obs.size()));
  auto within = [&](const Vec3d& v) {
    return (refit.evaluate(v).array() <= kRefitExcessFactor * free.evaluate(v).array() + slack).all();
  };
  for (const PhongLobe& lobe : refit.lobes)
    if (!within(lobe.direction)) return false;
  for (const Vec3d& v : refit_check_directions())
    if (!within(v)) return false;
  return true;
}

double phong_lobe_snr(const TexelObservations& obs, const PhongLobe& lobe, double noise_rms) {
  double sq = 0.0;
  for (size_t i = 0; i < obs.size(); ++i) {
    const double c = lobe.direction.dot(obs.direction[i].cast<double>().normalized());
    if (c > 0.0) sq += (lobe.ks * std::pow(c, lobe.shininess)).squaredNorm();
  }
  return noise_rms > 0.0 ? std::sqrt(sq) / noise_rms : std::numeric_limits<double>::infinity();
}

double phong_bic(double rss, int residuals, int parameters, double rms_observed) {
  const double n = std::max(1, residuals);
  const double floor_rms = 1e-6 * rms_observed;
  const double r = std::max({rss, n * floor_rms * floor_rms, std::numeric_limits<double>::min()});
  return n * std::log(r / n) + parameters * std::log(n);
}

PhongFit fit_phong(const TexelObservations& obs, const PhongFitOptions& opt) {
  std::string why;
  VDRIG_CHECK(opt.is_valid(&why), why);
  const size_t params = phong_parameter_count(opt.lobes, opt.shared_shininess, !opt.fixed_directions.empty());
  if (obs.size() * 3 < params + 3) return mean_only_fit(obs);
  if (!opt.significant_lobes_only)
    return fit_progressive(obs, opt, opt.lobes, [](int, const PhongFit&) { return true; });
  // 0..K lobes, the count of the lowest BIC (each k fitted from the k - 1 lobe fit, as without the choice).
  const LobeCountBic bic(obs, opt);
  PhongFit best = no_lobe_fit(obs, opt);
  double best_bic = bic(0, best);
  fit_progressive(obs, opt, opt.lobes, [&](int k, const PhongFit& f) {
    const double b = bic(k, f);
    if (b < best_bic) {
      best_bic = b;
      best = f;
    }
    return true;
  });
  return best;
}

PhongFit fit_phong_auto(const TexelObservations& obs, const PhongFitOptions& options, int max_lobes) {
  PhongFitOptions opt = options;
  opt.lobes = std::clamp(max_lobes, 1, 4);
  VDRIG_CHECK(opt.fixed_directions.empty(),
              "fit_phong_auto does not take fixed_directions: fit the fixed-direction model with fit_phong");
  std::string why;
  VDRIG_CHECK(opt.is_valid(&why), why);
  if (obs.size() * 3 < static_cast<size_t>(phong_parameter_count(1, opt.shared_shininess)) + 3)
    return mean_only_fit(obs);
  // The residuals as minimised (weighted in relative mode): RSS = 2 cost.
  const LobeCountBic bic(obs, opt);
  PhongFit best;
  double best_bic = std::numeric_limits<double>::infinity();
  if (opt.significant_lobes_only) {
    best = no_lobe_fit(obs, opt);
    best_bic = bic(0, best);
  }
  fit_progressive(obs, opt, opt.lobes, [&](int k, const PhongFit& f) {
    // One more lobe needs at least its parameters' worth of residuals; stop as soon as the BIC stops improving.
    if (static_cast<size_t>(phong_parameter_count(k, opt.shared_shininess)) + 3 > 3 * obs.size()) return false;
    const double b = bic(k, f);
    if (b >= best_bic) return false;
    best_bic = b;
    best = f;
    return true;
  });
  return best;
}

}  // namespace vdrig::fitting
