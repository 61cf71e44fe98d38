#include "vdrig/fitting/ggx_model.hpp"

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include "bounded_lm.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/tiled_fit.hpp"

namespace vdrig::fitting {
namespace {

// Channels after the material: ggx:iso+n's normal.x/y, then (both forms) light.x/y/z and E.R/G/B.
constexpr int kNormal = GgxModel::kMaterialParameters;

/// The specular factor of the radiance, pi D G2 / (4 lz vz) (the radiance's specular part is E F times it), and its
/// derivative with respect to the roughness r (alpha = r^2) when `d_dr` is given. lz, vz > 0.
double specular_factor(const Vec3d& l, const Vec3d& v, const Vec3d& h, double r, double* d_dr) {
  const double alpha = r * r, a2 = alpha * alpha;
  const double hz2 = h.z() * h.z();
  const double k = hz2 * (a2 - 1.0) + 1.0;  // alpha^2 q: D = alpha^2 / (pi k^2)
  auto lambda_of = [a2](const Vec3d& w, double* u) {
    *u = (w.x() * w.x() + w.y() * w.y()) / (w.z() * w.z());
    return std::sqrt(1.0 + a2 * *u);
  };
  double ul = 0, uv = 0;
  const double sl = lambda_of(l, &ul), sv = lambda_of(v, &uv);
  const double g_den = 1.0 + 0.5 * (sl - 1.0) + 0.5 * (sv - 1.0);  // 1 + Lambda(l) + Lambda(v)
  const double s = a2 / (k * k) / g_den / (4.0 * l.z() * v.z());   // pi D G2 / (4 lz vz)
  if (d_dr) {
    // d ln D / d alpha = 2 / alpha - 4 alpha hz^2 / k; d Lambda / d alpha = alpha u / (2 sqrt(1 + alpha^2 u)).
    const double dlnd = 2.0 / alpha - 4.0 * alpha * hz2 / k;
    const double dlambda = 0.5 * alpha * (ul / sl + uv / sv);
    *d_dr = s * (dlnd - dlambda / g_den) * 2.0 * r;
  }
  return s;
}

/// specular_factor in the frame of a shading normal n, from the cosines ln = l . n, vn = v . n, hn = h . n (> 0):
/// wx^2 + wy^2 there is 1 - (w . n)^2.
double specular_factor_cos(double ln, double vn, double hn, double r, double* d_dr) {
  const double alpha = r * r, a2 = alpha * alpha;
  const double k = hn * hn * (a2 - 1.0) + 1.0;
  const double ul = std::max(0.0, 1.0 - ln * ln) / (ln * ln), uv = std::max(0.0, 1.0 - vn * vn) / (vn * vn);
  const double sl = std::sqrt(1.0 + a2 * ul), sv = std::sqrt(1.0 + a2 * uv);
  const double g_den = 0.5 * (sl + sv);  // 1 + Lambda(l) + Lambda(v)
  const double s = a2 / (k * k) / g_den / (4.0 * ln * vn);
  if (d_dr) {
    const double dlnd = 2.0 / alpha - 4.0 * alpha * hn * hn / k;
    const double dlambda = 0.5 * alpha * (ul / sl + uv / sv);
    *d_dr = s * (dlnd - dlambda / g_den) * 2.0 * r;
  }
  return s;
}

/// A parameter map stores float channels: a normal the fit put on the tilt bound reads back up to ~1e-7 past it
/// (x^2 + y^2; a Blender session's map was refused at 0.9500000308), so a stored map is read with this slack (the
/// fit itself keeps to the bound: given the slack it would use it, and the stored value would land past it again).
constexpr double kTiltStorageSlack = 1e-6;

/// ggx:iso+n's shading normal from its two channels; false when x^2 + y^2 exceeds GgxModel::kMaxTilt + slack.
bool shading_normal(double x, double y, Vec3d* n, double slack = 0.0) {
  const double q = x * x + y * y;
  if (!(q <= GgxModel::kMaxTilt + slack)) return false;
  *n = Vec3d(x, y, std::sqrt(1.0 - q));
  return true;
}

/// ggx:aniso's pi D G2 / (4 lz vz) (sim/ggx.hpp's anisotropic D and Lambda) with alpha_t = rt^2 along the tangent at
/// angle phi from the surface's x axis and alpha_b = rb^2 along the bitangent; flat normal, lz, vz > 0.
double specular_factor_aniso(const Vec3d& l, const Vec3d& v, const Vec3d& h, double rt, double rb, double phi) {
  const double c = std::cos(phi), sn = std::sin(phi);
  const double at = rt * rt, ab = rb * rb;
  auto tangent = [c, sn](const Vec3d& w) { return c * w.x() + sn * w.y(); };
  auto bitangent = [c, sn](const Vec3d& w) { return -sn * w.x() + c * w.y(); };
  const double hx = tangent(h) / at, hy = bitangent(h) / ab;
  const double q = hx * hx + hy * hy + h.z() * h.z();
  const double pi_d = 1.0 / (at * ab * q * q);
  auto one_plus_two_lambda = [&](const Vec3d& w) {
    const double x = at * tangent(w), y = ab * bitangent(w);
    return std::sqrt(1.0 + (x * x + y * y) / (w.z() * w.z()));
  };
  const double g_den = 0.5 * (one_plus_two_lambda(l) + one_plus_two_lambda(v));  // 1 + Lambda(l) + Lambda(v)
  return pi_d / g_den / (4.0 * l.z() * v.z());
}

/// The smallest roughness the views identify (docs/models.md, "BRDF models"): the highlight may not be narrower than
/// the sampling sees, or a fit puts an unobserved spike at the mirror direction (a Lambertian texel seen from 17 views
/// got one thousands of times brighter than the truth between them). As Phong's support rule (b): the observation
/// whose half vector is nearest the normal (angle theta) sees at least half the peak of D, D(h) / D(n) =
/// alpha^4 / (alpha^2 cos^2 theta + sin^2 theta)^2 >= 1/2, i.e. alpha >= sin theta / sqrt(sqrt2 - cos^2 theta).
double ggx_supported_roughness(const std::vector<Vec3d>& half) {
  double cos_max = 0.0;
  for (const Vec3d& h : half) cos_max = std::max(cos_max, std::min(h.z(), 1.0));
  const double sin2 = 1.0 - cos_max * cos_max;
  const double alpha = std::sqrt(sin2 / (std::sqrt(2.0) - cos_max * cos_max));
  return std::clamp(std::sqrt(alpha), GgxModel::kMinRoughness, 1.0);
}

/// One texel's observations, with what does not depend on the parameters computed once.
struct GgxTexelData {
  Vec3d light = Vec3d::UnitZ();
  Vec3d irradiance = Vec3d::Zero();
  std::vector<Vec3d> view, half;
  std::vector<double> schlick;  // (1 - v . h)^5
  std::vector<Vec3d> radiance;
};

/// The least-squares cost of a texel's material for bounded_lm.hpp: residual E (albedo + s (f0 (1 - S) + S)) - L per
/// observation and colour, s = specular_factor(roughness).
struct GgxTexelCost {
  static constexpr int kParams = GgxModel::kMaterialParameters;
  using Vec = Eigen::Matrix<double, kParams, 1>;
  using Mat = Eigen::Matrix<double, kParams, kParams>;
  const GgxTexelData* data = nullptr;

