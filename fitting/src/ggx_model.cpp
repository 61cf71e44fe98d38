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

// Channels after the material: the anisotropic forms' roughness.b and aniso.angle, the shading normal's normal.x/y,
// then (every form) light.x/y/z and E.R/G/B (GgxModel::normal_channel, light_channel).

/// The forms (GgxModel::Form) by name, as the registry parses and lists them.
struct FormName {
  GgxModel::Form form;
  const char* settings;
};
constexpr FormName kFormNames[] = {{GgxModel::Form::kIso, "iso"},
                                   {GgxModel::Form::kIsoNormal, "iso+n"},
                                   {GgxModel::Form::kAniso, "aniso"},
                                   {GgxModel::Form::kAnisoNormal, "aniso+n"}};

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

/// ggx:aniso's pi D G2 / (4 lz vz) (sim/ggx.hpp's anisotropic D and Lambda) from the components of l, v and h in a
/// frame (tangent, bitangent, normal), with alpha_t = rt^2 along the tangent and alpha_b = rb^2 along the bitangent;
/// ln, vn > 0.
double specular_factor_aniso_local(double lt, double lb, double ln, double vt, double vb, double vn, double ht,
                                   double hb, double hn, double rt, double rb) {
  const double at = rt * rt, ab = rb * rb;
  const double hx = ht / at, hy = hb / ab;
  const double q = hx * hx + hy * hy + hn * hn;
  const double pi_d = 1.0 / (at * ab * q * q);
  auto one_plus_two_lambda = [&](double wt, double wb, double wn) {
    const double x = at * wt, y = ab * wb;
    return std::sqrt(1.0 + (x * x + y * y) / (wn * wn));
  };
  const double g_den = 0.5 * (one_plus_two_lambda(lt, lb, ln) + one_plus_two_lambda(vt, vb, vn));  // 1 + L(l) + L(v)
  return pi_d / g_den / (4.0 * ln * vn);
}

/// specular_factor_aniso_local on a flat texel, the tangent at angle phi from the surface's x axis; lz, vz > 0.
double specular_factor_aniso(const Vec3d& l, const Vec3d& v, const Vec3d& h, double rt, double rb, double phi) {
  const double c = std::cos(phi), sn = std::sin(phi);
  auto tangent = [c, sn](const Vec3d& w) { return c * w.x() + sn * w.y(); };
  auto bitangent = [c, sn](const Vec3d& w) { return -sn * w.x() + c * w.y(); };
  return specular_factor_aniso_local(tangent(l), bitangent(l), l.z(), tangent(v), bitangent(v), v.z(), tangent(h),
                                     bitangent(h), h.z(), rt, rb);
}

/// ggx:aniso+n's tangent: the direction (cos phi, sin phi, 0) projected onto the plane of the shading normal n
/// (n.z > 0), unit; the bitangent is n x t.
Vec3d tilted_tangent(double phi, const Vec3d& n) {
  const Vec3d d(std::cos(phi), std::sin(phi), 0.0);
  return (d - n * n.dot(d)).normalized();
}

/// The angle phi in [0, pi) whose tilted_tangent under n is the direction of w (in n's plane, nonzero): w projected
/// along n onto the surface's plane.
double tilted_tangent_angle(const Vec3d& w, const Vec3d& n) {
  const Vec3d d = w - n * (w.z() / n.z());
  double phi = std::fmod(std::atan2(d.y(), d.x()), kPi);
  if (phi < 0.0) phi += kPi;
  return phi;
}

