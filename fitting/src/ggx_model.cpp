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

constexpr int kLightDirection = GgxModel::kMaterialParameters;  // light.x/y/z
constexpr int kIrradiance = kLightDirection + 3;                // E.R/G/B
constexpr int kParameters = kIrradiance + 3;

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
  return {"albedo.R", "albedo.G", "albedo.B", "f0.R", "f0.G", "f0.B", "roughness",
          "light.x",  "light.y",  "light.z",  "E.R",  "E.G",  "E.B"};
}

GgxMaterial GgxModel::material(std::span<const double> p) {
  VDRIG_CHECK(p.size() >= static_cast<size_t>(kMaterialParameters), "GgxModel: too few parameters");
  return {Vec3d(p[0], p[1], p[2]), Vec3d(p[3], p[4], p[5]), p[6]};
}

Vec3d GgxModel::brdf(const GgxMaterial& m, const Vec3d& l, const Vec3d& v) {
  if (l.z() <= 0.0 || v.z() <= 0.0) return Vec3d::Zero();
  const Vec3d h = (l + v).normalized();
  const double s = specular_factor(l, v, h, std::max(m.roughness, kMinRoughness), nullptr);
  const double sch = std::pow(1.0 - std::clamp(v.dot(h), 0.0, 1.0), 5.0);
  const Vec3d fresnel = m.f0 + (Vec3d::Ones() - m.f0) * sch;
  return (m.albedo + fresnel * s) / kPi;
}

Vec3d GgxModel::evaluate(std::span<const double> p, const Vec3d& v) const {
  VDRIG_CHECK(static_cast<int>(p.size()) == kParameters, "GgxModel: wrong parameter count");
  const Vec3d l(p[kLightDirection], p[kLightDirection + 1], p[kLightDirection + 2]);
  const Vec3d e(p[kIrradiance], p[kIrradiance + 1], p[kIrradiance + 2]);
  const GgxMaterial m = material(p);
  if (l.z() <= 0.0 || v.z() <= 0.0) return e.cwiseProduct(m.albedo);  // no specular term below either horizon
  return kPi * e.cwiseProduct(brdf(m, l, v));
}

std::string GgxModel::check_parameters(std::span<const double> p) const {
  for (int i = 0; i < 3; ++i) {
    if (p[static_cast<size_t>(i)] < 0) return fmt::format("albedo is negative ({})", p[static_cast<size_t>(i)]);
    if (p[static_cast<size_t>(3 + i)] < 0 || p[static_cast<size_t>(3 + i)] > 1)
      return fmt::format("f0 is outside [0, 1] ({})", p[static_cast<size_t>(3 + i)]);
    if (p[static_cast<size_t>(kIrradiance + i)] < 0)
      return fmt::format("irradiance is negative ({})", p[static_cast<size_t>(kIrradiance + i)]);
  }
  if (p[6] < 0 || p[6] > 1) return fmt::format("roughness is outside [0, 1] ({})", p[6]);
  const double norm = Vec3d(p[kLightDirection], p[kLightDirection + 1], p[kLightDirection + 2]).norm();
  if (norm != 0.0 && std::abs(norm - 1.0) > 1e-3) return fmt::format("light direction is not unit ({})", norm);
  return {};
}

Vec3d GgxModel::diffuse_part(std::span<const double> p) const {
  return Vec3d(p[kIrradiance], p[kIrradiance + 1], p[kIrradiance + 2]).cwiseProduct(material(p).albedo);
}

std::vector<LobeSummary> GgxModel::lobes(std::span<const double> p) const {
  const Vec3d l(p[kLightDirection], p[kLightDirection + 1], p[kLightDirection + 2]);
  if (l.z() <= 0.0) return {};
  LobeSummary lobe;
  lobe.direction = Vec3d(-l.x(), -l.y(), l.z());  // the mirror direction: the peak of D (h = n)
  lobe.peak_rgb = evaluate(p, lobe.direction) - diffuse_part(p);
  // The Phong exponent of the same width near the peak (Walter et al. 2007): m = 2 / alpha^2 - 2.
  const double alpha = std::max(p[6], kMinRoughness) * std::max(p[6], kMinRoughness);
  lobe.phong_exponent = std::max(0.0, 2.0 / (alpha * alpha) - 2.0);
  return {lobe};
}

std::vector<double> GgxModel::sample_parameters(unsigned seed) const {
  const double phase = 0.9 * static_cast<double>(seed);
  const Vec3d l = Vec3d(0.3 * std::cos(phase), 0.3 * std::sin(phase), 0.9).normalized();
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
  s += "  vec3 l = " + vec3_of(kLightDirection) + ";\n  vec3 E = " + vec3_of(kIrradiance) + ";\n";
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
      std::vector<double> p(kParameters, 0.0);
      if (d.light.z() > 0.0) {
        const auto material = fit_texel(d, o.max_iterations);
        std::copy(material.begin(), material.end(), p.begin());
        for (int c = 0; c < 3; ++c) {
          p[static_cast<size_t>(kLightDirection + c)] = d.light[c];
          p[static_cast<size_t>(kIrradiance + c)] = d.irradiance[c];
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
                "ggx:iso",
                [](const std::string& settings) -> Result<ModelPtr> {
                  if (settings == "iso") return ModelPtr(std::make_shared<GgxModel>());
                  return make_error(ErrorCode::kInvalidArgument, "the form must be iso (ggx:iso)");
                },
                {"ggx:iso"}});
}

}  // namespace vdrig::fitting