  double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const {
    double cost = 0;
    if (jtj) {
      jtj->setZero();
      jtr->setZero();
    }
    const GgxTexelData& d = *data;
    for (size_t i = 0; i < d.view.size(); ++i) {
      double ds = 0;
      const double s = specular_factor(d.light, d.view[i], d.half[i], p[6], jtj ? &ds : nullptr);
      const double sch = d.schlick[i];
      for (int c = 0; c < 3; ++c) {
        const double e = d.irradiance[c];
        const double fresnel = p[3 + c] * (1.0 - sch) + sch;
        const double r = e * (p[c] + s * fresnel) - d.radiance[i][c];
        cost += 0.5 * r * r;
        if (jtj) {
          // Nonzero Jacobian entries of this residual: albedo_c, f0_c, roughness.
          const int idx[3] = {c, 3 + c, 6};
          const double jac[3] = {e, e * s * (1.0 - sch), e * fresnel * ds};
          for (int a = 0; a < 3; ++a) {
            (*jtr)[idx[a]] += jac[a] * r;
            for (int b = 0; b < 3; ++b) (*jtj)(idx[a], idx[b]) += jac[a] * jac[b];
          }
        }
      }
    }
    return cost;
  }
};

/// The material of one texel: for each roughness of a grid, albedo and f0 per colour by bounded linear least
/// squares (the radiance is linear in them at a fixed roughness), the best as the start of the bounded LM on all
/// seven. The grid makes the start independent of where the views happen to fall (no peak to find first).
std::array<double, GgxModel::kMaterialParameters> fit_texel(const GgxTexelData& d, int max_iterations) {
  std::array<double, GgxModel::kMaterialParameters> best{};
  const size_t n = d.view.size();
  if (d.irradiance.maxCoeff() <= 0.0 || n == 0) return best;  // unlit: nothing to measure the material by
  const double r_min = ggx_supported_roughness(d.half);
  double best_cost = std::numeric_limits<double>::infinity();
  std::vector<double> s(n);
  for (double r = r_min; r <= 1.0 + 1e-9; r *= 1.25) {
    for (size_t i = 0; i < n; ++i) s[i] = specular_factor(d.light, d.view[i], d.half[i], r, nullptr);
    std::array<double, GgxModel::kMaterialParameters> p{};
    p[6] = std::min(r, 1.0);
    double cost = 0;
    for (int c = 0; c < 3; ++c) {
      const double e = d.irradiance[c];
      if (e <= 0) continue;
      // y = L / E - s S = albedo + f0 x, x = s (1 - S).
      double sx = 0, sy = 0, sxx = 0, sxy = 0;
      for (size_t i = 0; i < n; ++i) {
        const double x = s[i] * (1.0 - d.schlick[i]);
        const double y = d.radiance[i][c] / e - s[i] * d.schlick[i];
        sx += x, sy += y, sxx += x * x, sxy += x * y;
      }
      const double nn = static_cast<double>(n), det = nn * sxx - sx * sx;
      double f0 = det > 1e-12 * nn * sxx ? (nn * sxy - sx * sy) / det : 0.0;
      f0 = std::clamp(f0, 0.0, 1.0);
      double albedo = std::max(0.0, (sy - f0 * sx) / nn);
      if (albedo == 0.0 && sxx > 0) f0 = std::clamp(sxy / sxx, 0.0, 1.0);  // albedo at its bound: f0 alone
      p[static_cast<size_t>(c)] = albedo;
      p[static_cast<size_t>(3 + c)] = f0;
      for (size_t i = 0; i < n; ++i) {
        const double res = e * (albedo + s[i] * (f0 * (1.0 - d.schlick[i]) + d.schlick[i])) - d.radiance[i][c];
        cost += res * res;
      }
    }
    if (cost < best_cost) best_cost = cost, best = p;
  }
  GgxTexelCost cost{&d};
  GgxTexelCost::Vec p = Eigen::Map<const GgxTexelCost::Vec>(best.data());
  GgxTexelCost::Vec lo, hi;
  lo << 0, 0, 0, 0, 0, 0, r_min;
  const double inf = std::numeric_limits<double>::infinity();
  hi << inf, inf, inf, 1, 1, 1, 1;
  double final_cost = 0;
  const GgxTexelCost::Vec start = p;
  minimise_bounded(cost, p, lo, hi, Eigen::Matrix<bool, 7, 1>::Constant(false), max_iterations, &final_cost);
  if (!p.allFinite()) p = start;
  std::copy(p.data(), p.data() + GgxModel::kMaterialParameters, best.begin());
  return best;
}

/// The least-squares cost of ggx:iso+n's nine parameters (material and normal.x/y): residual
/// E g (albedo + s (f0 (1 - S) + S)) - L, g = (l . n) / lz (the irradiance on the tilted texel relative to the flat
/// one), s = specular_factor_cos (0 when v . n <= 0; all 0 when l . n <= 0). The derivatives in the normal are central
/// differences (the model is smooth there; analytic ones would triple this code for no accuracy the fit needs).
struct GgxNormalTexelCost {
  static constexpr int kParams = GgxModel::kMaterialParameters + 2;
  using Vec = Eigen::Matrix<double, kParams, 1>;
  using Mat = Eigen::Matrix<double, kParams, kParams>;
  const GgxTexelData* data = nullptr;