/// specular_factor_aniso on a texel with shading normal n (ln = l . n, vn = v . n > 0), tangent tilted_tangent(phi).
double specular_factor_aniso_tilted(const Vec3d& l, const Vec3d& v, const Vec3d& h, const Vec3d& n, double rt,
                                    double rb, double phi) {
  const Vec3d t = tilted_tangent(phi, n), b = n.cross(t);
  return specular_factor_aniso_local(l.dot(t), l.dot(b), l.dot(n), v.dot(t), v.dot(b), v.dot(n), h.dot(t), h.dot(b),
                                     h.dot(n), rt, rb);
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

/// A form's shape: what follows albedo and f0 in its parameters (the roughness first, then the form's own), and per
/// observation the two factors of its residual E g (albedo + s (f0 (1 - S) + S)) - L: g, the irradiance on the texel
/// relative to the flat texel's (1 without a shading normal), and s, the specular factor pi D G2 / (4 lz vz) in the
/// texel's frame. A shape is
///   static constexpr int kShape;                // its parameter count (q = p[6 ..])
///   static constexpr bool kTilts;               // g varies (a shading normal)
///   static constexpr bool kAnalyticRoughness;   // geometry() gives ds/dq[0]; the others are central differences
///   static bool admissible(const double* q);    // inside the bounds the geometry is defined in
///   static void geometry(const GgxTexelData&, size_t i, const double* q, double* g, double* s, double* ds_dr);
struct IsoShape {
  static constexpr int kShape = 1;
  static constexpr bool kTilts = false, kAnalyticRoughness = true;
  static bool admissible(const double*) { return true; }
  static void geometry(const GgxTexelData& d, size_t i, const double* q, double* g, double* s, double* ds_dr) {
    *g = 1.0;
    *s = specular_factor(d.light, d.view[i], d.half[i], q[0], ds_dr);
  }
};

/// ggx:iso+n: roughness, normal.x/y. g = (l . n) / lz; s = specular_factor_cos (0 when v . n <= 0; both 0 when
/// l . n <= 0).
struct NormalShape {
  static constexpr int kShape = 3;
  static constexpr bool kTilts = true, kAnalyticRoughness = true;
  static bool admissible(const double* q) {
    Vec3d n = Vec3d::UnitZ();
    return shading_normal(q[1], q[2], &n);
  }
  static void geometry(const GgxTexelData& d, size_t i, const double* q, double* g, double* s, double* ds_dr) {
    Vec3d n = Vec3d::UnitZ();
    shading_normal(q[1], q[2], &n);
    const double ln = d.light.dot(n), vn = d.view[i].dot(n);
    *g = ln > 0.0 ? ln / d.light.z() : 0.0;
    *s = 0.0;
    if (ds_dr) *ds_dr = 0.0;
    if (ln > 0.0 && vn > 0.0) *s = specular_factor_cos(ln, vn, std::max(d.half[i].dot(n), 1e-12), q[0], ds_dr);
  }
};

/// ggx:aniso: roughness (along the tangent), roughness.b, aniso.angle; flat.
struct AnisoShape {
  static constexpr int kShape = 3;
  static constexpr bool kTilts = false, kAnalyticRoughness = false;
  static bool admissible(const double* q) { return q[0] > 0.0 && q[1] > 0.0; }
  static void geometry(const GgxTexelData& d, size_t i, const double* q, double* g, double* s, double*) {
    *g = 1.0;
    *s = specular_factor_aniso(d.light, d.view[i], d.half[i], q[0], q[1], q[2]);
  }
};

/// ggx:aniso+n: aniso's three, then normal.x/y; g and the horizons as NormalShape's.
struct AnisoNormalShape {
  static constexpr int kShape = 5;
  static constexpr bool kTilts = true, kAnalyticRoughness = false;
  static bool admissible(const double* q) {
    Vec3d n = Vec3d::UnitZ();
    return q[0] > 0.0 && q[1] > 0.0 && shading_normal(q[3], q[4], &n);
  }
  static void geometry(const GgxTexelData& d, size_t i, const double* q, double* g, double* s, double*) {
    Vec3d n = Vec3d::UnitZ();
    shading_normal(q[3], q[4], &n);
    const double ln = d.light.dot(n), vn = d.view[i].dot(n);
    *g = ln > 0.0 ? ln / d.light.z() : 0.0;
    *s = ln > 0.0 && vn > 0.0 ? specular_factor_aniso_tilted(d.light, d.view[i], d.half[i], n, q[0], q[1], q[2]) : 0.0;
  }
};

/// The least-squares cost of a form's parameters (albedo, f0, then the shape's) for bounded_lm.hpp: the residual
/// above per observation and colour. Derivatives in the shape's parameters without analytic ones are central
/// differences (the model is smooth there; analytic ones would triple the code for no accuracy the fit needs),
/// one-sided where a step leaves the admissible region (the tilt bound).
template <class Shape>
struct GgxTexelCost {
  static constexpr int kShape = Shape::kShape, kParams = 6 + kShape;
  using Vec = Eigen::Matrix<double, kParams, 1>;
  using Mat = Eigen::Matrix<double, kParams, kParams>;
  using Q = std::array<double, kShape>;
  const GgxTexelData* data = nullptr;

  double evaluate(const Vec& p, Mat* jtj, Vec* jtr) const {
    Q q;
    std::copy(p.data() + 6, p.data() + kParams, q.begin());
    if (!Shape::admissible(q.data())) return std::numeric_limits<double>::infinity();
    constexpr double kStep = 1e-6;
    constexpr int kFirstDifference = Shape::kAnalyticRoughness ? 1 : 0;
    std::array<Q, kShape> plus{}, minus{};
    std::array<double, kShape> width{};
    if (jtj)
      for (int k = kFirstDifference; k < kShape; ++k) {
        plus[k] = minus[k] = q;
        plus[k][k] += kStep;
        minus[k][k] -= kStep;
        const bool up = Shape::admissible(plus[k].data()), down = Shape::admissible(minus[k].data());
        if (!up) plus[k] = q;
        if (!down) minus[k] = q;
        width[k] = (up ? kStep : 0.0) + (down ? kStep : 0.0);
      }
    double cost = 0;
    if (jtj) {
      jtj->setZero();
      jtr->setZero();
    }
    const GgxTexelData& d = *data;
    for (size_t i = 0; i < d.view.size(); ++i) {
      double g = 0, s = 0;
      std::array<double, kShape> ds{}, dg{};
      Shape::geometry(d, i, q.data(), &g, &s, jtj && Shape::kAnalyticRoughness ? &ds[0] : nullptr);
      if (jtj)
        for (int k = kFirstDifference; k < kShape; ++k) {
          double gp, sp, gm, sm;
          Shape::geometry(d, i, plus[k].data(), &gp, &sp, nullptr);
          Shape::geometry(d, i, minus[k].data(), &gm, &sm, nullptr);
          dg[k] = (gp - gm) / width[k];
          ds[k] = (sp - sm) / width[k];
        }
      const double sch = d.schlick[i];
      for (int c = 0; c < 3; ++c) {
        const double e = d.irradiance[c];  // the flat texel's: E g on a tilted one
        const double fresnel = p[3 + c] * (1.0 - sch) + sch;
        double r = 0;
        std::array<double, 2 + kShape> jac{};
        if constexpr (Shape::kTilts) {
          const double inner = p[c] + s * fresnel, eg = e * g;
          r = eg * inner - d.radiance[i][c];
          jac[0] = eg, jac[1] = eg * s * (1.0 - sch);
          for (int k = 0; k < kShape; ++k)
            jac[static_cast<size_t>(2 + k)] =
                k < kFirstDifference ? eg * fresnel * ds[k] : e * (dg[k] * inner + g * fresnel * ds[k]);
        } else {
          r = e * (p[c] + s * fresnel) - d.radiance[i][c];
          jac[0] = e, jac[1] = e * s * (1.0 - sch);
          for (int k = 0; k < kShape; ++k) jac[static_cast<size_t>(2 + k)] = e * fresnel * ds[k];
        }
        cost += 0.5 * r * r;
        if (jtj) {
          // Nonzero Jacobian entries of this residual: albedo_c, f0_c, the shape's.
          std::array<int, 2 + kShape> idx{};
          idx[0] = c, idx[1] = 3 + c;
          for (int k = 0; k < kShape; ++k) idx[static_cast<size_t>(2 + k)] = 6 + k;
          for (size_t a = 0; a < idx.size(); ++a) {
            (*jtr)[idx[a]] += jac[a] * r;
            for (size_t b = 0; b < idx.size(); ++b) (*jtj)(idx[a], idx[b]) += jac[a] * jac[b];
          }
        }
      }
    }
    return cost;
  }
};

/// The bounded LM on a form's parameters from `start`; the start back when the LM's result is not finite. Returns
/// the final cost.
template <class Shape>
double minimise(const GgxTexelData& d, typename GgxTexelCost<Shape>::Vec& p,
                const typename GgxTexelCost<Shape>::Vec& lo, const typename GgxTexelCost<Shape>::Vec& hi,
                int max_iterations) {
  using Cost = GgxTexelCost<Shape>;
  const Cost cost{&d};
  const typename Cost::Vec start = p;
  double final_cost = std::numeric_limits<double>::infinity();
  minimise_bounded(cost, p, lo, hi, Eigen::Matrix<bool, Cost::kParams, 1>::Constant(false), max_iterations,
                   &final_cost);
  if (!p.allFinite() || !(final_cost < std::numeric_limits<double>::infinity()))
    p = start, final_cost = cost.evaluate(p, nullptr, nullptr);
  return final_cost;
}

using Params = std::vector<double>;  // a form's parameters without the light's (material, then the shape's)

/// ggx:iso's texel: for each roughness of a grid, albedo and f0 per colour by bounded linear least squares (the
/// radiance is linear in them at a fixed roughness), the best as the start of the bounded LM on all seven. The grid
/// makes the start independent of where the views happen to fall (no peak to find first).
Params fit_texel(const GgxTexelData& d, int max_iterations) {
  Params best(GgxModel::kMaterialParameters, 0.0);
  const size_t n = d.view.size();
  if (d.irradiance.maxCoeff() <= 0.0 || n == 0) return best;  // unlit: nothing to measure the material by
  const double r_min = ggx_supported_roughness(d.half);
  double best_cost = std::numeric_limits<double>::infinity();
  std::vector<double> s(n);
  for (double r = r_min; r <= 1.0 + 1e-9; r *= 1.25) {
    for (size_t i = 0; i < n; ++i) s[i] = specular_factor(d.light, d.view[i], d.half[i], r, nullptr);
    Params p(GgxModel::kMaterialParameters, 0.0);
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
  GgxTexelCost<IsoShape>::Vec p = Eigen::Map<const GgxTexelCost<IsoShape>::Vec>(best.data()), lo, hi;
  const double inf = std::numeric_limits<double>::infinity();
  lo << 0, 0, 0, 0, 0, 0, r_min;
  hi << inf, inf, inf, 1, 1, 1, 1;
  double final_cost = 0;
  const GgxTexelCost<IsoShape>::Vec start = p;
  minimise_bounded(GgxTexelCost<IsoShape>{&d}, p, lo, hi, Eigen::Matrix<bool, 7, 1>::Constant(false), max_iterations,
                   &final_cost);
  if (!p.allFinite()) p = start;
  std::copy(p.data(), p.data() + GgxModel::kMaterialParameters, best.begin());
  return best;
}

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

/// A texel's observations in the frame `r` (frame_of a normal): the flat fits there see the tilted texel (its
/// irradiance scaled to the tilt); observations below that normal's horizon are left out (no highlight there). False
/// when the light is below it or no observation is left.
bool local_data(const GgxTexelData& d, const Mat3d& r, GgxTexelData* local) {
  local->light = r * d.light;
  if (local->light.z() <= 0.0) return false;
  local->irradiance = d.irradiance * (local->light.z() / d.light.z());
  for (size_t i = 0; i < d.view.size(); ++i) {
    const Vec3d v = r * d.view[i];
    if (v.z() <= 0.0) continue;
    local->view.push_back(v);
    local->half.push_back(r * d.half[i]);
    local->schlick.push_back(d.schlick[i]);
    local->radiance.push_back(d.radiance[i]);
  }
  return !local->view.empty();
}

/// The starting normals of a form with a shading normal: the flat one and the half vector of the brightest
/// observation (the highlight's peak; its tilt capped at 45 deg).
std::array<Vec3d, 2> starting_normals(const GgxTexelData& d) {
  size_t brightest = 0;
  for (size_t i = 1; i < d.view.size(); ++i)
    if (d.radiance[i].sum() > d.radiance[brightest].sum()) brightest = i;
  Vec3d peak = d.half[brightest];
  const double max_sin = std::sqrt(0.5);
  if (peak.head<2>().norm() > max_sin) {
    const Eigen::Vector2d xy = peak.head<2>().normalized() * max_sin;
    peak = Vec3d(xy.x(), xy.y(), std::sqrt(0.5));
  }
  return {Vec3d::UnitZ(), peak};
}

/// ggx:iso+n's texel: from each starting normal, ggx:iso's fit in that normal's frame gives the material, then the
/// bounded LM on all nine parameters; the lower cost wins. The flat start keeps texels without a highlight (matte,
/// or seen from too few views) from being tilted toward noise.
Params fit_texel_with_normal(const GgxTexelData& d, int max_iterations) {
  Params best(GgxModel::kMaterialParameters + 2, 0.0);
  if (d.irradiance.maxCoeff() <= 0.0 || d.view.empty()) return best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (const Vec3d& n0 : starting_normals(d)) {
    GgxTexelData local;
    if (!local_data(d, frame_of(n0), &local)) continue;
    const Params material = fit_texel(local, max_iterations);
    GgxTexelCost<NormalShape>::Vec p, lo, hi;
    for (int k = 0; k < GgxModel::kMaterialParameters; ++k) p[k] = material[static_cast<size_t>(k)];
    p[7] = n0.x(), p[8] = n0.y();
    const double inf = std::numeric_limits<double>::infinity();
    lo << 0, 0, 0, 0, 0, 0, ggx_supported_roughness(local.half), -1, -1;
    hi << inf, inf, inf, 1, 1, 1, 1, 1, 1;
    const double final_cost = minimise<NormalShape>(d, p, lo, hi, max_iterations);
    if (final_cost < best_cost) best_cost = final_cost, best.assign(p.data(), p.data() + p.size());
  }
  return best;
}

/// ggx:aniso's texel: ggx:iso's fit gives the roughness r; from four tangent angles (0, 45, 90, 135 deg) with the
/// roughnesses split around r, the bounded LM on all nine; the lowest cost wins, the isotropic fit itself included
/// (so no texel fits worse than ggx:iso). Then the canonical form: roughness >= roughness.b (swapped with the angle
/// turned by 90 deg, the same BRDF) and the angle in [0, pi).
Params fit_texel_aniso(const GgxTexelData& d, int max_iterations) {
  Params best(GgxModel::kMaterialParameters + 2, 0.0);
  if (d.irradiance.maxCoeff() <= 0.0 || d.view.empty()) return best;
  const Params iso = fit_texel(d, max_iterations);
  const double r_min = ggx_supported_roughness(d.half);
  using Vec = GgxTexelCost<AnisoShape>::Vec;
  Vec p;
  for (int k = 0; k < GgxModel::kMaterialParameters; ++k) p[k] = iso[static_cast<size_t>(k)];
  p[7] = p[6], p[8] = 0.0;
  Vec best_p = p;
  double best_cost = GgxTexelCost<AnisoShape>{&d}.evaluate(p, nullptr, nullptr);
  const double inf = std::numeric_limits<double>::infinity();
  Vec lo, hi;
  lo << 0, 0, 0, 0, 0, 0, r_min, r_min, -inf;
  hi << inf, inf, inf, 1, 1, 1, 1, 1, inf;
  for (int k = 0; k < 4; ++k) {
    Vec q = best_p;
    for (int j = 0; j < GgxModel::kMaterialParameters; ++j) q[j] = iso[static_cast<size_t>(j)];
    q[6] = std::min(1.0, iso[6] * 1.2), q[7] = std::max(r_min, iso[6] / 1.2), q[8] = k * kPi / 4.0;
    double final_cost = inf;
    minimise_bounded(GgxTexelCost<AnisoShape>{&d}, q, lo, hi, Eigen::Matrix<bool, 9, 1>::Constant(false),
                     max_iterations, &final_cost);
    if (q.allFinite() && final_cost < best_cost) best_cost = final_cost, best_p = q;
  }
  if (best_p[6] < best_p[7]) std::swap(best_p[6], best_p[7]), best_p[8] += kPi / 2.0;
  best_p[8] = std::fmod(best_p[8], kPi);
  if (best_p[8] < 0.0) best_p[8] += kPi;
  best.assign(best_p.data(), best_p.data() + best_p.size());
  return best;
}

/// ggx:aniso+n's texel, from the two forms' starts: ggx:iso+n's fit gives the shading normal, ggx:aniso's fit in that
/// normal's frame the roughnesses and the tangent (turned back to the surface's angle); then the bounded LM on all
/// eleven. ggx:iso+n's own result (roughness.b = roughness) competes, so no texel fits worse than ggx:iso+n. Then the
/// canonical form: roughness >= roughness.b (swapped, the tangent becoming the old bitangent) and the angle in
/// [0, pi).
Params fit_texel_aniso_normal(const GgxTexelData& d, int max_iterations) {
  Params best(GgxModel::kMaterialParameters + 4, 0.0);
  if (d.irradiance.maxCoeff() <= 0.0 || d.view.empty()) return best;
  const Params with_normal = fit_texel_with_normal(d, max_iterations);
  Vec3d n = Vec3d::UnitZ();
  if (!shading_normal(with_normal[7], with_normal[8], &n)) return best;
  using Vec = GgxTexelCost<AnisoNormalShape>::Vec;
  const GgxTexelCost<AnisoNormalShape> cost{&d};
  Vec best_p;
  for (int k = 0; k < GgxModel::kMaterialParameters; ++k) best_p[k] = with_normal[static_cast<size_t>(k)];
  best_p[7] = best_p[6], best_p[8] = 0.0, best_p[9] = n.x(), best_p[10] = n.y();
  double best_cost = cost.evaluate(best_p, nullptr, nullptr);
  const Mat3d r = frame_of(n);
  GgxTexelData local;
  if (local_data(d, r, &local)) {
    const Params aniso = fit_texel_aniso(local, max_iterations);
    Vec p;
    for (int k = 0; k < 8; ++k) p[k] = aniso[static_cast<size_t>(k)];
    const Vec3d tangent = r.transpose() * Vec3d(std::cos(aniso[8]), std::sin(aniso[8]), 0.0);
    p[8] = tilted_tangent_angle(tangent, n), p[9] = n.x(), p[10] = n.y();
    const double inf = std::numeric_limits<double>::infinity(), r_min = ggx_supported_roughness(local.half);
    Vec lo, hi;
    lo << 0, 0, 0, 0, 0, 0, r_min, r_min, -inf, -1, -1;
    hi << inf, inf, inf, 1, 1, 1, 1, 1, inf, 1, 1;
    const double final_cost = minimise<AnisoNormalShape>(d, p, lo, hi, max_iterations);
    if (final_cost < best_cost) best_cost = final_cost, best_p = p;
  }
  if (!shading_normal(best_p[9], best_p[10], &n)) return best;
  if (best_p[6] < best_p[7]) {
    std::swap(best_p[6], best_p[7]);
    best_p[8] = tilted_tangent_angle(n.cross(tilted_tangent(best_p[8], n)), n);  // the old bitangent's angle
  }
  best_p[8] = std::fmod(best_p[8], kPi);
  if (best_p[8] < 0.0) best_p[8] += kPi;
  best.assign(best_p.data(), best_p.data() + best_p.size());
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

std::string GgxModel::name() const {
  const Form form = shading_normal_ ? (aniso_ ? Form::kAnisoNormal : Form::kIsoNormal)
                    : aniso_        ? Form::kAniso
                                    : Form::kIso;
  for (const FormName& f : kFormNames)
    if (f.form == form) return std::string("ggx:") + f.settings;
  VDRIG_CHECK(false, "GgxModel: a form without a name");
  return {};
}

std::vector<std::string> GgxModel::channels() const {
  std::vector<std::string> c = {"albedo.R", "albedo.G", "albedo.B", "f0.R", "f0.G", "f0.B", "roughness"};
  if (aniso_) c.insert(c.end(), {"roughness.b", "aniso.angle"});
  if (shading_normal_) c.insert(c.end(), {"normal.x", "normal.y"});
  c.insert(c.end(), {"light.x", "light.y", "light.z", "E.R", "E.G", "E.B"});
  return c;
}

GgxMaterial GgxModel::material(std::span<const double> p) {
  VDRIG_CHECK(p.size() >= static_cast<size_t>(kMaterialParameters), "GgxModel: too few parameters");
  return {Vec3d(p[0], p[1], p[2]), Vec3d(p[3], p[4], p[5]), p[6]};
}

GgxMaterial GgxModel::texel_material(std::span<const double> p) const {
  GgxMaterial m = material(p);
  const size_t nc = static_cast<size_t>(normal_channel());
  if (shading_normal_ && !shading_normal(p[nc], p[nc + 1], &m.normal, kTiltStorageSlack))
    m.normal = Vec3d(p[nc], p[nc + 1], 0.0).normalized();  // past the tilt bound: at the horizon
  if (aniso_) m.roughness_b = p[kMaterialParameters], m.angle = p[kMaterialParameters + 1];
  return m;
}

Vec3d GgxModel::brdf(const GgxMaterial& m, const Vec3d& l, const Vec3d& v) {
  const double ln = l.dot(m.normal), vn = v.dot(m.normal);
  if (ln <= 0.0 || vn <= 0.0) return Vec3d::Zero();
  const Vec3d h = (l + v).normalized();
  const double r = std::max(m.roughness, kMinRoughness);
  if (m.roughness_b > 0.0) {  // anisotropic; the flat texel keeps the rotation form (ggx:aniso's figures)
    const double rb = std::max(m.roughness_b, kMinRoughness);
    const double s = m.normal == Vec3d::UnitZ() ? specular_factor_aniso(l, v, h, r, rb, m.angle)
                                                : specular_factor_aniso_tilted(l, v, h, m.normal, r, rb, m.angle);
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
  const size_t nc = static_cast<size_t>(normal_channel());
  if (shading_normal_ && p[nc] * p[nc] + p[nc + 1] * p[nc + 1] > kMaxTilt + kTiltStorageSlack)
    return fmt::format("the normal is tilted past the bound (x^2 + y^2 = {} > {})",
                       p[nc] * p[nc] + p[nc + 1] * p[nc + 1], kMaxTilt);
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
  std::vector<double> p = {0.5 + 0.1 * std::sin(phase), 0.4, 0.3, 0.04, 0.05, 0.06, 0.5 + 0.1 * std::cos(1.3 * phase)};
  if (!aniso_ && !shading_normal_) {
    p[2] = 0.3 + 0.1 * std::cos(phase), p[4] = 0.05 + 0.02 * std::sin(phase);
    p[6] = 0.55 + 0.1 * std::sin(1.7 * phase);
  }
  if (aniso_) {
    p[6] = 0.6 + 0.1 * std::cos(1.3 * phase);
    p.insert(p.end(), {0.3 + 0.1 * std::sin(0.7 * phase), 1.5 + 1.2 * std::sin(1.9 * phase)});
  }
  if (shading_normal_) p.insert(p.end(), {0.15 * std::sin(2.1 * phase), 0.1 * std::cos(0.7 * phase)});
  p.insert(p.end(), {l.x(), l.y(), l.z(), 1.5, 1.4, 1.3});
  return p;
}

std::string GgxModel::glsl(const std::function<std::string(int parameter)>& parameter) const {
  auto vec3_of = [&](int i) {
    return "vec3(" + parameter(i) + ", " + parameter(i + 1) + ", " + parameter(i + 2) + ")";
  };
  auto roughness = [&](int i) { return "max(" + parameter(i) + ", " + glsl_float(kMinRoughness) + ")"; };
  std::string s = "vec3 model(ivec2 t, vec3 v) {\n";
  s += "  vec3 albedo = " + vec3_of(0) + ";\n  vec3 f0 = " + vec3_of(3) + ";\n";
  s += "  vec3 l = " + vec3_of(light_channel()) + ";\n  vec3 E = " + vec3_of(light_channel() + 3) + ";\n";
  // The horizons and the irradiance, as evaluate(): the flat texel's E scaled to a shading normal's tilt.
  if (shading_normal_) {
    s += "  float nx = " + parameter(normal_channel()) + ", ny = " + parameter(normal_channel() + 1) + ";\n";
    s += "  vec3 n = vec3(nx, ny, sqrt(max(0.0, 1.0 - nx * nx - ny * ny)));\n";
    s += "  float ln = dot(l, n), vn = dot(v, n);\n";
    s += "  if (l.z <= 0.0 || ln <= 0.0) return vec3(0.0);\n";
    s += "  E *= ln / l.z;\n";
    s += "  if (vn <= 0.0 || v.z <= 0.0) return E * albedo;\n";
  } else {
    s += "  if (l.z <= 0.0 || v.z <= 0.0) return E * albedo;\n";
  }
  // The specular factor pi D G2 / (4 (l . n) (v . n)).
  if (aniso_) {
    // sim/ggx.hpp's anisotropic D and Lambda in the frame of the tangent at aniso.angle (projected onto the shading
    // normal's plane for ggx:aniso+n).
    s += "  float at = " + roughness(6) + ";\n  at *= at;\n";
    s += "  float ab = " + roughness(kMaterialParameters) + ";\n  ab *= ab;\n";
    s += "  float phi = " + parameter(kMaterialParameters + 1) + ";\n";
    s += "  vec3 h = normalize(l + v);\n";
    if (shading_normal_) {
      s += "  vec3 dir = vec3(cos(phi), sin(phi), 0.0);\n";
      s += "  vec3 tg = normalize(dir - n * dot(n, dir)), bt = cross(n, tg);\n";
      s += "  vec2 hl = vec2(dot(h, tg), dot(h, bt)), ll = vec2(dot(l, tg), dot(l, bt)), vl = vec2(dot(v, tg), "
           "dot(v, bt));\n";
      s += "  float hn = dot(h, n);\n";
    } else {
      s += "  mat2 rot = mat2(cos(phi), -sin(phi), sin(phi), cos(phi));\n";  // columns: (c, -s), (s, c)
      s += "  vec2 hl = rot * h.xy, ll = rot * l.xy, vl = rot * v.xy;\n";
      s += "  float hn = h.z, ln = l.z, vn = v.z;\n";
    }
    s += "  float q = (hl.x / at) * (hl.x / at) + (hl.y / ab) * (hl.y / ab) + hn * hn;\n";
    s += "  float gl = sqrt(1.0 + ((at * ll.x) * (at * ll.x) + (ab * ll.y) * (ab * ll.y)) / (ln * ln));\n";
    s += "  float gv = sqrt(1.0 + ((at * vl.x) * (at * vl.x) + (ab * vl.y) * (ab * vl.y)) / (vn * vn));\n";
    s += "  float spec = 1.0 / (at * ab * q * q) / (0.5 * (gl + gv)) / (4.0 * ln * vn);\n";
  } else {
    // Trowbridge-Reitz and Smith in the cosines (the normal's frame: wx^2 + wy^2 = 1 - (w . n)^2) or, flat, in the
    // components (ggx:iso's figures).
    s += "  float r = " + roughness(6) + ";\n";
    s += "  float a2 = r * r * r * r;\n";
    s += "  vec3 h = normalize(l + v);\n";
    if (shading_normal_) {
      s += "  float hn = max(dot(h, n), 1e-12);\n";
      s += "  float k = hn * hn * (a2 - 1.0) + 1.0;\n";
      s += "  float gl = sqrt(1.0 + a2 * max(0.0, 1.0 - ln * ln) / (ln * ln));\n";
      s += "  float gv = sqrt(1.0 + a2 * max(0.0, 1.0 - vn * vn) / (vn * vn));\n";
      s += "  float spec = a2 / (k * k) / (0.5 * (gl + gv)) / (4.0 * ln * vn);\n";
    } else {
      s += "  float k = h.z * h.z * (a2 - 1.0) + 1.0;\n";
      s += "  float gl = sqrt(1.0 + a2 * (l.x * l.x + l.y * l.y) / (l.z * l.z));\n";
      s += "  float gv = sqrt(1.0 + a2 * (v.x * v.x + v.y * v.y) / (v.z * v.z));\n";
      s += "  float spec = a2 / (k * k) / (0.5 * (gl + gv)) / (4.0 * l.z * v.z);\n";
    }
  }
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
  return fit_region(context, 0, 0, context.spec);
}

Result<ParameterMap> GgxModel::fit_region(const MapFitContext& context, int s0, int t0,
                                          const ObservationMapSpec& whole) const {
  const MapFitOptions& options = context.options;
  VDRIG_TRY(check_options(options));
  const GgxFitOptions& o = options.model_options.get<GgxFitOptions>();
  if (!o.light)
    return make_error(ErrorCode::kInvalidArgument,
                      "ggx is a BRDF: its fit needs the session's light (vdrig fit --light X,Y,Z[,I] in metres, "
                      "surface frame, --light-scene SCENE, --light estimate, or the lamp the session recorded)");
  const SessionLight light = *o.light;
  const int lc = light_channel();
  const ObservationMapSpec& spec = context.spec;
  ParameterMap map(shared_from_this(), spec.texels_s, spec.texels_t, spec.width_mm, spec.height_mm);
  const bool holding_out = !options.held_out.empty();
  if (holding_out) map.set_holdout_rms(0, 0, Vec3d::Zero());  // channels before threads
  map.image().string_attributes["vdrig.session_light"] = light.describe();
  const auto fit_material = shading_normal_ ? (aniso_ ? fit_texel_aniso_normal : fit_texel_with_normal)
                                            : (aniso_ ? fit_texel_aniso : fit_texel);
  std::vector<GgxTexelData> work(static_cast<size_t>(context.workers));
  auto fit_one = [&](int worker, int s, int t, const TexelObservations& texel, const TexelObservations& held) {
    FitQuality q, hq;
    q.samples = static_cast<int>(texel.size());
    if (static_cast<int>(texel.size()) >= options.min_observations) {
      GgxTexelData& d = work[static_cast<size_t>(worker)];
      // The light's direction and irradiance at the texel's place on the whole map.
      const Vec3d centre_mm =
          texel_centre_mm(s0 + s, t0 + t, whole.texels_s, whole.texels_t, whole.width_mm, whole.height_mm);
      light.at(centre_mm / 1000.0, &d.light, &d.irradiance);
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
        const Params material = fit_material(d, o.max_iterations);
        VDRIG_CHECK(static_cast<int>(material.size()) == lc, "GgxModel: a form's fit of the wrong size");
        std::copy(material.begin(), material.end(), p.begin());
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

namespace {

/// The per-texel tiled fit with the map's attribute the tile maps' channels do not carry (vdrig.session_light).
class GgxTiledFit final : public ModelTiledFit {
 public:
  GgxTiledFit(std::unique_ptr<ModelTiledFit> tiles, std::string light)
      : tiles_(std::move(tiles)), light_(std::move(light)) {}
  Result<TileBytes> fit_tile(int pass, const TileWork& work, const TileBytes* previous) override {
    return tiles_->fit_tile(pass, work, previous);
  }
  Result<ParameterMap> assemble(const std::vector<TileRect>& tiles,
                                const std::function<Result<TileBytes>(int tile)>& record) override {
    auto map = tiles_->assemble(tiles, record);
    if (map) map->image().string_attributes["vdrig.session_light"] = light_;
    return map;
  }

 private:
  std::unique_ptr<ModelTiledFit> tiles_;
  std::string light_;
};

}  // namespace

Result<std::unique_ptr<ModelTiledFit>> GgxModel::tiled_fit(const MapFitOptions& options,
                                                           const ObservationMapSpec& spec) const {
  auto self = std::static_pointer_cast<const GgxModel>(shared_from_this());
  auto tiles = per_texel_tiled_fit(
      self, options, spec, [self](const MapFitContext& context, const TileRect& rect, const ObservationMapSpec& whole) {
        return self->fit_region(context, rect.s0, rect.t0, whole);
      });
  if (!tiles) return tiles.error();
  const auto& light = options.model_options.get<GgxFitOptions>().light;  // checked by per_texel_tiled_fit
  return std::unique_ptr<ModelTiledFit>(
      std::make_unique<GgxTiledFit>(std::move(tiles.value()), light ? light->describe() : std::string()));
}

void register_ggx_model(ModelRegistry& registry) {
  std::string syntax;
  std::vector<std::string> names;
  for (const FormName& f : kFormNames) {
    names.push_back(std::string("ggx:") + f.settings);
    syntax += (syntax.empty() ? "" : "|") + names.back();
  }
  registry.add({"ggx", syntax,
                [](const std::string& settings) -> Result<ModelPtr> {
                  for (const FormName& f : kFormNames)
                    if (settings == f.settings) return ModelPtr(std::make_shared<GgxModel>(f.form));
                  return make_error(ErrorCode::kInvalidArgument,
                                    "the form must be iso (ggx:iso), iso+n (ggx:iso+n, with a shading normal), aniso "
                                    "(ggx:aniso, two roughnesses and an angle) or aniso+n (ggx:aniso+n, both)");
                },
                names});
}

}  // namespace vdrig::fitting