  /// g and s (and ds/dr when given) of observation i under normal n.
  void geometry(size_t i, const Vec3d& n, double r, double* g, double* s, double* ds) const {
    const GgxTexelData& d = *data;
    const double ln = d.light.dot(n), vn = d.view[i].dot(n);
    *g = ln > 0.0 ? ln / d.light.z() : 0.0;
    *s = 0.0;
    if (ds) *ds = 0.0;
    if (ln > 0.0 && vn > 0.0) *s = specular_factor_cos(ln, vn, std::max(d.half[i].dot(n), 1e-12), r, ds);
  }

  double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const {
    Vec3d n;
    if (!shading_normal(p[7], p[8], &n)) return std::numeric_limits<double>::infinity();
    // The normals of the difference quotients: central where both lie inside the tilt bound, one-sided otherwise.
    constexpr double kStep = 1e-6;
    Vec3d plus[2], minus[2];
    double width[2];
    for (int a = 0; a < 2; ++a) {
      Vec q = p;
      q[7 + a] += kStep;
      const bool up = shading_normal(q[7], q[8], &plus[a]);
      q[7 + a] -= 2 * kStep;
      const bool down = shading_normal(q[7], q[8], &minus[a]);
      if (!up) plus[a] = n;
      if (!down) minus[a] = n;
      width[a] = (up ? kStep : 0.0) + (down ? kStep : 0.0);
    }
    double cost = 0;
    if (jtj) {
      jtj->setZero();
      jtr->setZero();
    }
    const GgxTexelData& d = *data;
    for (size_t i = 0; i < d.view.size(); ++i) {
      double g = 0, s = 0, ds = 0;
      geometry(i, n, p[6], &g, &s, jtj ? &ds : nullptr);
      double dg[2] = {0, 0}, dsn[2] = {0, 0};
      if (jtj)
        for (int a = 0; a < 2; ++a) {
          double gp, sp, gm, sm;
          geometry(i, plus[a], p[6], &gp, &sp, nullptr);
          geometry(i, minus[a], p[6], &gm, &sm, nullptr);
          dg[a] = (gp - gm) / width[a];
          dsn[a] = (sp - sm) / width[a];
        }
      const double sch = d.schlick[i];
      for (int c = 0; c < 3; ++c) {
        const double e = d.irradiance[c];  // the flat texel's: E g on the tilted one
        const double fresnel = p[3 + c] * (1.0 - sch) + sch;
        const double inner = p[c] + s * fresnel;
        const double r = e * g * inner - d.radiance[i][c];
        cost += 0.5 * r * r;
        if (jtj) {
          const double eg = e * g, el = e;
          const int idx[5] = {c, 3 + c, 6, 7, 8};
          const double jac[5] = {eg, eg * s * (1.0 - sch), eg * fresnel * ds,
                                 el * (dg[0] * inner + g * fresnel * dsn[0]),
                                 el * (dg[1] * inner + g * fresnel * dsn[1])};
          for (int a = 0; a < 5; ++a) {
            (*jtr)[idx[a]] += jac[a] * r;
            for (int b = 0; b < 5; ++b) (*jtj)(idx[a], idx[b]) += jac[a] * jac[b];
          }
        }
      }
    }
    return cost;
  }
};

/// The rotation into the frame of unit normal n (rows: a tangent, the bitangent, n); isotropic: any tangent does.
Mat3d frame_of(const Vec3d& n) {
  Vec3d t = Vec3d::UnitX() - n * n.x();
  t.normalize();
  Mat3d r;
  r.row(0) = t.transpose();
  r.row(1) = n.cross(t).transpose();
  r.row(2) = n.transpose();
  return r;
}

/// ggx:iso+n's texel: from two starting normals, the flat one and the half vector of the brightest observation (the
/// highlight's peak; its tilt capped at 45 deg), ggx:iso's fit in that normal's frame gives the material, then the
/// bounded LM on all nine parameters; the lower cost wins. The flat start keeps texels without a highlight (matte,
/// or seen from too few views) from being tilted toward noise.
std::array<double, GgxModel::kMaterialParameters + 2> fit_texel_with_normal(const GgxTexelData& d, int max_iterations) {
  std::array<double, GgxModel::kMaterialParameters + 2> best{};
  const size_t n = d.view.size();
  if (d.irradiance.maxCoeff() <= 0.0 || n == 0) return best;
  size_t brightest = 0;
  for (size_t i = 1; i < n; ++i)
    if (d.radiance[i].sum() > d.radiance[brightest].sum()) brightest = i;
  Vec3d peak = d.half[brightest];
  const double max_sin = std::sqrt(0.5);
  if (peak.head<2>().norm() > max_sin) {
    const Eigen::Vector2d xy = peak.head<2>().normalized() * max_sin;
    peak = Vec3d(xy.x(), xy.y(), std::sqrt(0.5));
  }
  double best_cost = std::numeric_limits<double>::infinity();
  GgxNormalTexelCost cost{&d};
  for (const Vec3d& n0 : {Vec3d(Vec3d::UnitZ()), peak}) {
    const Mat3d r = frame_of(n0);
    GgxTexelData local;
    local.light = r * d.light;
    if (local.light.z() <= 0.0) continue;
    local.irradiance = d.irradiance * (local.light.z() / d.light.z());
    for (size_t i = 0; i < n; ++i) {
      const Vec3d v = r * d.view[i];
      if (v.z() <= 0.0) continue;  // below this normal's horizon: no highlight, left to the nine-parameter fit
      local.view.push_back(v);
      local.half.push_back(r * d.half[i]);
      local.schlick.push_back(d.schlick[i]);
      local.radiance.push_back(d.radiance[i]);
    }
    if (local.view.empty()) continue;
    const auto material = fit_texel(local, max_iterations);
    GgxNormalTexelCost::Vec p;
    for (int k = 0; k < GgxModel::kMaterialParameters; ++k) p[k] = material[static_cast<size_t>(k)];
    p[7] = n0.x(), p[8] = n0.y();
    GgxNormalTexelCost::Vec lo, hi;
    const double inf = std::numeric_limits<double>::infinity();
    const double r_min = ggx_supported_roughness(local.half);
    lo << 0, 0, 0, 0, 0, 0, r_min, -1, -1;
    hi << inf, inf, inf, 1, 1, 1, 1, 1, 1;
    double final_cost = inf;
    const GgxNormalTexelCost::Vec start = p;
    minimise_bounded(cost, p, lo, hi, Eigen::Matrix<bool, 9, 1>::Constant(false), max_iterations, &final_cost);
    if (!p.allFinite() || !(final_cost < inf)) p = start, final_cost = cost.evaluate(p, nullptr, nullptr);
    if (final_cost < best_cost) {
      best_cost = final_cost;
      std::copy(p.data(), p.data() + p.size(), best.begin());
    }
  }
  return best;
}

/// The least-squares cost of ggx:aniso's nine parameters (albedo, f0, roughness along the tangent, along the
/// bitangent, the tangent's angle): residual E (albedo + s (f0 (1 - S) + S)) - L, s = specular_factor_aniso; the
/// derivatives in the two roughnesses and the angle are central differences.
struct GgxAnisoTexelCost {
  static constexpr int kParams = GgxModel::kMaterialParameters + 2;
  using Vec = Eigen::Matrix<double, kParams, 1>;
  using Mat = Eigen::Matrix<double, kParams, kParams>;
  const GgxTexelData* data = nullptr;

  double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const {
    const GgxTexelData& d = *data;
    if (!(p[6] > 0.0) || !(p[7] > 0.0)) return std::numeric_limits<double>::infinity();
    double cost = 0;
    if (jtj) {
      jtj->setZero();
      jtr->setZero();
    }
    constexpr double kStep = 1e-6;
    for (size_t i = 0; i < d.view.size(); ++i) {
      auto factor = [&](double rt, double rb, double phi) {
        return specular_factor_aniso(d.light, d.view[i], d.half[i], rt, rb, phi);
      };
      const double s = factor(p[6], p[7], p[8]);
      double ds[3] = {0, 0, 0};
      if (jtj) {
        ds[0] = (factor(p[6] + kStep, p[7], p[8]) - factor(p[6] - kStep, p[7], p[8])) / (2 * kStep);
        ds[1] = (factor(p[6], p[7] + kStep, p[8]) - factor(p[6], p[7] - kStep, p[8])) / (2 * kStep);
        ds[2] = (factor(p[6], p[7], p[8] + kStep) - factor(p[6], p[7], p[8] - kStep)) / (2 * kStep);
      }
      const double sch = d.schlick[i];
      for (int c = 0; c < 3; ++c) {
        const double e = d.irradiance[c];
        const double fresnel = p[3 + c] * (1.0 - sch) + sch;
        const double r = e * (p[c] + s * fresnel) - d.radiance[i][c];
        cost += 0.5 * r * r;
        if (jtj) {
          const int idx[5] = {c, 3 + c, 6, 7, 8};
          const double jac[5] = {e, e * s * (1.0 - sch), e * fresnel * ds[0], e * fresnel * ds[1], e * fresnel * ds[2]};
          for (int a = 0; a < 5; ++a) {
            (*jtr)[idx[a]] += jac[a] * r;
            for (int b = 0; b < 5; ++b) (*jtj)(idx[a], idx[b]) += jac[a] * jac[b];
          }
        }
      }
    }
    return cost;
  }
};

/// ggx:aniso's texel: ggx:iso's fit gives the roughness r; from four tangent angles (0, 45, 90, 135 deg) with the
/// roughnesses split around r, the bounded LM on all nine; the lowest cost wins, the isotropic fit itself included
/// (so no texel fits worse than ggx:iso). Then the canonical form: roughness >= roughness.b (swapped with the angle
/// turned by 90 deg, the same BRDF) and the angle in [0, pi).
std::array<double, GgxModel::kMaterialParameters + 2> fit_texel_aniso(const GgxTexelData& d, int max_iterations) {
  std::array<double, GgxModel::kMaterialParameters + 2> best{};
  if (d.irradiance.maxCoeff() <= 0.0 || d.view.empty()) return best;
  const auto iso = fit_texel(d, max_iterations);
  const double r_min = ggx_supported_roughness(d.half);
  GgxAnisoTexelCost cost{&d};
  GgxAnisoTexelCost::Vec p;
  for (int k = 0; k < GgxModel::kMaterialParameters; ++k) p[k] = iso[static_cast<size_t>(k)];
  p[7] = p[6], p[8] = 0.0;
  GgxAnisoTexelCost::Vec best_p = p;
  double best_cost = cost.evaluate(p, nullptr, nullptr);
  const double inf = std::numeric_limits<double>::infinity();
  GgxAnisoTexelCost::Vec lo, hi;
  lo << 0, 0, 0, 0, 0, 0, r_min, r_min, -inf;
  hi << inf, inf, inf, 1, 1, 1, 1, 1, inf;
  for (int k = 0; k < 4; ++k) {
    GgxAnisoTexelCost::Vec q = best_p;
    for (int j = 0; j < GgxModel::kMaterialParameters; ++j) q[j] = iso[static_cast<size_t>(j)];
    q[6] = std::min(1.0, iso[6] * 1.2), q[7] = std::max(r_min, iso[6] / 1.2), q[8] = k * kPi / 4.0;
    double final_cost = inf;
    minimise_bounded(cost, q, lo, hi, Eigen::Matrix<bool, 9, 1>::Constant(false), max_iterations, &final_cost);
    if (q.allFinite() && final_cost < best_cost) best_cost = final_cost, best_p = q;
  }
  if (best_p[6] < best_p[7]) std::swap(best_p[6], best_p[7]), best_p[8] += kPi / 2.0;
  best_p[8] = std::fmod(best_p[8], kPi);
  if (best_p[8] < 0.0) best_p[8] += kPi;
  std::copy(best_p.data(), best_p.data() + best_p.size(), best.begin());
  return best;
}

std::string glsl_float(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9e", v);
  return buf;
}

}  // namespace

void SessionLight::at(const Vec3d& p_m, Vec3d* direction, Vec3d* irradiance) const {
  const Vec3d to_light = position_m - p_m;
  const double d2 = to_light.squaredNorm();
  *direction = d2 > 0 ? Vec3d(to_light / std::sqrt(d2)) : Vec3d::UnitZ();
  const double cosine = direction->z();
  *irradiance = cosine > 0 && d2 > 0 ? Vec3d(intensity * (cosine / d2)) : Vec3d::Zero();
}

std::string SessionLight::describe() const {
  return fmt::format("point {} {} {} {} {} {}", position_m.x(), position_m.y(), position_m.z(), intensity.x(),
                     intensity.y(), intensity.z());
}

std::string SessionLight::check() const {
  if (!position_m.allFinite() || !intensity.allFinite()) return "the light's position and intensity must be finite";
  if (position_m.z() <= 0) return "the light must be above the surface (z > 0)";
  if (intensity.minCoeff() < 0 || intensity.maxCoeff() <= 0) return "the light's intensity must be >= 0 and not 0";
  return {};
}

std::string GgxFitOptions::fingerprint() const {
  return fmt::format("light={};max_iterations={}", light ? light->describe() : std::string("none"), max_iterations);
}

std::vector<std::string> GgxModel::channels() const {
  std::vector<std::string> c = {"albedo.R", "albedo.G", "albedo.B", "f0.R", "f0.G", "f0.B", "roughness"};
  if (shading_normal_) c.insert(c.end(), {"normal.x", "normal.y"});
  if (aniso_) c.insert(c.end(), {"roughness.b", "aniso.angle"});
  c.insert(c.end(), {"light.x", "light.y", "light.z", "E.R", "E.G", "E.B"});
  return c;
}

GgxMaterial GgxModel::material(std::span<const double> p) {
  VDRIG_CHECK(p.size() >= static_cast<size_t>(kMaterialParameters), "GgxModel: too few parameters");
  return {Vec3d(p[0], p[1], p[2]), Vec3d(p[3], p[4], p[5]), p[6]};
}

GgxMaterial GgxModel::texel_material(std::span<const double> p) const {
  GgxMaterial m = material(p);
  if (shading_normal_ && !shading_normal(p[kNormal], p[kNormal + 1], &m.normal, kTiltStorageSlack))
    m.normal = Vec3d(p[kNormal], p[kNormal + 1], 0.0).normalized();  // past the tilt bound: at the horizon
  if (aniso_) m.roughness_b = p[kMaterialParameters], m.angle = p[kMaterialParameters + 1];
  return m;
}

Vec3d GgxModel::brdf(const GgxMaterial& m, const Vec3d& l, const Vec3d& v) {
  const double ln = l.dot(m.normal), vn = v.dot(m.normal);
  if (ln <= 0.0 || vn <= 0.0) return Vec3d::Zero();
  const Vec3d h = (l + v).normalized();
  const double r = std::max(m.roughness, kMinRoughness);
  if (m.roughness_b > 0.0) {  // anisotropic (ggx:aniso: flat normal)
    const double s = specular_factor_aniso(l, v, h, r, std::max(m.roughness_b, kMinRoughness), m.angle);
    const double sch = std::pow(1.0 - std::clamp(v.dot(h), 0.0, 1.0), 5.0);
    return (m.albedo + (m.f0 + (Vec3d::Ones() - m.f0) * sch) * s) / kPi;
  }
  // The flat texel keeps the component form (ggx:iso's figures); a tilted one needs the cosines.
  const double s = m.normal == Vec3d::UnitZ()
                       ? specular_factor(l, v, h, r, nullptr)
                       : specular_factor_cos(ln, vn, std::max(h.dot(m.normal), 1e-12), r, nullptr);
  const double sch = std::pow(1.0 - std::clamp(v.dot(h), 0.0, 1.0), 5.0);
  const Vec3d fresnel = m.f0 + (Vec3d::Ones() - m.f0) * sch;
  return (m.albedo + fresnel * s) / kPi;
}

Vec3d GgxModel::evaluate(std::span<const double> p, const Vec3d& v) const {
  VDRIG_CHECK(static_cast<int>(p.size()) == parameter_count(), "GgxModel: wrong parameter count");
  const int lc = light_channel();
  const Vec3d l(p[lc], p[lc + 1], p[lc + 2]);
  Vec3d e(p[lc + 3], p[lc + 4], p[lc + 5]);
  const GgxMaterial m = texel_material(p);
  if (shading_normal_) {
    // E is the flat texel's irradiance I lz / d^2; the tilted texel receives I (l . n) / d^2.
    const double ln = l.dot(m.normal);
    if (l.z() <= 0.0 || ln <= 0.0) return Vec3d::Zero();
    e *= ln / l.z();
    if (v.dot(m.normal) <= 0.0) return e.cwiseProduct(m.albedo);
  }
  if (l.z() <= 0.0 || v.z() <= 0.0) return e.cwiseProduct(m.albedo);  // no specular term below either horizon
  return kPi * e.cwiseProduct(brdf(m, l, v));
}

std::string GgxModel::check_parameters(std::span<const double> p) const {
  const int light_at = light_channel(), irradiance_at = light_at + 3;
  if (shading_normal_ && p[kNormal] * p[kNormal] + p[kNormal + 1] * p[kNormal + 1] > kMaxTilt + kTiltStorageSlack)
    return fmt::format("the normal is tilted past the bound (x^2 + y^2 = {} > {})",
                       p[kNormal] * p[kNormal] + p[kNormal + 1] * p[kNormal + 1], kMaxTilt);
  for (int i = 0; i < 3; ++i) {
    if (p[static_cast<size_t>(i)] < 0) return fmt::format("albedo is negative ({})", p[static_cast<size_t>(i)]);
    if (p[static_cast<size_t>(3 + i)] < 0 || p[static_cast<size_t>(3 + i)] > 1)
      return fmt::format("f0 is outside [0, 1] ({})", p[static_cast<size_t>(3 + i)]);
    if (p[static_cast<size_t>(irradiance_at + i)] < 0)
      return fmt::format("irradiance is negative ({})", p[static_cast<size_t>(irradiance_at + i)]);
  }
  if (p[6] < 0 || p[6] > 1) return fmt::format("roughness is outside [0, 1] ({})", p[6]);
  if (aniso_) {
    const double rb = p[kMaterialParameters], angle = p[kMaterialParameters + 1];
    if (rb < 0 || rb > p[6] + 1e-9) return fmt::format("roughness.b is outside [0, roughness] ({})", rb);
    if (angle < 0 || angle > kPi) return fmt::format("aniso.angle is outside [0, pi] ({})", angle);
  }
  const double norm = Vec3d(p[light_at], p[light_at + 1], p[light_at + 2]).norm();
  if (norm != 0.0 && std::abs(norm - 1.0) > 1e-3) return fmt::format("light direction is not unit ({})", norm);
  return {};
}

Vec3d GgxModel::diffuse_part(std::span<const double> p) const {
  const int lc = light_channel();
  const GgxMaterial m = texel_material(p);
  const Vec3d l(p[lc], p[lc + 1], p[lc + 2]);
  const double tilt = shading_normal_ ? (l.z() > 0.0 ? std::max(0.0, l.dot(m.normal)) / l.z() : 0.0) : 1.0;
  return tilt * Vec3d(p[lc + 3], p[lc + 4], p[lc + 5]).cwiseProduct(m.albedo);
}

std::vector<LobeSummary> GgxModel::lobes(std::span<const double> p) const {
  const int lc = light_channel();
  const Vec3d l(p[lc], p[lc + 1], p[lc + 2]);
  const Vec3d n = texel_material(p).normal;
  if (l.z() <= 0.0 || l.dot(n) <= 0.0) return {};
  LobeSummary lobe;
  lobe.direction = 2.0 * l.dot(n) * n - l;  // the mirror direction about the shading normal: the peak of D (h = n)
  lobe.peak_rgb = evaluate(p, lobe.direction) - diffuse_part(p);
  // The Phong exponent of the same width near the peak (Walter et al. 2007): m = 2 / alpha^2 - 2.
  double alpha = std::max(p[6], kMinRoughness) * std::max(p[6], kMinRoughness);
  if (aniso_)
    alpha = std::sqrt(alpha * std::max(p[kMaterialParameters], kMinRoughness) *
                      std::max(p[kMaterialParameters], kMinRoughness));  // the two widths' geometric mean
  lobe.phong_exponent = std::max(0.0, 2.0 / (alpha * alpha) - 2.0);
  return {lobe};
}

std::vector<double> GgxModel::sample_parameters(unsigned seed) const {
  const double phase = 0.9 * static_cast<double>(seed);
  const Vec3d l = Vec3d(0.3 * std::cos(phase), 0.3 * std::sin(phase), 0.9).normalized();
  if (aniso_)
    return {0.5 + 0.1 * std::sin(phase),
            0.4,
            0.3,
            0.04,
            0.05,
            0.06,
            0.6 + 0.1 * std::cos(1.3 * phase),
            0.3 + 0.1 * std::sin(0.7 * phase),
            1.5 + 1.2 * std::sin(1.9 * phase),
            l.x(),
            l.y(),
            l.z(),
            1.5,
            1.4,
            1.3};
  if (shading_normal_)
    return {0.5 + 0.1 * std::sin(phase),
            0.4,
            0.3,
            0.04,
            0.05,
            0.06,
            0.5 + 0.1 * std::cos(1.3 * phase),
            0.15 * std::sin(2.1 * phase),
            0.1 * std::cos(0.7 * phase),
            l.x(),
            l.y(),
            l.z(),
            1.5,
            1.4,
            1.3};
  return {0.5 + 0.1 * std::sin(phase),
          0.4,
          0.3 + 0.1 * std::cos(phase),
          0.04,
          0.05 + 0.02 * std::sin(phase),
          0.06,
          0.55 + 0.1 * std::sin(1.7 * phase),
          l.x(),
          l.y(),
          l.z(),
          1.5,
          1.4,
          1.3};
}

std::string GgxModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  auto vec3_of = [&](int i) {
    return "vec3(" + parameter(i) + ", " + parameter(i + 1) + ", " + parameter(i + 2) + ")";
  };
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  s += "  vec3 albedo = " + vec3_of(0) + ";\n  vec3 f0 = " + vec3_of(3) + ";\n";
  s += "  vec3 l = " + vec3_of(light_channel()) + ";\n  vec3 E = " + vec3_of(light_channel() + 3) + ";\n";
  if (aniso_) {
    // As evaluate(): sim/ggx.hpp's anisotropic D and Lambda in the frame of the tangent at aniso.angle.
    s += "  if (l.z <= 0.0 || v.z <= 0.0) return E * albedo;\n";
    s += "  float at = max(" + parameter(6) + ", " + glsl_float(kMinRoughness) + ");\n  at *= at;\n";
    s += "  float ab = max(" + parameter(kMaterialParameters) + ", " + glsl_float(kMinRoughness) + ");\n  ab *= ab;\n";
    s += "  float phi = " + parameter(kMaterialParameters + 1) + ";\n";
    s += "  mat2 rot = mat2(cos(phi), -sin(phi), sin(phi), cos(phi));\n";  // columns: (c, -s), (s, c)
    s += "  vec3 h = normalize(l + v);\n";
    s += "  vec2 hl = rot * h.xy, ll = rot * l.xy, vl = rot * v.xy;\n";
    s += "  float q = (hl.x / at) * (hl.x / at) + (hl.y / ab) * (hl.y / ab) + h.z * h.z;\n";
    s += "  float gl = sqrt(1.0 + ((at * ll.x) * (at * ll.x) + (ab * ll.y) * (ab * ll.y)) / (l.z * l.z));\n";
    s += "  float gv = sqrt(1.0 + ((at * vl.x) * (at * vl.x) + (ab * vl.y) * (ab * vl.y)) / (v.z * v.z));\n";
    s += "  float spec = 1.0 / (at * ab * q * q) / (0.5 * (gl + gv)) / (4.0 * l.z * v.z);\n";
    s += "  float sch = pow(1.0 - clamp(dot(v, h), 0.0, 1.0), 5.0);\n";
    s += "  return E * (albedo + (f0 + (1.0 - f0) * sch) * spec);\n}\n";
    return s;
  }
  if (shading_normal_) {
    // As evaluate(): the formula in the shading normal's frame, from cosines; the flat texel's E scaled to the tilt.
    s += "  float nx = " + parameter(kNormal) + ", ny = " + parameter(kNormal + 1) + ";\n";
    s += "  vec3 n = vec3(nx, ny, sqrt(max(0.0, 1.0 - nx * nx - ny * ny)));\n";
    s += "  float ln = dot(l, n), vn = dot(v, n);\n";
    s += "  if (l.z <= 0.0 || ln <= 0.0) return vec3(0.0);\n";
    s += "  E *= ln / l.z;\n";
    s += "  if (vn <= 0.0 || v.z <= 0.0) return E * albedo;\n";
    s += "  float r = max(" + parameter(6) + ", " + glsl_float(kMinRoughness) + ");\n";
    s += "  float a2 = r * r * r * r;\n";
    s += "  vec3 h = normalize(l + v);\n";
    s += "  float hn = max(dot(h, n), 1e-12);\n";
    s += "  float k = hn * hn * (a2 - 1.0) + 1.0;\n";
    s += "  float gl = sqrt(1.0 + a2 * max(0.0, 1.0 - ln * ln) / (ln * ln));\n";
    s += "  float gv = sqrt(1.0 + a2 * max(0.0, 1.0 - vn * vn) / (vn * vn));\n";
    s += "  float spec = a2 / (k * k) / (0.5 * (gl + gv)) / (4.0 * ln * vn);\n";
    s += "  float sch = pow(1.0 - clamp(dot(v, h), 0.0, 1.0), 5.0);\n";
    s += "  return E * (albedo + (f0 + (1.0 - f0) * sch) * spec);\n}\n";
    return s;
  }
  s += "  if (l.z <= 0.0 || v.z <= 0.0) return E * albedo;\n";
  s += "  float r = max(" + parameter(6) + ", " + glsl_float(kMinRoughness) + ");\n";
  s += "  float a2 = r * r * r * r;\n";
  s += "  vec3 h = normalize(l + v);\n";
  s += "  float k = h.z * h.z * (a2 - 1.0) + 1.0;\n";
  s += "  float gl = sqrt(1.0 + a2 * (l.x * l.x + l.y * l.y) / (l.z * l.z));\n";
  s += "  float gv = sqrt(1.0 + a2 * (v.x * v.x + v.y * v.y) / (v.z * v.z));\n";
  s += "  float spec = a2 / (k * k) / (0.5 * (gl + gv)) / (4.0 * l.z * v.z);\n";
  s += "  float sch = pow(1.0 - clamp(dot(v, h), 0.0, 1.0), 5.0);\n";
  s += "  return E * (albedo + (f0 + (1.0 - f0) * sch) * spec);\n}\n";
  return s;
}

Status GgxModel::check_options(const MapFitOptions& options) const {
  VDRIG_TRY(ReflectanceModel::check_options(options));
  const GgxFitOptions& o = options.model_options.get<GgxFitOptions>();
  if (o.max_iterations < 1) return make_error(ErrorCode::kInvalidArgument, "ggx: max_iterations must be >= 1");
  if (o.light)
    if (const std::string why = o.light->check(); !why.empty())
      return make_error(ErrorCode::kInvalidArgument, "ggx: " + why);
  return Status::ok();
}

std::string GgxModel::options_fingerprint(const MapFitOptions& options) const {
  return options.model_options.get<GgxFitOptions>().fingerprint();
}

Result<ParameterMap> GgxModel::fit_map(const MapFitContext& context) const {
  const MapFitOptions& options = context.options;
  VDRIG_TRY(check_options(options));
  const GgxFitOptions& o = options.model_options.get<GgxFitOptions>();
  if (!o.light)
    return make_error(ErrorCode::kInvalidArgument,
                      "ggx is a BRDF: its fit needs the session's light (vdrig fit --light X,Y,Z[,I] in metres, "
                      "surface frame, or --light-scene SCENE for a simulated session)");
  const SessionLight light = *o.light;
  const int lc = light_channel();
  const ObservationMapSpec& spec = context.spec;
  ParameterMap map(shared_from_this(), spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  const bool holding_out = !options.held_out.empty();
  if (holding_out) map.set_holdout_rms(0, 0, Vec3d::Zero());  // channels before threads
  map.image().string_attributes["vdrig.session_light"] = light.describe();
  std::vector<GgxTexelData> work(static_cast<size_t>(context.workers));
  auto fit_one = [&](int worker, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    if (static_cast<int>(texel.size()) >= options.min_observations) {
      GgxTexelData& d = work[static_cast<size_t>(worker)];
      light.at(texel_centre_mm(s, t, spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm) / 1000.0, &d.light,
               &d.irradiance);
      d.view.clear(), d.half.clear(), d.schlick.clear(), d.radiance.clear();
      for (size_t i = 0; i < texel.size(); ++i) {
        const Vec3d v = texel.direction[i].cast<double>().normalized();
        if (v.z() <= 0.0) continue;  // no BRDF below the horizon (the observation map flags these anyway)
        const Vec3d h = (d.light + v).normalized();
        d.view.push_back(v);
        d.half.push_back(h);
        d.schlick.push_back(std::pow(1.0 - std::clamp(v.dot(h), 0.0, 1.0), 5.0));
        d.radiance.push_back(texel.radiance[i].cast<double>());
      }
      std::vector<double> p(static_cast<size_t>(parameter_count()), 0.0);
      if (d.light.z() > 0.0) {
        if (shading_normal_) {
          const auto material = fit_texel_with_normal(d, o.max_iterations);
          std::copy(material.begin(), material.end(), p.begin());
        } else if (aniso_) {
          const auto material = fit_texel_aniso(d, o.max_iterations);
          std::copy(material.begin(), material.end(), p.begin());
        } else {
          const auto material = fit_texel(d, o.max_iterations);
          std::copy(material.begin(), material.end(), p.begin());
        }
        for (int c = 0; c < 3; ++c) {
          p[static_cast<size_t>(lc + c)] = d.light[c];
          p[static_cast<size_t>(lc + 3 + c)] = d.irradiance[c];
        }
      }
      map.set_parameters(s, t, p);
      q = measure_quality(*this, p, texel);
      if (held.size()) hq = measure_quality(*this, p, held);
    }
    map.set_quality(s, t, q);
    if (holding_out) map.set_holdout_rms(s, t, hq.rms);
  };
  VDRIG_TRY(context.for_each_texel(0, 1, fit_one));
  return map;
}

Result<std::unique_ptr<ModelTiledFit>> GgxModel::tiled_fit(const MapFitOptions&, const ObservationMapSpec&) const {
  return make_error(ErrorCode::kUnsupported,
                    "ggx: tiled and distributed fits are not supported yet (the fit depends on the texel's position "
                    "under the light, which tile jobs do not keep); fit without --mpi");
}

void register_ggx_model(ModelRegistry& registry) {
  registry.add({"ggx",
                "ggx:iso|ggx:iso+n|ggx:aniso",
                [](const std::string& settings) -> Result<ModelPtr> {
                  if (settings == "iso") return ModelPtr(std::make_shared<GgxModel>());
                  if (settings == "iso+n") return ModelPtr(std::make_shared<GgxModel>(GgxModel::Form::kIsoNormal));
                  if (settings == "aniso") return ModelPtr(std::make_shared<GgxModel>(GgxModel::Form::kAniso));
                  return make_error(ErrorCode::kInvalidArgument,
                                    "the form must be iso (ggx:iso), iso+n (ggx:iso+n, with a shading normal) or "
                                    "aniso (ggx:aniso, two roughnesses and an angle)");
                },
                {"ggx:iso", "ggx:iso+n", "ggx:aniso"}});
}

}  // namespace vdrig::fitting
